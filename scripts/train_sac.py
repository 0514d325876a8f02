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
    """The normalised improvement at the end of every training episode, by env step."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[tuple[int, float]] = []

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if done:
                self.rows.append((self.num_timesteps, float(info["improvement"])))
        return True


def make_agent(env: gymnasium.Env, *, seed: int = 0, buffer_size: int = 100_000, learning_starts: int = 1000,
               batch_size: int = 256) -> SAC:
    return SAC("MultiInputPolicy", env, seed=seed, buffer_size=buffer_size, learning_starts=learning_starts,
               batch_size=batch_size, policy_kwargs={"features_extractor_class": PointFeatures,
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
    parser.add_argument("--eval-configs", type=int, default=20)
    parser.add_argument("--out", default="runs/sac")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env = gymnasium.make(f"pasta/{args.task}-v0")
    model, curve = make_agent(env, seed=args.seed), Curve()
    model.learn(args.steps, callback=curve)
    from safetensors.torch import save_file

    save_file({k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()},
              str(out / "policy.safetensors"))
    np.savetxt(out / "curve.csv", np.array(curve.rows).reshape(-1, 2), delimiter=",", header="step,improvement",
               comments="")
    result = {"task": args.task, "steps": args.steps, "seed": args.seed, **evaluate(model, args.task, args.eval_configs)}
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
