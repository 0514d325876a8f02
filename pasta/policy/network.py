"""The per-skill policy network: PointNet++ over dough + tool + sub-goal points -> action and done.

Input: three clouds of one skill execution step,

- ``dough (B, P, 3)``: the attended piece(s),
- ``tool (B, T, 3)``: the skill's tool surface points,
- ``goal (B, G, 3)``: the step's sub-goal (all produced entities together),

concatenated to one cloud of ``P + T + G`` points, each with a one-hot source feature
(dough ``[1, 0, 0]``, tool ``[0, 1, 0]``, goal ``[0, 0, 1]``). With ``center_xz`` the clouds are
shifted so that the dough centroid lies at ``x = z = 0`` (``y``, the height above the floor, is
kept): actions are relative tool motions, so the policy need not learn every placement. With ``floor_y``
also ``y`` is measured from the dough's bottom (its 2nd percentile): a roll on the raised board and one
on the table are the same motion, so the roll policy does not learn two height scales.

Low-dimensional inputs, embedded by a small MLP (``aux_widths``) and concatenated to the global point
feature before the heads (``step_feature`` and ``pose_feature`` on by default: every skill's policy uses
them; ``goal_feature`` for the skills whose goal lies elsewhere, push and lift):

- ``step_feature``: the execution step ``t`` (actions taken so far in this skill execution), as
  ``t / step_scale``. A multi-phase skill is not Markov in one frame: the cut's knife passes the same
  heights going down, up and down again, a roll's pass count is not visible.
- ``pose_feature``: the tool pose ``(7,)`` (position, quaternion ``w, x, y, z``), the position shifted
  like the clouds and times ``encoder.pos_scale``. The same information as the tool cloud, but exact: the
  max-pooled cloud feature locates the tool only coarsely.
- ``goal_feature``: the offset of the goal centroid from the dough centroid ``(3,)``, times
  ``encoder.pos_scale``, computed from the two clouds (no extra input). Where the piece must go, exact:
  the lift policy trained without it carried every piece along the demonstrations' mean direction (-x)
  whatever the goal, and never stopped (docs/policies.md, "lift and gather").
- ``action_feature``: the policy's previous action ``(A,)`` (zeros at the first step). Which way a roller
  is going is not in the frame: halfway along the piece the expert rolls forward on one pass and back on
  the next, from the same dough, pose and (nearly) step; the last action says which pass it is.

Output: ``action (B, A)`` in ``[-1, 1]`` (tanh) and ``done (B,)`` logits.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, field
from typing import Any

import torch
from torch import nn

from pasta.policy.pointnet2 import PointNet2, PointNet2Config, SAConfig

__all__ = ["PolicyConfig", "PolicyNet"]


@dataclass
class PolicyConfig:
    """Sizes of one skill policy.

    Attributes:
        action_dim: ``A``, the skill's tool action size.
        dough_points, tool_points, goal_points: points per source fed to the network.
        center_xz: shift every cloud so that the dough centroid is at ``x = z = 0``.
        floor_y: shift every cloud so that the dough's bottom (2nd percentile of ``y``) is at ``y = 0``.
        encoder: the PointNet++ sizes.
        head_widths: hidden widths of the action and done heads.
        step_feature: feed the execution step ``t / step_scale`` to the heads (on: every shipped policy).
        step_scale: divisor of the step index.
        pose_feature: feed the tool pose ``(7,)`` to the heads (on: every shipped policy).
        goal_feature: feed the goal centroid's offset from the dough centroid ``(3,)`` to the heads.
        action_feature: feed the previous action ``(action_dim,)`` to the heads (zeros at the first step).
        aux_widths: widths of the MLP that embeds the step / pose / goal inputs.
    """

    action_dim: int = 2
    dough_points: int = 512
    tool_points: int = 100
    goal_points: int = 512
    center_xz: bool = True
    floor_y: bool = False
    encoder: PointNet2Config = field(default_factory=PointNet2Config)
    head_widths: tuple[int, ...] = (256, 128)
    step_feature: bool = True
    step_scale: float = 50.0
    pose_feature: bool = True
    goal_feature: bool = False
    action_feature: bool = False
    aux_widths: tuple[int, ...] = (64, 64)

    @property
    def aux_dim(self) -> int:
        """Size of the raw low-dimensional input (0: none)."""
        return ((1 if self.step_feature else 0) + (7 if self.pose_feature else 0) + (3 if self.goal_feature else 0)
                + (self.action_dim if self.action_feature else 0))

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["head_widths"] = list(self.head_widths)
        d["aux_widths"] = list(self.aux_widths)
        d["encoder"]["global_widths"] = list(self.encoder.global_widths)
        for lv in d["encoder"]["levels"]:
            lv["widths"] = list(lv["widths"])
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PolicyConfig:
        """The config :meth:`to_dict` wrote; every key must be there (no defaults for missing ones).

        Raises:
            ConfigError: a key is missing or unknown."""
        if "action_feature" not in d and "floor_y" not in d and "goal_feature" in d:
            from pasta.core.errors import ConfigError

            raise ConfigError("policy network config lacks action_feature and floor_y: it was written by a pasta "
                              "before 2026-12-06; retrain it, or add \"action_feature\": false, \"floor_y\": false "
                              "to its network config (the policy had neither input)")
        _check_keys("policy network", d, cls.__dataclass_fields__)
        enc = dict(d["encoder"])
        _check_keys("policy network encoder", enc, ("in_features", "pos_scale", "global_widths", "levels"))
        levels = [SAConfig(int(lv["centers"]), float(lv["radius"]), int(lv["k"]), tuple(int(w) for w in lv["widths"]))
                  for lv in enc["levels"]]
        encoder = PointNet2Config(in_features=int(enc["in_features"]), pos_scale=float(enc["pos_scale"]),
                                  global_widths=tuple(int(w) for w in enc["global_widths"]), levels=levels)
        return cls(action_dim=int(d["action_dim"]), dough_points=int(d["dough_points"]), tool_points=int(d["tool_points"]),
                   goal_points=int(d["goal_points"]), center_xz=bool(d["center_xz"]), floor_y=bool(d["floor_y"]),
                   encoder=encoder,
                   head_widths=tuple(int(w) for w in d["head_widths"]), step_feature=bool(d["step_feature"]),
                   step_scale=float(d["step_scale"]), pose_feature=bool(d["pose_feature"]),
                   goal_feature=bool(d["goal_feature"]), action_feature=bool(d["action_feature"]), aux_widths=tuple(int(w) for w in d["aux_widths"]))


def _check_keys(what: str, d: dict[str, Any], keys: Any) -> None:
    """Raise :class:`~pasta.core.errors.ConfigError` naming the keys of ``keys`` that ``d`` lacks and those it
    has beyond them (a checkpoint config of format version 2 writes every key)."""
    from pasta.core.errors import ConfigError

    missing, unknown = sorted(set(keys) - set(d)), sorted(set(d) - set(keys))
    if missing or unknown:
        parts = ([f"lacks {', '.join(missing)}"] if missing else []) + ([f"has unknown {', '.join(unknown)}"] if unknown else [])
        raise ConfigError(f"{what} config {' and '.join(parts)}")


def _head(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class PolicyNet(nn.Module):
    """``(dough (B, P, 3), tool (B, T, 3), goal (B, G, 3)[, step (B,), pose (B, 7), prev_action (B, A)])`` ->
    ``(action (B, A) in [-1, 1], done logit (B,))``; ``step`` / ``pose`` / ``prev_action`` are required when
    ``cfg.step_feature`` / ``cfg.pose_feature`` / ``cfg.action_feature`` is on, ignored otherwise."""

    def __init__(self, cfg: PolicyConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or PolicyConfig()
        if cfg.encoder.in_features != 3:
            raise ValueError("the policy's PointNet++ takes the 3-channel one-hot source feature")
        self.encoder = PointNet2(cfg.encoder)
        aux = 0
        if cfg.aux_dim:
            self.aux = _head([cfg.aux_dim, *cfg.aux_widths])
            if cfg.aux_widths:
                self.aux.append(nn.ReLU())
            aux = cfg.aux_widths[-1] if cfg.aux_widths else cfg.aux_dim
        widths = [cfg.encoder.out_dim + aux, *cfg.head_widths]
        self.action_head = _head([*widths, cfg.action_dim])
        self.done_head = _head([*widths, 1])
        # Small last layers: the initial action is near 0 and the initial done probability near 1/2.
        for head in (self.action_head, self.done_head):
            last = head[-1]
            assert isinstance(last, nn.Linear)
            nn.init.uniform_(last.weight, -1e-3, 1e-3)
            nn.init.zeros_(last.bias)

    def forward(self, dough: torch.Tensor, tool: torch.Tensor, goal: torch.Tensor,
                step: torch.Tensor | None = None, pose: torch.Tensor | None = None,
                prev_action: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        xyz = torch.cat([dough, tool, goal], 1)
        shift = dough.mean(1, keepdim=True) * xyz.new_tensor([1.0, 0.0, 1.0]) if self.cfg.center_xz else None
        if self.cfg.floor_y:
            bottom = torch.quantile(dough[..., 1], 0.02, dim=1).reshape(-1, 1, 1) * xyz.new_tensor([0.0, 1.0, 0.0])
            shift = bottom if shift is None else shift + bottom
        if shift is not None:
            xyz = xyz - shift
        sizes = (dough.shape[1], tool.shape[1], goal.shape[1])
        src = torch.cat([torch.full((n,), i, dtype=torch.long, device=xyz.device) for i, n in enumerate(sizes)])
        onehot = nn.functional.one_hot(src, 3).to(xyz.dtype).unsqueeze(0).expand(xyz.shape[0], -1, -1)
        h = self.encoder(xyz, onehot)
        if self.cfg.aux_dim:
            offset = goal.mean(1) - dough.mean(1) if self.cfg.goal_feature else None
            h = torch.cat([h, self.aux(self._aux_input(h, step, pose, shift, offset, prev_action))], -1)
        return torch.tanh(self.action_head(h)), self.done_head(h).squeeze(-1)

    def _aux_input(self, h: torch.Tensor, step: torch.Tensor | None, pose: torch.Tensor | None,
                   shift: torch.Tensor | None, offset: torch.Tensor | None = None,
                   prev_action: torch.Tensor | None = None) -> torch.Tensor:
        parts = []
        if self.cfg.step_feature:
            if step is None:
                raise ValueError("this policy network takes the execution step (step_feature): pass step (B,)")
            parts.append(step.to(h.dtype).reshape(-1, 1).expand(h.shape[0], 1) / self.cfg.step_scale)
        if self.cfg.pose_feature:
            if pose is None:
                raise ValueError("this policy network takes the tool pose (pose_feature): pass pose (B, 7)")
            pose = pose.to(h.dtype).reshape(-1, 7).expand(h.shape[0], 7)
            pos = pose[:, :3] - (shift[:, 0] if shift is not None else 0.0)
            parts += [pos * self.cfg.encoder.pos_scale, pose[:, 3:]]
        if offset is not None:  # (B, 3): goal centroid - dough centroid, unchanged by the centring shift
            parts.append(offset.to(h.dtype) * self.cfg.encoder.pos_scale)
        if self.cfg.action_feature:
            a = self.cfg.action_dim
            if prev_action is None:
                raise ValueError(f"this policy network takes its previous action (action_feature): pass prev_action (B, {a})")
            parts.append(prev_action.to(h.dtype).reshape(-1, a).expand(h.shape[0], a))
        return torch.cat(parts, -1)
