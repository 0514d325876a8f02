"""Config dataclasses of the learned plugins (no torch import: the plugin registry reads these)."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.core import PluginConfig


@dataclass
class PointVAEEncoderConfig(PluginConfig):
    """Config of the ``pc_vae`` encoder.

    Attributes:
        weights: directory of a trained VAE (``pasta train vae ... out=models`` writes ``models/vae``);
            empty: the shipped weights (:mod:`pasta.weights`).
        encode_points: points fed to the PointNet per entity (a fixed, deterministic subset).
        device: torch device of the network.
    """

    weights: str = ""
    encode_points: int = 512
    device: str = "cpu"


@dataclass
class FlatEncoderConfig(PointVAEEncoderConfig):
    """Config of the ``flat`` encoder (the whole scene as one latent; Flat 3D baseline)."""

    weights: str = ""


@dataclass
class SetCostConfig(PluginConfig):
    """Config of the ``set_cost`` cost model.

    Attributes:
        weights: directory of a trained cost network (``pasta train cost ... out=models`` writes ``models/cost``);
            empty: the shipped weights (:mod:`pasta.weights`).
        device: torch device of the network.
    """

    weights: str = ""
    device: str = "cpu"
