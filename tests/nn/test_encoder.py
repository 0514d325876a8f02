import pytest
import torch

from pasta.core.errors import MissingComponentError
from pasta.nn.config import PointVAEEncoderConfig
from pasta.nn.encoders import FlatEncoder, PointVAEEncoder
from pasta.plugins import get_plugins
from pasta.testing import check_encoder


def test_registered_encoder_loads_weights_and_conforms(vae_dir):
    registry = get_plugins().encoders
    assert {"pc_vae", "flat"} <= set(registry.names())
    encoder = registry.create("pc_vae", PointVAEEncoderConfig(weights=str(vae_dir)))
    check_encoder(encoder)
    assert encoder.z_dim == 2 and encoder.latent_dim == 5
    assert encoder.t_low == pytest.approx((0.1, 0.02, 0.2))


def test_encode_is_mean_and_centroid_decode_deterministic(tiny_vae):
    encoder = PointVAEEncoder(PointVAEEncoderConfig(weights=""), model=tiny_vae)
    clouds = torch.rand(3, 700, 3) * 0.1 + 0.4
    u = encoder.encode(clouds)
    assert torch.equal(u, encoder.encode(clouds))
    assert torch.allclose(u[:, 2:], clouds.mean(1))
    a, b = encoder.decode(u, 333), encoder.decode(u, 333)
    assert a.shape == (3, 333, 3) and torch.equal(a, b)


def test_prior_in_box(tiny_vae):
    encoder = PointVAEEncoder(PointVAEEncoderConfig(weights=""), model=tiny_vae)
    u = encoder.sample_prior(500, torch.Generator().manual_seed(0))
    t = u[:, 2:]
    assert (t >= torch.tensor(encoder.t_low)).all() and (t <= torch.tensor(encoder.t_high)).all()
    assert abs(float(u[:, :2].std()) - 1.0) < 0.15


def test_missing_weights_name_the_training_command(tmp_path):
    with pytest.raises(MissingComponentError, match="pasta train vae"):
        PointVAEEncoder(PointVAEEncoderConfig(weights=str(tmp_path / "nothing")))
    from pasta.nn.config import FlatEncoderConfig

    with pytest.raises(MissingComponentError, match="flat=true"):
        get_plugins().encoders.create("flat", FlatEncoderConfig(weights=str(tmp_path / "nothing")))
    assert get_plugins().encoders.create("flat").scope == "scene"  # the shipped Flat 3D VAE (pasta/weights/flat)


def test_flat_encoder_refuses_entity_weights(vae_dir):
    from pasta.io.checkpoint import IncompatibleCheckpointError
    from pasta.nn.config import FlatEncoderConfig

    with pytest.raises(IncompatibleCheckpointError, match="scope"):
        FlatEncoder(FlatEncoderConfig(weights=str(vae_dir)))


def test_flat_encoder_scene_is_one_latent(tiny_vae):
    encoder = FlatEncoder(model=tiny_vae)
    assert encoder.encode_scene(torch.rand(900, 3).numpy()).shape == (1, 5)
