"""The generic single-skill task: any registered skill with a demonstration scene and an expert, run alone
(``pasta run task=skill task.skill=NAME``), without writing a task of its own."""
