"""``Encoder.decode_clouds``: latents ``(K, D)`` -> ``K`` float32 clouds ``(num_points, 3)``, without gradients."""

import numpy as np
import torch

from pasta.core import Encoder


class _Line(Encoder):
    """Decodes ``[z, t]`` to ``num_points`` points on a segment of length ``z`` through ``t``."""

    z_dim = 1

    def encode(self, points):
        raise NotImplementedError

    def decode(self, latents, num_points):
        s = torch.linspace(-0.5, 0.5, num_points, dtype=latents.dtype)[None, :, None]
        x = s * latents[:, None, :1] * torch.tensor([1.0, 0.0, 0.0], dtype=latents.dtype)
        return x + latents[:, None, 1:]

    def sample_prior(self, n, generator):
        raise NotImplementedError


def test_decode_clouds_takes_tensors_arrays_and_lists_alike():
    enc = _Line()
    u = [[0.2, 0.5, 0.1, 0.5], [0.1, 0.3, 0.1, 0.4]]
    want = enc.decode(torch.tensor(u), 7).numpy()
    leaf = torch.tensor(u, dtype=torch.float64, requires_grad=True)  # a planner's latents: grads, float64
    for given in (u, np.asarray(u), torch.tensor(u), leaf):
        clouds = enc.decode_clouds(given, 7)
        assert len(clouds) == 2 and all(c.shape == (7, 3) and c.dtype == np.float32 for c in clouds)
        assert np.allclose(np.stack(clouds), want)
    assert enc.decode_clouds([], 7) == [] and enc.decode_clouds(np.zeros((0, 4)), 7) == []
