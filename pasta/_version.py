"""The version of pasta: the one source (pyproject reads it; ``pasta.__version__`` re-exports it)."""

__version__ = "0.1.0"
