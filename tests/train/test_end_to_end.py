import json

import numpy as np
import pytest
import torch

from pasta.cli import main
from pasta.core.decompose import decompose
from pasta.core.errors import ConfigError
from pasta.io.checkpoint import load_checkpoint
from pasta.nn.loading import load_models
from pasta.plugins import get_plugins
from pasta.testing import check_encoder, check_skill
from pasta.train.run import train


@pytest.fixture(scope="module")
def models(three_demos, tmp_path_factory, tiny):
    out = tmp_path_factory.mktemp("models")
    figures = {m: train(m, three_demos, out, {**tiny[m], **({"skill": "cut"} if m == "feasibility" else {})})
               for m in ("vae", "feasibility", "cost")}
    return out, figures


def test_three_modules_train_and_report(models):
    out, figures = models
    assert figures["vae"]["heldout_chamfer_mean"] > 0 and (out / "vae" / "reconstructions.png").is_file()
    assert 0.0 <= figures["feasibility"]["heldout_auc_hard"] <= 1.0
    assert -1.0 <= figures["cost"]["heldout_spearman"] <= 1.0
    for sub in ("vae", "feasibility/cut", "cost"):
        metrics = json.loads((out / sub / "metrics.json").read_text())
        assert metrics["train_demos"] == 2 and metrics["heldout_demos"] == 1


def test_trained_models_plug_into_planning_contracts(models, three_demos):
    out, _ = models
    cut = get_plugins().skills.create("cut")
    encoder, cost = load_models(out, [cut])
    check_encoder(encoder)
    check_skill(cut, latent_dim=encoder.latent_dim)
    dough = np.load(three_demos / "cut" / "demo_00001.npz", allow_pickle=False)["dough"]
    obs = encoder.encode(torch.from_numpy(np.stack(decompose(dough[0], num_points=128))))
    goal = encoder.encode(torch.from_numpy(np.stack(decompose(dough[-1], num_points=128))))
    assert obs.shape == (1, 5) and goal.shape == (2, 5)
    f = cut.feasibility(obs[None], goal[None])
    assert f.shape == (1,) and 0 <= float(f) <= 1
    # the box of the produced pieces' centroids is recorded and reaches the skill (the planner's box for it)
    low, high = (np.array(b) for b in cut.output_box)
    assert np.all(low <= high) and np.all(low <= goal[:, 2:].numpy().max(0) + 1e-6)
    assert np.all(goal[:, 2:].numpy().min(0) <= high + 1e-6) and high[1] < 0.2  # pieces on the floor
    assert cost.set_cost(obs[None], goal[None]).shape == (1,)


def test_resume_continues_the_same_run(three_demos, tmp_path, tiny):
    cfg = {**tiny["cost"], "epochs": "1"}
    train("vae", three_demos, tmp_path, tiny["vae"])
    train("cost", three_demos, tmp_path / "a", {**cfg, "vae": str(tmp_path / "vae")})
    train("cost", three_demos, tmp_path / "a", {**cfg, "epochs": "2", "vae": str(tmp_path / "vae")})
    train("cost", three_demos, tmp_path / "b", {**cfg, "epochs": "2", "vae": str(tmp_path / "vae")})
    a = load_checkpoint(tmp_path / "a" / "cost", module="set_cost", name="last")
    b = load_checkpoint(tmp_path / "b" / "cost", module="set_cost", name="last")
    assert len(a.state["history"]) == 2
    assert all(torch.allclose(a.tensors[k], b.tensors[k], atol=1e-6) for k in b.tensors)
    with pytest.raises(ConfigError, match="hidden"):
        train("cost", three_demos, tmp_path / "a", {**cfg, "epochs": "3", "hidden": "8", "vae": str(tmp_path / "vae")})


def test_cli_errors(three_demos, tmp_path, capsys):
    assert main(["train", "cost", f"data={three_demos}"]) == 2
    assert "out=DIR" in capsys.readouterr().err
    assert main(["train", "cost", f"data={three_demos}", f"out={tmp_path}", "epoch=3"]) == 2
    assert "did you mean 'epochs'" in capsys.readouterr().err
    assert main(["train", "feasibility", f"data={three_demos}", f"out={tmp_path}"]) == 2
    assert "skill=NAME" in capsys.readouterr().err
    assert main(["train", "vae", f"data={tmp_path / 'missing'}", f"out={tmp_path}"]) == 2


def test_flat_vae_for_the_flat_baseline(three_demos, tmp_path, tiny):
    from pasta.nn.config import FlatEncoderConfig

    figures = train("vae", three_demos, tmp_path, {**tiny["vae"], "epochs": "1", "flat": "true"})
    assert figures["heldout_examples"] == 3  # one held-out demo, states 0, 2 and 4
    encoder = get_plugins().encoders.create("flat", FlatEncoderConfig(weights=str(tmp_path / "vae")))
    check_encoder(encoder)
    dough = np.load(three_demos / "cut" / "demo_00000.npz", allow_pickle=False)["dough"]
    assert encoder.encode_scene(dough[-1]).shape == (1, 5)
