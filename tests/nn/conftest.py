import pytest
import torch

from pasta.io.checkpoint import save_checkpoint
from pasta.nn.vae import MODULE, PointVAE


def make_tiny_vae(seed: int = 0) -> PointVAE:
    torch.manual_seed(seed)
    model = PointVAE(z_dim=2, width=16, fold_hidden=16)
    model.scale.fill_(0.05)
    model.t_low.copy_(torch.tensor([0.1, 0.02, 0.2]))
    model.t_high.copy_(torch.tensor([0.9, 0.1, 0.8]))
    return model


@pytest.fixture
def vae_dir(tmp_path):
    model = make_tiny_vae()
    save_checkpoint(tmp_path / "vae", module=MODULE, tensors=model.state_dict(),
                    config={**model.config(), "scope": "entity"})
    return tmp_path / "vae"


@pytest.fixture
def tiny_vae():
    return make_tiny_vae()
