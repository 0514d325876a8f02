"""Demonstrations: generation with the scripted experts (``pasta demos``, :mod:`pasta.demos.generate`) and the
reader every trainer uses (:mod:`pasta.demos.data`: ``load_demos``, ``split_by_demo``).

The skills that can make them, and their scenes, come from the skill plugins (:mod:`pasta.demos.scene`).
"""

from pasta.demos.generate import DemoConfig, demo_path, generate_demos, validate
from pasta.demos.scene import check_demo_skill, demo_skills, scene_boxes, scene_particles, variants

__all__ = ["DemoConfig", "check_demo_skill", "demo_path", "demo_skills", "generate_demos", "scene_boxes",
           "scene_particles", "validate", "variants"]
