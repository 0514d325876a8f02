"""Demonstrations: generation with the scripted experts (``pasta demos``) and the dataset loader."""

from pasta.demos.dataset import DemoBatch, DemoDataset, Demonstration, load_demo
from pasta.demos.generate import DEMO_SKILLS, DemoConfig, demo_path, generate_demos, validate

__all__ = ["DEMO_SKILLS", "DemoBatch", "DemoConfig", "DemoDataset", "Demonstration", "demo_path",
           "generate_demos", "load_demo", "validate"]
