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
    save_checkpoint(directory, module="feasibility", tensors=model.state_dict(),
                    config={**model.config(), "skill": skill, "scope": "entity", "output_box": None, "train": {}})
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


def test_other_format_versions_fail_with_one_error_naming_the_version_and_the_fix(tmp_path):
    save_feasibility(tmp_path)
    header = json.loads((tmp_path / "model.json").read_text())
    for version in (1, 99):
        header["format_version"] = version
        (tmp_path / "model.json").write_text(json.dumps(header))
        with pytest.raises(IncompatibleCheckpointError, match=f"format_version {version}; this pasta reads version 2"):
            load_checkpoint(tmp_path, module="feasibility")
    # a loader's own training command is the fix it names
    with pytest.raises(IncompatibleCheckpointError, match="format_version 1; .*pasta train feasibility .*skill=cut"):
        header["format_version"] = 1
        (tmp_path / "model.json").write_text(json.dumps(header))
        load_feasibility(tmp_path, skill="cut")


def test_loaders_read_every_key_and_default_none(tmp_path):
    """Format version 2 writes every key a loader needs; one missing is an error, not a default."""
    save_feasibility(tmp_path)
    header = json.loads((tmp_path / "model.json").read_text())
    del header["config"]["output_box"]
    (tmp_path / "model.json").write_text(json.dumps(header))
    with pytest.raises(KeyError, match="output_box"):
        load_feasibility(tmp_path, skill="cut")


def test_entity_and_flat_networks_name_their_scope(tmp_path):
    save_feasibility(tmp_path)
    with pytest.raises(IncompatibleCheckpointError, match="scope is 'entity', expected 'scene'"):
        load_feasibility(tmp_path, skill="cut", scope="scene")


def test_shipped_weights_are_format_2_with_every_key():
    from dataclasses import fields

    from pasta.policy.network import PolicyConfig
    from pasta.policy.reset import ResetConfig
    from pasta.weights import ROOT

    headers = sorted(p for p in ROOT.rglob("*.json") if not p.name.endswith("metrics.json"))
    assert len(headers) >= 13
    for path in headers:
        doc = json.loads(path.read_text())
        assert doc["format_version"] == FORMAT_VERSION == 2, path
        config = doc["config"]
        if doc["module"] == "policy":
            assert set(config["network"]) == {f.name for f in fields(PolicyConfig)}, path
        elif doc["module"] == "reset_pose":
            assert set(config["network"]) == {f.name for f in fields(ResetConfig)}, path
        elif doc["module"] in ("feasibility", "set_cost"):
            scope = "scene" if path.relative_to(ROOT).parts[0] == "flat" else "entity"  # the Flat 3D baseline's
            assert config["scope"] == scope and "train" in config, path
            assert doc["module"] != "feasibility" or "output_box" in config, path


def test_missing_checkpoint_names_the_fix(tmp_path):
    with pytest.raises(MissingComponentError, match="pasta train feasibility .*skill=roll"):
        load_feasibility(tmp_path / "none", skill="roll")


def test_no_pickle_in_weights(tmp_path):
    save_feasibility(tmp_path)
    raw = (tmp_path / "model.safetensors").read_bytes()
    assert b"\x80\x04" not in raw[:16]  # not a pickle stream
    header_len = int.from_bytes(raw[:8], "little")
    assert json.loads(raw[8 : 8 + header_len])["__metadata__"]["module"] == "feasibility"
