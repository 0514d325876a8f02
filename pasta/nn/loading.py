"""Load trained modules from a models directory (see :mod:`pasta.nn` for the layout) and attach them."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pasta.nn import COST_DIR, FEASIBILITY_DIR, VAE_DIR
from pasta.nn.feasibility import SetFeasibility

FEASIBILITY_MODULE = "feasibility"


def feasibility_hint(skill: str) -> str:
    return f"train one with `pasta train feasibility data=DIR out=models skill={skill}` (writes models/feasibility/{skill})"


def load_feasibility(
    directory: str | Path,
    *,
    skill: str | None = None,
    n_in: int | None = None,
    n_out: int | None = None,
    latent_dim: int | None = None,
    device: str = "cpu",
    scope: str = "entity",
) -> SetFeasibility:
    """Load a trained :class:`SetFeasibility`, checking the skill name and sizes that are given and the scope
    (``"entity"``; ``"scene"`` accepts only Flat 3D networks, trained with ``flat=true``)."""
    from pasta.io.checkpoint import load_checkpoint

    given = (("skill", skill), ("n_in", n_in), ("n_out", n_out), ("latent_dim", latent_dim), ("scope", scope))
    expect = {k: v for k, v in given if v is not None}
    ckpt = load_checkpoint(directory, module=FEASIBILITY_MODULE, expect=expect, hint=feasibility_hint(skill or "NAME"))
    c = ckpt.config
    model = SetFeasibility(c["n_in"], c["n_out"], c["latent_dim"], c["hidden"])
    model.load_state_dict(ckpt.tensors)
    box = c["output_box"]  # null: the skill's outputs recorded no box (pasta.core.Skill.output_box)
    model.output_box = None if box is None else (tuple(float(v) for v in box[0]), tuple(float(v) for v in box[1]))
    model.train_settings = dict(c["train"])  # how it was trained (e.g. its negatives), for run summaries
    return model.requires_grad_(False).to(device).eval()


def attach_feasibility(skills: Iterable[Any], root: str | Path, *, latent_dim: int | None = None, strict: bool = True) -> list[str]:
    """Attach ``root/feasibility/<skill>`` (or the shipped one, :func:`pasta.weights.module_dir`) to every skill;
    return the names attached.

    With ``strict=False`` skills without a trained network are skipped; otherwise they raise
    :class:`~pasta.core.errors.MissingComponentError` with the training command.
    """
    from pasta.core.errors import MissingComponentError
    from pasta.weights import module_dir

    attached = []
    for skill in skills:
        try:
            model = load_feasibility(module_dir(root, f"{FEASIBILITY_DIR}/{skill.name}"), skill=skill.name, n_in=skill.n_in,
                                     n_out=skill.n_out, latent_dim=latent_dim)
        except MissingComponentError:
            if strict:
                raise
            continue
        skill.attach_feasibility(model)
        attached.append(skill.name)
    return attached


def load_models(root: str | Path, skills: Iterable[Any] = (), *, device: str = "cpu") -> tuple[Any, Any]:
    """The ``pc_vae`` encoder and ``set_cost`` model under ``root``; attaches feasibility to ``skills``.

    Returns:
        ``(encoder, cost_model)``.
    """
    from pasta.nn.config import PointVAEEncoderConfig, SetCostConfig
    from pasta.nn.cost import SetCostModel
    from pasta.nn.encoders import PointVAEEncoder

    encoder = PointVAEEncoder(PointVAEEncoderConfig(weights=str(Path(root) / VAE_DIR), device=device))
    cost = SetCostModel(SetCostConfig(weights=str(Path(root) / COST_DIR), device=device))
    attach_feasibility(skills, root, latent_dim=encoder.latent_dim)
    return encoder, cost
