"""The learned policy object a skill carries: ``skill.attach_policy(LearnedPolicy)``.

:meth:`LearnedPolicy.controller` returns a :class:`PolicyController` (the
:class:`~pasta.core.skill.Controller` contract): it subsamples the observed piece, the tool points
and the sub-goal to the network's point counts with a seeded generator, runs the network and returns
the action ``(A,)`` in ``[-1, 1]`` and its stop: ``Stop.DONE`` when the done probability is above
``done_threshold`` (never before ``min_steps`` actions), ``Stop.CAP`` at ``max_steps`` actions when that is
set. Its ``watch`` is on: the step monitor (:class:`pasta.tasks.step.GoalMonitor`) watches a learned policy's
progress instead of trusting its done head alone.

Checkpoints: ``DIR/model.safetensors`` + ``DIR/model.json`` with module ``"policy"`` and config
``{"skill", "tool", "network": PolicyConfig}`` (written by :func:`pasta.train.policy.train_policy`
through the shared loop of :mod:`pasta.train.loop`).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import torch

from pasta.core.errors import InputError
from pasta.core.skill import Controller, Skill, SkillObservation
from pasta.core.step import Stop
from pasta.policy.network import PolicyConfig, PolicyNet

__all__ = ["MODULE", "LearnedPolicy", "PolicyController", "load_policy"]

#: checkpoint module name of a policy
MODULE = "policy"


class LearnedPolicy:
    """A trained policy network of one skill.

    Args:
        net: the network.
        skill: name of the skill it was trained for (checked when a controller is made).
        done_threshold: done when ``sigmoid(logit) > done_threshold``.
        min_steps: the done head is ignored before this many actions.
        max_steps: done at this many actions whatever the done head says (0: no limit of its own; the
            skill's step limit still applies).
        seed: seed of the point subsampling of each controller.
        reset: optional learned reset pose (:class:`pasta.policy.reset.ResetPose`): the tool starts at
            the piece centroid ``x`` plus its predicted offset (see :meth:`approach_pose`).
        start_step: the step counter a controller starts from when it starts at the learned reset pose
            (default: the regressor's own ``start_step``).

    A checkpoint directory may also hold a reset-pose regressor ``DIR/reset.*``; :meth:`load` attaches it
    unless ``reset=False``. Without one the policy starts from the skill's own approach pose, as before.

    A checkpoint may carry its stopping rule (selected on validation configs by
    :mod:`pasta.train.select`) in ``config.controller``; :meth:`load` uses it unless overridden.
    """

    def __init__(self, net: PolicyNet, skill: str, *, done_threshold: float = 0.5, min_steps: int = 1,
                 max_steps: int = 0, seed: int = 0, reset: Any = None, start_step: int | None = None) -> None:
        self.net = net.eval()
        self.reset = reset
        self.start_step = start_step
        self.skill = skill
        self.done_threshold = done_threshold
        self.min_steps = min_steps
        self.max_steps = max_steps
        self.seed = seed

    @property
    def config(self) -> PolicyConfig:
        return self.net.cfg

    @classmethod
    def load(cls, directory: str | os.PathLike, skill: str | None = None, *, device: str = "cpu", **kwargs: Any) -> LearnedPolicy:
        """Load ``DIR/model.*``; with ``skill`` the checkpoint must belong to that skill."""
        from pasta.io.checkpoint import load_checkpoint

        ckpt = load_checkpoint(directory, module=MODULE, expect={"skill": skill} if skill else None,
                               hint=f"train one with `pasta train policy skill={skill or 'NAME'} data=DIR out={directory}`")
        net = PolicyNet(PolicyConfig.from_dict(ckpt.config["network"]))
        net.load_state_dict(ckpt.tensors)
        rule = {k: v for k, v in dict(ckpt.config.get("controller") or {}).items()
                if k in ("done_threshold", "min_steps", "max_steps")}
        if kwargs.get("reset", True) is True:
            from pasta.policy.reset import load_reset

            kwargs["reset"] = load_reset(directory)
        elif kwargs.get("reset") is False:
            kwargs["reset"] = None
        return cls(net.to(device), ckpt.config["skill"], **{**rule, **kwargs})

    def controller(self, skill: Skill) -> PolicyController:
        """A fresh closed-loop controller for ``skill`` (must be the skill the policy was trained for)."""
        if skill.name != self.skill:
            raise InputError(f"policy trained for '{self.skill}' cannot drive skill '{skill.name}'")
        return PolicyController(self, skill)

    def approach_pose(self, skill: Skill, piece: np.ndarray, goal: np.ndarray | None,
                      scene: np.ndarray | None = None) -> Any:
        """The learned start pose of the tool: the skill's approach pose with ``x`` replaced by the
        regressor's (:meth:`pasta.policy.reset.ResetPose.tool_x`: the piece centroid ``x`` plus its offset,
        through the skill's ``reset_tool_x`` when it learned the skill's target); ``None`` without a
        regressor (or a goal)."""
        if self.reset is None or goal is None:
            return None
        from pasta.core import ToolPose

        try:
            base = skill.approach_pose(piece, goal, scene=scene)  # type: ignore[call-arg]  # beyond the contract
        except TypeError:
            base = skill.approach_pose(piece, goal)
        return ToolPose((self.reset.tool_x(skill, piece, goal), *base.position[1:]), base.yaw)

    @torch.no_grad()
    def predict(self, dough: np.ndarray, tool: np.ndarray, goal: np.ndarray,
                step: np.ndarray | None = None, pose: np.ndarray | None = None,
                prev_action: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Batched inference: ``dough (B, P, 3)``, ``tool (B, T, 3)``, ``goal (B, G, 3)`` (already at the
        network's point counts) and, for a network with ``step_feature``, ``step (B,)`` (actions taken so
        far; default 0), with ``pose_feature``, ``pose (B, 7)`` (the tool pose; required) and, with
        ``action_feature``, ``prev_action (B, A)`` (the previous action; default zeros) ->
        ``action (B, A)``, ``done probability (B,)``."""
        dev = next(self.net.parameters()).device
        clouds = [torch.as_tensor(np.asarray(x, np.float32), device=dev) for x in (dough, tool, goal)]
        t = None
        if self.net.cfg.step_feature:
            t = torch.as_tensor(np.zeros(len(dough)) if step is None else np.asarray(step, np.float32).reshape(-1),
                                dtype=torch.float32, device=dev)
        p = None
        if self.net.cfg.pose_feature:
            if pose is None:
                raise InputError("this policy takes the tool pose: pass pose (B, 7)")
            p = torch.as_tensor(np.asarray(pose, np.float32).reshape(-1, 7), device=dev)
        prev = None
        if self.net.cfg.action_feature:
            shape = (len(dough), self.net.cfg.action_dim)
            prev = torch.as_tensor(np.zeros(shape, np.float32) if prev_action is None
                                   else np.asarray(prev_action, np.float32).reshape(shape), device=dev)
        a, logit = self.net(*clouds, t, p, prev)
        return a.cpu().numpy(), torch.sigmoid(logit).cpu().numpy()


class PolicyController(Controller):
    """Drives one execution of a skill with a :class:`LearnedPolicy`."""

    #: a learned done head can stay low while the policy pushes its piece past the goal: the monitor watches
    watch = True

    def __init__(self, policy: LearnedPolicy, skill: Skill | None = None) -> None:
        self.policy = policy
        self.skill = skill
        self.rng = np.random.default_rng(policy.seed)
        self.steps = 0
        self.first_step = 0
        self.last_done_prob = 0.0
        self.prev_action = np.zeros(policy.config.action_dim, np.float32)

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None, scene: np.ndarray | None = None) -> Any:
        """The policy's learned start pose (:meth:`LearnedPolicy.approach_pose`) or ``None`` (then the
        skill's own); starting there, the step counter starts at the policy's ``start_step``."""
        pose = None if self.skill is None else self.policy.approach_pose(self.skill, piece, goal, scene)
        if pose is None:
            self.first_step = 0
        else:
            start = self.policy.start_step
            self.first_step = int(self.policy.reset.start_step if start is None else start)
        return pose

    def reset(self, obs: SkillObservation) -> None:
        self.rng = np.random.default_rng(self.policy.seed)
        self.steps = self.first_step
        self.prev_action = np.zeros(self.policy.config.action_dim, np.float32)

    def _pick(self, cloud: np.ndarray | None, n: int, what: str) -> np.ndarray:
        cloud = np.asarray(cloud, np.float32)
        if cloud.ndim != 2 or cloud.shape[1] != 3 or len(cloud) == 0:
            raise InputError(f"policy observation: {what} must be a non-empty (N, 3) array, got shape {cloud.shape}")
        return cloud[self.rng.choice(len(cloud), size=n, replace=len(cloud) < n)]

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, Stop | None]:
        cfg = self.policy.config
        dough = self._pick(obs.piece, cfg.dough_points, "piece")
        tool = self._pick(obs.tool_points, cfg.tool_points, "tool_points")
        goal = self._pick(obs.goal, cfg.goal_points, "goal")
        action, prob = self.policy.predict(dough[None], tool[None], goal[None], np.array([self.steps]),
                                            np.asarray(obs.tool_pose, np.float32).reshape(1, -1)[:, :7],
                                            self.prev_action[None])
        self.prev_action = action[0].astype(np.float32)
        self.steps += 1
        taken = self.steps - self.first_step
        self.last_done_prob = float(prob[0])
        if taken >= self.policy.min_steps and self.last_done_prob > self.policy.done_threshold:
            stop = Stop.DONE
        elif 0 < self.policy.max_steps <= taken:
            stop = Stop.CAP  # the done head has not fired, but the policy's own budget is used up
        else:
            stop = None
        return action[0].astype(np.float32), stop


def load_policy(directory: str | os.PathLike, skill: Skill, **kwargs: Any) -> LearnedPolicy:
    """Load the policy of ``skill`` from ``directory`` and attach it to the skill; return it."""
    policy = LearnedPolicy.load(directory, skill.name, **kwargs)
    skill.attach_policy(policy)
    return policy
