"""SAC-Point, the paper's model-free baseline, on a pasta task's Gymnasium environment (docs/gymnasium.md).

    .venv/bin/python scripts/train_sac.py --task crs --steps 50000 --out runs/sac_crs

Stable-Baselines3's SAC with a PointNet-style feature extractor (a shared per-point MLP and a max pool over each
of the dough and goal clouds, the tool poses as they are), on the all-tools action layout. Training draws
instances from the environment's training pool (seeds 100000+); the trained policy is then scored on the 20
fixed test configs (seeds 1000-1019) with deterministic actions, as the results table scores pasta. Writes
OUT/curve.csv (step, episode improvement), OUT/curve.png, OUT/result.json (mean improvement and success over
the test configs, the settings), OUT/episodes.jsonl (one row per test config, as ``pasta eval`` writes them) and
OUT/policy.safetensors (the policy's weights; no pickle). A finished run's command run again evaluates it again.

A long run keeps OUT/checkpoint/ (every ``--checkpoint-every`` env steps: the networks, optimisers, entropy
coefficient and random states as safetensors + JSON, the replay buffer as .npz; no pickle), and the same command
resumes from it: a run killed (or stopped at the end of a working session) goes on where its last checkpoint
was, with a fresh episode. A resumed run is reproducible from its checkpoint, not bit for bit the run that was
never stopped (the interrupted episode is not replayed).
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


#: the settings a checkpoint must share with the command that resumes it
RESUME_KEYS = ("task", "seed", "points", "batch_size", "train_freq")


def save_checkpoint(model: SAC, folder: Path, settings: dict) -> None:
    """Everything :func:`load_checkpoint` needs to go on training ``model`` (written to a temporary folder, then
    renamed over ``folder``: a kill while writing leaves the previous checkpoint)."""
    import shutil

    from safetensors.torch import save_file

    tmp = folder.with_name(folder.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    tensors = {f"policy.{k}": v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()}
    tensors["log_ent_coef"] = model.log_ent_coef.detach().cpu().clone()
    tensors["rng.torch"] = torch.get_rng_state()
    groups = {}
    for name, opt in _optimisers(model).items():
        state = opt.state_dict()
        groups[name] = state["param_groups"]
        for index, values in state["state"].items():
            for key, value in values.items():
                tensors[f"opt.{name}.{index}.{key}"] = torch.as_tensor(value).detach().cpu().clone()
    save_file(tensors, str(tmp / "model.safetensors"))
    buffer = model.replay_buffer
    end = buffer.buffer_size if buffer.full else buffer.pos
    arrays = {f"obs.{k}": v[:end] for k, v in buffer.observations.items()}
    arrays |= {f"next.{k}": v[:end] for k, v in buffer.next_observations.items()}
    arrays |= {name: getattr(buffer, name)[:end] for name in ("actions", "rewards", "dones", "timeouts")}
    mt_key, mt_pos, has_gauss, gauss = np.random.get_state()[1:]
    arrays["rng.numpy"] = np.asarray(mt_key, np.uint32)
    np.savez(tmp / "buffer.npz", **arrays)
    env = model.get_env().envs[0].unwrapped  # type: ignore[union-attr]
    state = {**settings, "num_timesteps": model.num_timesteps, "n_updates": model._n_updates,
             "episode_num": model._episode_num, "buffer_pos": int(buffer.pos), "buffer_full": bool(buffer.full),
             "optimisers": groups, "rng_numpy": [int(mt_pos), int(has_gauss), float(gauss)],
             "rng_env": env.np_random.bit_generator.state}
    (tmp / "state.json").write_text(json.dumps(state, indent=1) + "\n")
    shutil.rmtree(folder, ignore_errors=True)
    tmp.rename(folder)


def load_checkpoint(model: SAC, folder: Path, settings: dict) -> int:
    """Restore ``model`` from :func:`save_checkpoint`'s ``folder``; return its env step. A checkpoint of other
    settings (task, seed, points, batch size, train frequency) is refused."""
    from safetensors.torch import load_file

    state = json.loads((folder / "state.json").read_text())
    differ = {k: (state.get(k), settings.get(k)) for k in RESUME_KEYS if state.get(k) != settings.get(k)}
    if differ:
        raise SystemExit(f"{folder} holds a run of other settings {differ} (checkpoint, command): use another --out")
    tensors = load_file(str(folder / "model.safetensors"))
    model.policy.load_state_dict({k[len("policy."):]: v for k, v in tensors.items() if k.startswith("policy.")})
    with torch.no_grad():
        model.log_ent_coef.copy_(tensors["log_ent_coef"])
    for name, opt in _optimisers(model).items():
        own: dict[int, dict] = {}
        for key, value in tensors.items():
            if key.startswith(f"opt.{name}."):
                index, field = key[len(f"opt.{name}."):].split(".", 1)
                own.setdefault(int(index), {})[field] = value
        opt.load_state_dict({"state": own, "param_groups": state["optimisers"][name]})
    buffer = model.replay_buffer
    with np.load(folder / "buffer.npz") as arrays:
        end = len(arrays["actions"])
        for k in buffer.observations:
            buffer.observations[k][:end] = arrays[f"obs.{k}"]
            buffer.next_observations[k][:end] = arrays[f"next.{k}"]
        for name in ("actions", "rewards", "dones", "timeouts"):
            getattr(buffer, name)[:end] = arrays[name]
        mt_key = arrays["rng.numpy"]
    buffer.pos, buffer.full = int(state["buffer_pos"]), bool(state["buffer_full"])
    model.num_timesteps, model._n_updates = int(state["num_timesteps"]), int(state["n_updates"])
    model._episode_num = int(state["episode_num"])
    pos, has_gauss, gauss = state["rng_numpy"]
    np.random.set_state(("MT19937", mt_key, int(pos), int(has_gauss), float(gauss)))
    torch.set_rng_state(tensors["rng.torch"])
    vec = model.get_env()
    vec._reset_seeds()  # type: ignore[union-attr]  # no seed at the next reset: it draws from the restored stream
    vec.envs[0].unwrapped.np_random.bit_generator.state = state["rng_env"]  # type: ignore[union-attr]
    return model.num_timesteps


def _optimisers(model: SAC) -> dict[str, torch.optim.Optimizer]:
    return {"actor": model.actor.optimizer, "critic": model.critic.optimizer, "ent_coef": model.ent_coef_optimizer}


class Curve(BaseCallback):
    """The normalised improvement at the end of every training episode, by env step; a progress line (rate, ETA,
    recent improvement) and OUT/curve.csv rewritten every ``every`` steps, so a long run can be watched and a
    killed one keeps its curve."""

    def __init__(self, total: int = 0, out: Path | None = None, every: int = 1000, *, rows=(), checkpoint_every: int = 0,
                 settings: dict | None = None) -> None:
        super().__init__()
        self.rows: list[tuple[int, float]] = list(rows)
        self.total, self.out, self.every = total, out, every
        self.checkpoint_every, self.settings = checkpoint_every, settings or {}
        self.start = time.monotonic()
        self.first = -1  # the env step this process started at (a resumed run's rate counts its own steps)

    def _on_step(self) -> bool:
        if self.first < 0:
            self.first = self.num_timesteps - 1
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if done:
                self.rows.append((self.num_timesteps, float(info["improvement"])))
        if self.out is not None and self.checkpoint_every and self.num_timesteps % self.checkpoint_every == 0:
            write_curve(self.rows, self.out / "curve.csv")
            save_checkpoint(self.model, self.out / "checkpoint", self.settings)
        if self.every and self.num_timesteps % self.every == 0:
            rate = (self.num_timesteps - self.first) / max(time.monotonic() - self.start, 1e-9)
            recent = [value for _, value in self.rows[-10:]]
            eta = (self.total - self.num_timesteps) / rate if self.total else 0.0
            print(f"step {self.num_timesteps}/{self.total}  {rate:.1f} steps/s  ETA {eta / 60:.0f} min  "
                  f"episodes {len(self.rows)}  last-10 improvement "
                  f"{np.mean(recent) if recent else float('nan'):.3f}", flush=True)
            if self.out is not None:
                write_curve(self.rows, self.out / "curve.csv")
        return True


def read_curve(path: Path) -> list[tuple[int, float]]:
    """The rows :func:`write_curve` wrote (none when the file is missing)."""
    if not path.exists():
        return []
    lines = path.read_text().splitlines()[1:]
    return [(int(step), float(value)) for step, value in (line.split(",") for line in lines if line.strip())]


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


def evaluate(model: SAC, task: str, num: int = 20, points: int = 512) -> tuple[dict, list[dict]]:
    """The policy (deterministic actions) on the task's first ``num`` fixed test configs: the summary and one row
    per episode, in the form ``pasta eval`` writes (``docs/results``: ``<task>_sac-point.json`` / ``.jsonl``)."""
    from pasta.tasks import fixed_test_seeds

    env = gymnasium.make(f"pasta/{task}-v0", seeds=fixed_test_seeds(num), points=points)
    rows = []
    for seed in fixed_test_seeds(num):
        obs, info = env.reset(seed=0, options={"instance": seed})
        done, steps, t0 = False, 0, time.monotonic()
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            steps += 1
        rows.append({"task": task, "method": "sac-point", "seed": int(seed), "improvement": float(info["improvement"]),
                     "success": bool(info["success"]), "env_steps": steps, "execute_s": round(time.monotonic() - t0, 3)})
    improvements = [r["improvement"] for r in rows]
    summary = {"task": task, "method": "sac-point", "split": "test", "episodes": len(rows),
               "improvement_mean": float(np.mean(improvements)), "improvement_std": float(np.std(improvements)),
               "success_rate": float(np.mean([r["success"] for r in rows]))}
    return summary, rows


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
    parser.add_argument("--checkpoint-every", type=int, default=5000,
                        help="env steps between checkpoints (OUT/checkpoint; the same command resumes); 0: none")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env = gymnasium.make(f"pasta/{args.task}-v0", points=args.points)
    model = make_agent(env, seed=args.seed, batch_size=args.batch_size, train_freq=args.train_freq)
    settings = {"task": args.task, "seed": args.seed, "points": args.points, "batch_size": args.batch_size,
                "train_freq": args.train_freq}
    done, rows = 0, []
    if (out / "checkpoint" / "state.json").exists():
        done = load_checkpoint(model, out / "checkpoint", settings)
        settings["resumed_at"] = [*json.loads((out / "checkpoint" / "state.json").read_text()).get("resumed_at", []), done]
        rows = [r for r in read_curve(out / "curve.csv") if r[0] <= done]
        print(f"resumed from {out / 'checkpoint'} at env step {done}", flush=True)
    curve = Curve(args.steps, out, rows=rows, checkpoint_every=args.checkpoint_every, settings=settings)
    if args.steps > done:
        model.learn(args.steps - done, callback=curve, reset_num_timesteps=done == 0)
    from safetensors.torch import save_file

    save_file({k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()},
              str(out / "policy.safetensors"))
    write_curve(curve.rows, out / "curve.csv")
    summary, episodes = evaluate(model, args.task, args.eval_configs, args.points)
    result = {**summary, "settings": {**settings, "steps": args.steps}}
    (out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "episodes.jsonl").write_text("".join(json.dumps(row) + "\n" for row in episodes))
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
