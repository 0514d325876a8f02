"""The CostModel contract: distance between entities, and between entity sets under the best matching."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

from pasta.core.matching import min_cost_matching

if TYPE_CHECKING:
    import torch


class CostModel(ABC):
    """Base class of cost-model plugins (e.g. a network predicting the Chamfer distance of two entities)."""

    def __init__(self, config: Any = None) -> None:
        self.config = config

    @abstractmethod
    def pairwise(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """Cost of every entity pair: ``a (B, K, D)``, ``b (B, G, D)`` -> ``(B, K, G)``, >= 0."""

    def set_cost(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """Summed cost of ``a (B, K, D)`` against ``b (B, G, D)`` under the cheapest matching -> ``(B,)``."""
        return min_cost_matching(self.pairwise(a, b))[0]
