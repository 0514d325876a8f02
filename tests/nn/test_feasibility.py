import torch

from pasta.nn.feasibility import SetFeasibility
from pasta.plugins import get_plugins
from pasta.testing import check_skill


def test_permutation_and_translation_invariance():
    torch.manual_seed(0)
    f = SetFeasibility(2, 3, 5, hidden=32).eval()
    u_in, u_out = torch.randn(6, 2, 5), torch.randn(6, 3, 5)
    with torch.no_grad():
        base = f(u_in, u_out)
        assert base.shape == (6,) and ((base >= 0) & (base <= 1)).all()
        assert torch.allclose(base, f(u_in.flip(1), u_out[:, [2, 0, 1]]), atol=1e-6)
        shift = torch.tensor([0.0, 0.0, 0.3, -0.1, 0.2])
        assert torch.allclose(base, f(u_in + shift, u_out + shift), atol=1e-5)
        # Swapping inputs and outputs is a different question: the two sides have their own networks.
        g = SetFeasibility(2, 2, 5, hidden=32).eval()
        a, b = torch.randn(6, 2, 5), torch.randn(6, 2, 5)
        assert not torch.allclose(g(a, b), g(b, a))


def test_attaches_to_a_registered_skill():
    cut = get_plugins().skills.create("cut")
    cut.attach_feasibility(SetFeasibility(cut.n_in, cut.n_out, 5, hidden=16).eval())
    check_skill(cut, latent_dim=5)
