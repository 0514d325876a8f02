"""Near-miss negatives of feasibility training: produced entities (all, or one) moved by 3-10 cm."""

from __future__ import annotations

import pytest
import torch

from pasta.core.errors import ConfigError
from pasta.train.feasibility import FeasibilityTrainConfig, shifted_negatives, train_dict

Z = 2  # latent u = [z (2), t (3)]


def tuples(b: int = 400):
    g = torch.Generator().manual_seed(0)
    return torch.rand(b, 1, Z + 3, generator=g), torch.rand(b, 2, Z + 3, generator=g)


def test_outputs_move_together_by_the_asked_length_in_the_table_plane():
    u_in, u_out = tuples()
    n_in, n_out = shifted_negatives(u_in, u_out, 3, Z, 0.03, 0.1, torch.Generator().manual_seed(1))
    assert n_in.shape == (1200, 1, Z + 3) and torch.equal(n_in, u_in.repeat(3, 1, 1))  # inputs untouched
    d = n_out - u_out.repeat(3, 1, 1)
    assert torch.equal(d[..., :Z], torch.zeros_like(d[..., :Z]))  # shapes untouched
    assert torch.allclose(d[:, 0, Z:], d[:, 1, Z:], atol=1e-6)  # both produced entities by one offset
    length = d[:, 0, Z:].norm(dim=-1)
    assert float(length.min()) >= 0.03 - 1e-6 and float(length.max()) <= 0.1 + 1e-6
    assert float(d[:, 0, Z + 1].abs().max()) < 1e-6  # in the table plane


def test_table_plane_draws_are_the_earlier_ones():
    u_in, u_out = tuples(50)
    _, got = shifted_negatives(u_in, u_out, 2, Z, 0.03, 0.1, torch.Generator().manual_seed(5))
    g = torch.Generator().manual_seed(5)  # the formula, written out
    ref = u_out.repeat(2, 1, 1).clone()
    angle = torch.rand(100, generator=g) * 2 * torch.pi
    length = 0.03 + torch.rand(100, generator=g) * 0.07
    ref[:, :, Z] += (length * torch.cos(angle))[:, None]
    ref[:, :, Z + 2] += (length * torch.sin(angle))[:, None]
    assert torch.equal(got, ref)


def test_one_entity_moves_and_the_others_stay():
    u_in, u_out = tuples()
    n_in, n_out = shifted_negatives(u_in, u_out, 3, Z, 0.03, 0.1, torch.Generator().manual_seed(2), "one")
    assert torch.equal(n_in, u_in.repeat(3, 1, 1))
    d = (n_out - u_out.repeat(3, 1, 1))[..., Z:].norm(dim=-1)  # (B, 2) displacement per produced entity
    moved = d > 1e-6
    assert torch.equal(moved.sum(1), torch.ones(1200, dtype=torch.long))  # exactly one of the two
    assert 0.4 < float(moved[:, 0].float().mean()) < 0.6  # either one, uniformly
    assert float(d[moved].min()) >= 0.03 - 1e-6 and float(d[moved].max()) <= 0.1 + 1e-6
    # the default moves all
    _, all_out = shifted_negatives(u_in, u_out, 3, Z, 0.03, 0.1, torch.Generator().manual_seed(2))
    assert torch.equal(all_out, shifted_negatives(u_in, u_out, 3, Z, 0.03, 0.1, torch.Generator().manual_seed(2),
                                                  "all")[1])
    assert train_dict(FeasibilityTrainConfig(skill="cut", shift_entities="one"))["shift_entities"] == "one"
    with pytest.raises(ConfigError, match="shift_entities"):
        shifted_negatives(u_in, u_out, 1, Z, 0.03, 0.1, torch.Generator(), "some")


def _task(hard: int, shift: int = 0):
    from pasta.testing import AnalyticEncoder
    from pasta.train.feasibility import FeasibilityTask

    enc = AnalyticEncoder()
    g = torch.Generator().manual_seed(0)
    pos = lambda b: (torch.rand(b, 1, enc.latent_dim, generator=g), torch.rand(b, 2, enc.latent_dim, generator=g))  # noqa: E731
    cfg = FeasibilityTrainConfig(skill="cut", hard_per_positive=hard, shift_per_positive=shift)
    return FeasibilityTask("cut", 1, 2, pos(64), pos(32), enc, cfg)


@pytest.mark.parametrize("shift", [0, 2])
def test_no_hard_negatives_trains_on_random_ones_and_still_measures_hard(shift):
    """``hard_per_positive=0`` (the paper's ablation): a finite loss without the hard term; val_auc_hard is
    still measured on held-out hard negatives, which the validation loss leaves out as training does."""
    without, with_hard = _task(0, shift), _task(10, shift)
    loss = without.loss(torch.arange(16), torch.Generator().manual_seed(0))
    assert torch.isfinite(loss)
    metrics = without.validate()
    assert all(torch.isfinite(torch.tensor(v)) for v in metrics.values())
    assert len(without.val_hard[0]) == len(with_hard.val_hard[0])  # the same held-out negatives measured
    if shift == 0:
        assert without.val_hard_trained is None and with_hard.val_hard_trained is not None
        with torch.no_grad():
            base = without._weighted((without.val_in, without.val_out), None, without.val_random)
        assert float(base) == pytest.approx(metrics["val_loss"])
    else:  # only the near misses are trained on, so only they count in the validation loss
        assert len(without.val_hard_trained[0]) == len(without.val_shift[0])
