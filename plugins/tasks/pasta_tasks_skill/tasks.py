"""``task=skill``: one registered skill, alone, on the scene its plugin draws for demonstrations.

The initial state is the skill's demonstration scene (``Skill.demo_scene``, variant ``task.scene``, with the
static tools its plugin stands up, ``Skill.demo_tools``); the goal is what the skill's scripted expert makes
of it with parameters the skill samples (``Skill.sample_expert_params``). So a plugin author runs a new skill
in the simulator, plans it and scores it before writing a task:

    pasta run task=skill task.skill=press method=oracle        # the expert's chain, heuristic controller
    pasta run task=skill task.skill=press                      # planned (once its feasibility is trained)
    pasta eval task=skill task.skill=press num=20

A skill that consumes several pieces (``n_in`` > 1, e.g. gather) gets them as one attended piece, as the
gather_move task gives its lumps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pasta.core import Scene
from pasta.core.errors import ConfigError
from pasta.tasks.base import Generation, Task, TaskConfig


@dataclass
class SkillTaskConfig(TaskConfig):
    """``task.skill``: the registered skill to run (default ``push``); ``task.scene``: the variant of its
    demonstration scene (``default``, or one its plugin declares, e.g. roll's ``sheet``)."""

    skill: str = "push"
    scene: str = "default"

    def __post_init__(self) -> None:
        if not isinstance(self.skill, str) or not self.skill:
            raise ConfigError("task.skill= needs the name of a registered skill (`pasta plugins` lists them)")


class SkillTask(Task):
    """The skill ``config.skill`` alone on its demonstration scene."""

    name = "skill"
    config_class = SkillTaskConfig
    summary = "any registered skill alone, on its own demonstration scene (task.skill=NAME)"

    def __init__(self, config=None, sim_config=None, *, skill_configs=None) -> None:
        super().__init__(config, sim_config, skill_configs=skill_configs)
        from pasta.demos.scene import check_demo_skill, check_variant, variant_config

        cls = check_demo_skill(self.config.skill)  # unknown, or without a demo scene and an expert: named here
        check_variant(cls, self.config.scene)
        name = self.config.skill
        if self.config.scene != "default":  # the variant's settings, under any the run config gives
            from pasta.plugins import get_plugins

            config_class = get_plugins().skills.info(name).config
            base = self.skill_configs.get(name) or (config_class() if config_class is not None else None)
            self.skill_configs[name] = variant_config(base, cls, self.config.scene)

    @property
    def skeleton(self) -> tuple[str, ...]:  # type: ignore[override]  # the chain is the configured skill
        return (self.config.skill,)

    def scene(self) -> Scene:
        """The static tools the skill's demonstration scene stands up, with their tops where they are put."""
        from pasta.demos.generate import demo_tools
        from pasta.plugins import get_plugins

        placed = demo_tools(self.skill(self.config.skill), self.config.scene)
        tools = get_plugins().tools
        tops = tuple(pose.position[1] + tools.info(name).spec.extent()[1][1] for name, pose in placed.items())
        return Scene(static=tuple(placed), surfaces=tops, source=f"task skill ({self.config.skill})")

    def build(self, gen: Generation) -> None:
        from pasta.demos.generate import demo_tools
        from pasta.demos.scene import scene_boxes

        skill = self.skill(self.config.skill)
        gen.start(scene_boxes(skill, gen.rng, float(gen.sim.floor_y), self.config.scene))
        placed = demo_tools(skill, self.config.scene)
        for tool, pose in placed.items():  # e.g. the board a lift sets its piece down on
            gen.sim.set_tool_pose(tool, pose.position, yaw=pose.yaw)
        if placed:
            gen.init = gen.sim.get_state()
        if len(gen.pieces) > 1:  # the skill consumes every piece of its scene: one attended piece
            gen.pieces[:] = [np.concatenate(gen.pieces)]
        gen.run(self.config.skill, 0)
