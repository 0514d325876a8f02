"""Decoded goals: training goals that look like the sub-goals a plan hands a controller at execution.

A plan's sub-goal for a step is the VAE's decoding of a shape code the planner chose, not an observed cloud:
smoother, often a little lower, longer or off-centre. A controller trained only on exact demonstration
goals can fail on it (the lift carried LiftSpread's cube into the board's edge, chasing a decoded goal
1.5 cm lower and 3 cm longer than the cube it sets down). The trainers of the reset pose and of the policy
replace a share of their goals with such decodings, noised on the shape code and, for the policy, shifted.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

__all__ = ["DecodedPieces", "check_encoder_weights", "decoded_pieces", "goal_draw", "load_encoder"]

#: per piece of a goal: the exact piece ``(n, 3)`` and its reconstructions ``(draws, n, 3)``
DecodedPieces = list[tuple[np.ndarray, np.ndarray]]


def load_encoder(weights: str = "") -> Any:
    """The point-cloud VAE encoder whose decodings the goals mimic (``weights``: a `pasta train vae`
    output; empty: the shipped one)."""
    from pasta.nn.config import PointVAEEncoderConfig
    from pasta.nn.encoders import PointVAEEncoder

    return PointVAEEncoder(PointVAEEncoderConfig(weights=weights))


def check_encoder_weights(weights: str) -> None:
    """Refuse ``encoder_weights=`` that hold no trained VAE (before any training starts)."""
    from pasta.core.errors import ConfigError
    from pasta.io.checkpoint import checkpoint_exists

    if weights and not checkpoint_exists(weights):
        raise ConfigError(f"encoder_weights={weights}: no trained VAE there (model.safetensors and model.json); give a "
                          "`pasta train vae` output, or leave it empty for the shipped one")


def decoded_pieces(goal: np.ndarray, encoder: Any, *, noise: float = 0.0, draws: int = 1,
                   rng: np.random.Generator | None = None) -> DecodedPieces:
    """The pieces of ``goal (G, 3)`` (DBSCAN, :func:`pasta.core.decompose.decompose_labels`), each with
    ``draws`` reconstructions by ``encoder`` ``(draws, n, 3)`` (encoded, Gaussian ``noise`` on the shape
    code ``z``, decoded to the piece's own point count ``n``): the kind of piece a plan's decoded sub-goal
    hands a controller at execution, where the planner chose the shape code. ``encoder``: a
    :class:`pasta.core.Encoder` (:meth:`~pasta.core.Encoder.decode_clouds`)."""
    from pasta.core.decompose import decompose_labels

    rng = rng or np.random.default_rng(0)
    labels = decompose_labels(goal)
    pieces = [np.asarray(goal[labels == k], np.float32) for k in range(int(labels.max()) + 1)]
    z_dim = int(getattr(encoder, "z_dim", 0))
    out = []
    for piece in pieces:
        with torch.no_grad():
            u = torch.as_tensor(encoder.encode(piece[None])).repeat(max(1, draws), 1)
        if noise > 0 and z_dim:
            u[:, :z_dim] += noise * torch.as_tensor(rng.standard_normal((len(u), z_dim)), dtype=u.dtype)
        out.append((piece, np.stack(encoder.decode_clouds(u, len(piece)))))
    return out


def goal_draw(goal: np.ndarray, pieces: Sequence[tuple[np.ndarray, np.ndarray]] | None, p: float,
              rng: np.random.Generator, shift: float = 0.0) -> np.ndarray:
    """``goal`` with each of its ``pieces`` replaced by one of its reconstructions with probability ``p``, a
    replaced piece moved by a uniform offset in ``[-shift, shift]`` per axis (metres)."""
    if not pieces or p <= 0:
        return goal
    out = []
    for exact, recs in pieces:
        if rng.random() < p:
            piece = recs[rng.integers(len(recs))]
            if shift > 0:
                piece = piece + rng.uniform(-shift, shift, 3).astype(piece.dtype)
            out.append(piece)
        else:
            out.append(exact)
    return np.concatenate(out)
