"""SAC-Point, the paper's model-free baseline, on a pasta task's Gymnasium environment (docs/gymnasium.md).

    .venv/bin/python scripts/train_sac.py --task crs --steps 50000 --out runs/sac_crs

Stable-Baselines3's SAC with a PointNet-style feature extractor (a shared per-point MLP and a max pool over each
of the dough and goal clouds, the tool poses as they are), on the all-tools action layout. Training draws
instances from the environment's training pool (seeds 100000+); the trained policy is then scored on the 20
fixed test configs (seeds 1000-1019) with deterministic actions, as the results table scores pasta. Writes
OUT/curve.csv (step, episode improvement), OUT/curve.png, OUT/result.json (mean improvement and success over
the test configs) and OUT/policy.safetensors (the policy's weights; no pickle).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium
import numpy as np
import torch
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

import pasta.envs  # noqa: F401 - registers pasta/<task>-v0


class PointFeatures(BaseFeaturesExtractor):
    """Per-point MLP (3 -> 64 -> 128) and a max pool for the dough and for the goal, with the tool poses."""

    def __init__(self, space: gymnasium.spaces.Dict, width: int = 128) -> None:
        tools = int(np.prod(space["tools"].shape))
        super().__init__(space, features_dim=2 * width + tools)
        self.dough = nn.Sequential(nn.Linear(3, 64), nn.ReLU(), nn.Linear(64, width), nn.ReLU())
        self.goal = nn.Sequential(nn.Linear(3, 64), nn.ReLU(), nn.Linear(64, width), nn.ReLU())

    def forward(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        dough = self.dough(obs["dough"]).max(1).values
        goal = self.goal(obs["goal"]).max(1).values
        return torch.cat([dough, goal, obs["tools"].flatten(1)], 1)


class Curve(BaseCallback):
    """The normalised improvement at the end of every training episode, by env step; a progress line (rate, ETA,
    recent improvement) and OUT/curve.csv rewritten every ``every`` steps, so a long run can be watched and a
    killed one keeps its curve."""

    def __init__(self, total: int = 0, out: Path | None = None, every: int = 1000) -> None:
        super().__init__()
        self.rows: list[tuple[int, float]] = []
        self.total, self.out, self.every = total, out, every
        self.start = time.monotonic()

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if done:
                self.rows.append((self.num_timesteps, float(info["improvement"])))
        if self.every and self.num_timesteps % self.every == 0:
            rate = self.num_timesteps / max(time.monotonic() - self.start, 1e-9)
            recent = [value for _, value in self.rows[-10:]]
            eta = (self.total - self.num_timesteps) / rate if self.total else 0.0
            print(f"step {self.num_timesteps}/{self.total}  {rate:.1f} steps/s  ETA {eta / 60:.0f} min  "
                  f"episodes {len(self.rows)}  last-10 improvement "
                  f"{np.mean(recent) if recent else float('nan'):.3f}", flush=True)
            if self.out is not None:
                write_curve(self.rows, self.out / "curve.csv")
        return True


def write_curve(rows: list[tuple[int, float]], path: Path) -> None:
    from pasta.core.files import write_text

    lines = ["step,improvement"] + [f"{step},{value:.6f}" for step, value in rows]
    write_text(path, "\n".join(lines) + "\n")


def make_agent(env: gymnasium.Env, *, seed: int = 0, buffer_size: int = 100_000, learning_starts: int = 1000,
               batch_size: int = 128, train_freq: int = 4) -> SAC:
    """SB3's SAC with the point features; one gradient step per ``train_freq`` env steps (the update of a
    point-cloud batch costs about as much as a few simulator steps on a CPU)."""
    return SAC("MultiInputPolicy", env, seed=seed, buffer_size=buffer_size, learning_starts=learning_starts,
               batch_size=batch_size, train_freq=train_freq, gradient_steps=1, policy_kwargs={"features_extractor_class": PointFeatures,
                                                     "net_arch": [256, 256]}, verbose=0)


def evaluate(model: SAC, task: str, num: int = 20, points: int = 512) -> dict[str, float]:
    from pasta.tasks import fixed_test_seeds

    env = gymnasium.make(f"pasta/{task}-v0", seeds=fixed_test_seeds(num), points=points)
    improvements, successes = [], []
    for seed in fixed_test_seeds(num):
        obs, info = env.reset(seed=0, options={"instance": seed})
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        improvements.append(info["improvement"])
        successes.append(info["success"])
    return {"improvement_mean": float(np.mean(improvements)), "improvement_std": float(np.std(improvements)),
            "success_rate": float(np.mean(successes)), "configs": num}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="crs")
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--points", type=int, default=256, help="observed dough and goal points (env points=)")
    parser.add_argument("--batch-size", type=int, default=128)
    parser.add_argument("--train-freq", type=int, default=4, help="env steps per gradient step")
    parser.add_argument("--eval-configs", type=int, default=20)
    parser.add_argument("--out", default="runs/sac")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env = gymnasium.make(f"pasta/{args.task}-v0", points=args.points)
    model = make_agent(env, seed=args.seed, batch_size=args.batch_size, train_freq=args.train_freq)
    curve = Curve(args.steps, out)
    model.learn(args.steps, callback=curve)
    from safetensors.torch import save_file

    save_file({k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()},
              str(out / "policy.safetensors"))
    write_curve(curve.rows, out / "curve.csv")
    result = {"task": args.task, "steps": args.steps, "seed": args.seed, "points": args.points,
              "batch_size": args.batch_size, "train_freq": args.train_freq,
              **evaluate(model, args.task, args.eval_configs, args.points)}
    (out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
    _plot(curve.rows, out / "curve.png", f"SAC-Point on {args.task}")
    print(json.dumps(result))


def _plot(rows: list[tuple[int, float]], path: Path, title: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5, 3.2), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if rows:
        steps, values = np.array(rows).T
        ax.plot(steps, values, ".", alpha=0.4, label="episode")
        window = max(1, len(values) // 20)
        ax.plot(steps, np.convolve(values, np.ones(window) / window, mode="same"), label=f"mean of {window}")
        ax.legend(fontsize=8)
    ax.set_xlabel("env steps")
    ax.set_ylabel("normalised improvement")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    main()
