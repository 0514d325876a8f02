"""Behaviour cloning of one skill policy through the shared training loop (:mod:`pasta.train.loop`).

``pasta train policy skill=cut data=DIR out=DIR`` is :func:`train_policy`; the policy plugs into the
one loop as a :class:`PolicyTask` (network, batches, loss, validation), and the loop writes the
same safetensors checkpoints as every other module (``OUT/model.*`` best by validation loss,
``OUT/last.*`` to resume).

Loss per sample: squared action error summed over the action dimensions, plus ``done_weight`` times
the binary cross-entropy of the done logit. Validation uses fixed, noise-free batches of held-out
demonstrations (split by demonstration, seeded).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pasta.core.errors import ConfigError
from pasta.core.files import write_json
from pasta.train.policy_data import Batch, DemoSet
from pasta.policy.learned import MODULE, LearnedPolicy
from pasta.policy.network import PolicyConfig, PolicyNet
from pasta.train.loop import LoopConfig, fit, numpy_rng

__all__ = ["PolicyTask", "PolicyTrainConfig", "from_reset_pose", "train_policy"]


@dataclass
class PolicyTrainConfig:
    """Policy-specific training settings (the loop's own are in :class:`pasta.train.loop.LoopConfig`).

    Attributes:
        hindsight_ratio: probability of a hindsight goal (else the demo's final state).
        noise: uniform point noise half-width during training.
        val_fraction: share of demonstrations held out for validation.
        steps_per_epoch: optimiser steps per loop epoch (transitions are sampled with replacement).
        val_batches: fixed validation batches (of the loop's batch size).
        done_weight: weight of the done loss.
        done_pos_weight: weight of the positive (done = 1) samples in the done loss; done is rare (about
            one step in twenty with hindsight goals), and without it the done probability stays below 1/2.
        dough_points, tool_points, goal_points: points per source fed to the network.
        max_demos: use at most this many demonstrations (0 = all).
        step_feature: the network also sees the step index within the execution
            (:attr:`PolicyConfig.step_feature`, whose default this is: a skill's phase one frame does not show).
        pose_feature: the network also sees the tool pose (:attr:`PolicyConfig.pose_feature`, its default).
        goal_feature: the network also sees the goal centroid's offset from the dough centroid
            (:attr:`PolicyConfig.goal_feature`; push and lift turn it on in their ``training_defaults``).
        action_feature: the network also sees its previous action (:attr:`PolicyConfig.action_feature`;
            the roll turns it on: which way the roller goes is not in one frame).
        floor_y: heights measured from the dough's bottom (:attr:`PolicyConfig.floor_y`; the roll: the board
            and the table are the same motion).
        start_at_reset: drop each demonstration's steps before its reset pose (the align phase, up to the
            first step with a vertical action, :func:`pasta.train.reset.align_offset`), so the step
            counter starts at 0 where a policy with a learned reset pose starts (``start_step`` 0) and
            the policy never learns the align motion the reset pose replaces (cut).
        decoded_goals: probability that a piece of a demonstration's final-state goal is replaced by its VAE
            reconstruction (``encoder_weights``; empty: the shipped VAE), as a plan's decoded sub-goals
            are at execution (:mod:`pasta.train.decoded`; hindsight goals stay exact).
        decoded_noise: std of Gaussian noise on the shape code of those reconstructions (4 per piece).
        decoded_shift: a reconstruction is moved by up to this much per axis (metres): a plan's sub-goal
            sits a little off where the demonstration put the dough, and the policy should still finish it.
        encoder_weights: the VAE directory for ``decoded_goals`` (empty: the shipped VAE).
    """

    hindsight_ratio: float = 0.5
    noise: float = 0.005
    val_fraction: float = 0.1
    steps_per_epoch: int = 50
    val_batches: int = 4
    done_weight: float = 1.0
    done_pos_weight: float = 5.0
    dough_points: int = 512
    tool_points: int = 100
    goal_points: int = 512
    max_demos: int = 0
    step_feature: bool = PolicyConfig.step_feature
    pose_feature: bool = PolicyConfig.pose_feature
    goal_feature: bool = PolicyConfig.goal_feature
    action_feature: bool = PolicyConfig.action_feature
    floor_y: bool = PolicyConfig.floor_y
    start_at_reset: bool = False
    decoded_goals: float = 0.0
    decoded_noise: float = 0.0
    decoded_shift: float = 0.0
    encoder_weights: str = ""

    def __post_init__(self) -> None:
        from pasta.config.validate import check_ranges
        from pasta.train.vae import MAX_POINTS

        check_ranges(self, {"hindsight_ratio": (0.0, 1.0), "noise": (0.0, None), "val_fraction": (0.0, 1.0, "[)"),
                            "steps_per_epoch": (1, None), "val_batches": (1, None), "done_weight": (0.0, None),
                            "done_pos_weight": (0.0, None), "dough_points": (1, MAX_POINTS),
                            "tool_points": (1, MAX_POINTS), "goal_points": (1, MAX_POINTS), "max_demos": (0, None),
                            "decoded_goals": (0.0, 1.0), "decoded_noise": (0.0, None), "decoded_shift": (0.0, None)})


def _to_torch(b: Batch) -> dict[str, torch.Tensor]:
    out = {k: torch.from_numpy(getattr(b, k)) for k in ("dough", "tool", "goal", "action", "done")}
    for k in ("step", "pose", "prev_action"):
        if getattr(b, k) is not None:
            out[k] = torch.from_numpy(getattr(b, k))
    return out


class PolicyTask:
    """The policy as a :class:`pasta.train.loop.TrainTask`.

    Args:
        skill: skill name; ``tool``: its tool (saved in the checkpoint).
        train, val: demonstration sets (``val`` may be the training set for tiny runs).
        cfg: policy training settings (the point counts and the step / pose / goal inputs of the network);
            ``network``: the other network sizes (``action_dim`` is taken from the data).
        seed: seed of the fixed validation batches.
        batch_size: size of the validation batches.
    """

    module = MODULE

    def __init__(self, skill: str, tool: str, train: DemoSet, val: DemoSet, cfg: PolicyTrainConfig,
                 network: PolicyConfig | None = None, *, seed: int = 0, batch_size: int = 32) -> None:
        self.skill, self.tool, self.train_set, self.cfg = skill, tool, train, cfg
        net_cfg = network or PolicyConfig()
        net_cfg.action_dim = train.action_dim
        net_cfg.dough_points, net_cfg.tool_points, net_cfg.goal_points = cfg.dough_points, cfg.tool_points, cfg.goal_points
        # the inputs are training settings (key=value on `pasta train policy`); network= gives the sizes
        net_cfg.step_feature, net_cfg.pose_feature, net_cfg.goal_feature = cfg.step_feature, cfg.pose_feature, cfg.goal_feature
        net_cfg.action_feature, net_cfg.floor_y = cfg.action_feature, cfg.floor_y
        torch.manual_seed(seed)
        self.model = PolicyNet(net_cfg)
        rng = np.random.default_rng(seed + 7919)
        self.val = [_to_torch(val.sample(rng.integers(0, len(val), batch_size), rng)) for _ in range(cfg.val_batches)]

    def config(self) -> dict[str, Any]:
        return {"skill": self.skill, "tool": self.tool, "network": self.model.cfg.to_dict()}

    def batches(self, batch_size: int, generator: torch.Generator) -> Iterator[dict[str, torch.Tensor]]:
        rng = numpy_rng(generator)
        for _ in range(self.cfg.steps_per_epoch):
            yield _to_torch(self.train_set.sample(rng.integers(0, len(self.train_set), batch_size), rng))

    def _losses(self, b: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        action, logit = self.model(b["dough"], b["tool"], b["goal"], b.get("step"), b.get("pose"), b.get("prev_action"))
        a_loss = (action - b["action"].clamp(-1, 1)).pow(2).sum(-1).mean()
        d_loss = torch.nn.functional.binary_cross_entropy_with_logits(
            logit, b["done"], pos_weight=logit.new_tensor(self.cfg.done_pos_weight))
        acc = ((logit > 0).float() == b["done"]).float().mean()
        return a_loss, d_loss, acc

    def loss(self, batch: dict[str, torch.Tensor], generator: torch.Generator) -> torch.Tensor:
        a_loss, d_loss, _ = self._losses(batch)
        return a_loss + self.cfg.done_weight * d_loss

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        parts = [self._losses(b) for b in self.val]
        a = float(np.mean([float(p[0]) for p in parts]))
        d = float(np.mean([float(p[1]) for p in parts]))
        acc = float(np.mean([float(p[2]) for p in parts]))
        return {"val_loss": a + self.cfg.done_weight * d, "val_action": a, "val_done": d, "val_done_acc": acc}


def make_task(skill: str, data: str | Path, cfg: PolicyTrainConfig, *, network: PolicyConfig | None = None,
              tool: str | None = None, seed: int = 0, batch_size: int = 32) -> PolicyTask:
    """Load the demonstrations of ``skill`` under ``data`` (shared reader), split them by demonstration, build the task."""
    from pasta.demos.data import load_demos, split_by_demo

    demos = load_demos(data, [skill], stage="policy")
    if cfg.max_demos > 0:
        demos = demos[: cfg.max_demos]
    if cfg.start_at_reset:
        demos = [from_reset_pose(d) for d in demos]
    train_demos, val_demos = split_by_demo(demos, val_fraction=cfg.val_fraction, seed=seed)
    kw: dict[str, Any] = {"dough_points": cfg.dough_points, "tool_points": cfg.tool_points, "goal_points": cfg.goal_points,
          "hindsight_ratio": cfg.hindsight_ratio}
    decoded = None
    if cfg.decoded_goals > 0:
        from pasta.train.decoded import decoded_pieces, load_encoder

        encoder, rng = load_encoder(cfg.encoder_weights), np.random.default_rng(seed)
        draws = 4 if cfg.decoded_noise > 0 else 1
        decoded = [decoded_pieces(np.asarray(d.dough[-1], np.float32), encoder, noise=cfg.decoded_noise, draws=draws,
                                  rng=rng) for d in train_demos]
    train = DemoSet(train_demos, noise=cfg.noise, decoded=decoded, p_decoded=cfg.decoded_goals,
                    decoded_shift=cfg.decoded_shift, **kw)
    val = DemoSet(val_demos or train_demos, noise=0.0, **kw)
    if tool is None:
        tool = _skill_tool(skill)
    return PolicyTask(skill, tool, train, val, cfg, network, seed=seed, batch_size=batch_size)


def from_reset_pose(demo: Any) -> Any:
    """``demo`` from its reset pose on: the steps before its first vertical action (the align phase,
    :func:`pasta.train.reset.align_offset`) removed; a demo with no vertical action is kept whole."""
    from dataclasses import replace

    from pasta.train.reset import align_offset

    _, k = align_offset(demo)
    if k <= 0 or k >= len(demo.action):
        return demo
    return replace(demo, dough=demo.dough[k:], tool_points=demo.tool_points[k:], tool_pose=demo.tool_pose[k:],
                   action=demo.action[k:])


def _skill_tool(skill: str) -> str:
    try:
        from pasta.plugins import get_plugins

        return get_plugins().skills.info(skill).spec.tool
    except Exception:  # noqa: BLE001 - the tool name is informative only
        return ""


def train_policy(skill: str, data: str | Path, out: str | Path, *, cfg: PolicyTrainConfig | None = None,
                 loop: Any = None, network: PolicyConfig | None = None) -> tuple[LearnedPolicy, Any]:
    """Train the policy of ``skill`` on ``data/<skill>/demo_*.npz`` into ``out`` with the shared loop.

    Args:
        cfg: policy settings (defaults: :class:`PolicyTrainConfig`).
        loop: a :class:`pasta.train.loop.LoopConfig` (defaults: its defaults).
        network: network sizes (defaults: :class:`~pasta.policy.network.PolicyConfig`).

    Returns:
        ``(policy, fit_result)``: the best-validation policy and the loop's result.
    """
    cfg = cfg or PolicyTrainConfig()
    loop = loop or LoopConfig()
    task = make_task(skill, data, cfg, network=network, seed=loop.seed, batch_size=loop.batch_size)
    result = fit(task, loop, out)
    return LearnedPolicy(task.model, skill), result


#: loop defaults of policy training (one CPU core: ~0.5-1 s per step at batch 32 with the default network)
LOOP_DEFAULTS: dict[str, Any] = {"epochs": 40, "batch_size": 32, "lr": 1e-3}


def policy_configs(overrides: Mapping[str, Any] | None = None) -> tuple[LoopConfig, PolicyTrainConfig]:
    """The loop's and the policy's settings from ``key=value`` overrides over :data:`LOOP_DEFAULTS` (a typo
    fails with the closest valid key)."""
    from pasta.config.overrides import build_many

    loop, cfg = build_many({**LOOP_DEFAULTS, **dict(overrides or {})}, [LoopConfig, PolicyTrainConfig],
                           command="pasta train policy")
    if cfg.decoded_goals > 0:
        from pasta.train.decoded import check_encoder_weights

        check_encoder_weights(cfg.encoder_weights)
    return loop, cfg


def train_command(data: str | Path, out: str | Path, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """``pasta train policy skill=NAME data=DIR out=MODELS [key=value ...]`` as a function.

    Keys: ``skill`` (required), the loop's (:class:`~pasta.train.loop.LoopConfig`), the policy's
    (:class:`PolicyTrainConfig`) and ``threads`` (torch CPU threads, 0 = leave as is). Writes
    ``MODELS/policy/<skill>/model.*`` and ``metrics.json``; returns the metrics.
    """
    from pasta.policy import POLICY_DIR

    pairs = dict(overrides or {})
    skill = pairs.pop("skill", "")
    if not skill:
        raise ConfigError("`pasta train policy` needs skill=NAME (a registered skill)")
    loop, cfg = policy_configs(pairs)
    directory = Path(out) / POLICY_DIR / skill
    task = make_task(skill, data, cfg, seed=loop.seed, batch_size=loop.batch_size)
    result = fit(task, loop, directory)
    figures = {f"heldout_{k[4:]}": v for k, v in task.validate().items() if k != "val_loss"}
    metrics = {"module": MODULE, "skill": skill, "data": str(data), "train_demos": len(task.train_set.demos),
               "train_transitions": len(task.train_set), "best_epoch": result.best_epoch,
               "best_val_loss": result.best_val_loss, **figures}
    write_json(directory / "metrics.json", metrics)
    return metrics
