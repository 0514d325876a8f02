import json

import pytest
import torch

from pasta.core.errors import MissingComponentError
from pasta.io.checkpoint import (
    FORMAT_VERSION,
    IncompatibleCheckpointError,
    checkpoint_exists,
    load_checkpoint,
    save_checkpoint,
)
from pasta.nn.feasibility import SetFeasibility
from pasta.nn.loading import load_feasibility


def save_feasibility(directory, skill="cut", n_in=1, n_out=2):
    model = SetFeasibility(n_in, n_out, 5, hidden=8)
    save_checkpoint(directory, module="feasibility", tensors=model.state_dict(), config={**model.config(), "skill": skill})
    return model


def test_round_trip(tmp_path):
    model = save_feasibility(tmp_path)
    assert checkpoint_exists(tmp_path) and (tmp_path / "model.json").is_file()
    header = json.loads((tmp_path / "model.json").read_text())
    assert header["format_version"] == FORMAT_VERSION and header["module"] == "feasibility"
    loaded = load_feasibility(tmp_path, skill="cut", n_in=1, n_out=2, latent_dim=5)
    u_in, u_out = torch.randn(4, 1, 5), torch.randn(4, 2, 5)
    with torch.no_grad():
        assert torch.equal(model(u_in, u_out), loaded(u_in, u_out))
    ckpt = load_checkpoint(tmp_path, module="feasibility")
    assert set(ckpt.tensors) == set(model.state_dict())


def test_incompatible_checkpoint_lists_every_mismatch(tmp_path):
    save_feasibility(tmp_path)
    with pytest.raises(IncompatibleCheckpointError) as err:
        load_feasibility(tmp_path, skill="push", n_in=1, n_out=1, latent_dim=7)
    msg = str(err.value)
    assert "skill is 'cut', expected 'push'" in msg and "n_out is 2, expected 1" in msg and "latent_dim is 5, expected 7" in msg
    with pytest.raises(IncompatibleCheckpointError, match="module is 'feasibility', expected 'vae'"):
        load_checkpoint(tmp_path, module="vae")


def test_wrong_format_version(tmp_path):
    save_feasibility(tmp_path)
    header = json.loads((tmp_path / "model.json").read_text())
    header["format_version"] = 99
    (tmp_path / "model.json").write_text(json.dumps(header))
    with pytest.raises(IncompatibleCheckpointError, match="format_version is 99"):
        load_checkpoint(tmp_path, module="feasibility")


def test_missing_checkpoint_names_the_fix(tmp_path):
    with pytest.raises(MissingComponentError, match="pasta train feasibility .*skill=roll"):
        load_feasibility(tmp_path / "none", skill="roll")


def test_no_pickle_in_weights(tmp_path):
    save_feasibility(tmp_path)
    raw = (tmp_path / "model.safetensors").read_bytes()
    assert b"\x80\x04" not in raw[:16]  # not a pickle stream
    header_len = int.from_bytes(raw[:8], "little")
    assert json.loads(raw[8 : 8 + header_len])["__metadata__"]["module"] == "feasibility"
