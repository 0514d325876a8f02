"""pasta: planning with spatial and temporal abstraction over dough point clouds (PASTA, CoRL 2022)."""

__version__ = "0.1.0"
