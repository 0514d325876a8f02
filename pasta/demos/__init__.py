"""Demonstrations: generation with the scripted experts (``pasta demos``); :mod:`pasta.train.data` reads them."""

from pasta.demos.generate import DEMO_SKILLS, DemoConfig, demo_path, generate_demos, validate

__all__ = ["DEMO_SKILLS", "DemoConfig", "demo_path", "generate_demos", "validate"]
