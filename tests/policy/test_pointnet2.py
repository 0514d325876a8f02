"""PointNet++ building blocks: shapes, order invariance, farthest point sampling vs brute force."""

import numpy as np
import pytest
import torch

from pasta.policy.network import PolicyConfig, PolicyNet
from pasta.policy.pointnet2 import PointNet2, PointNet2Config, SAConfig, ball_query, farthest_point_sample


def _tiny_encoder() -> PointNet2Config:
    return PointNet2Config(levels=[SAConfig(32, 0.2, 8, (16, 16)), SAConfig(8, 0.4, 8, (32,))], global_widths=(32, 48))


def _brute_force_fps(x: np.ndarray, m: int) -> list[int]:
    """Textbook FPS: start farthest from the centroid, then repeatedly the point farthest from the chosen set."""
    c = x.mean(0)
    chosen = [int(np.argmax([np.sum((p - c) ** 2) for p in x]))]
    while len(chosen) < m:
        best, best_d = -1, -1.0
        for i, p in enumerate(x):
            d = min(float(np.sum((p - x[j]) ** 2)) for j in chosen)
            if d > best_d:
                best, best_d = i, d
        chosen.append(best)
    return chosen


def test_fps_matches_brute_force():
    rng = np.random.default_rng(0)
    x = rng.random((3, 60, 3)).astype(np.float64)
    got = farthest_point_sample(torch.from_numpy(x), 12)
    assert got.shape == (3, 12) and got.dtype == torch.long
    for b in range(3):
        assert got[b].tolist() == _brute_force_fps(x[b], 12)


def test_fps_respects_start_and_covers_all_points():
    x = torch.rand(2, 10, 3)
    idx = farthest_point_sample(x, 10, start=torch.tensor([3, 7]))
    assert idx[:, 0].tolist() == [3, 7]
    assert all(sorted(row.tolist()) == list(range(10)) for row in idx)


def test_ball_query_nearest_within_radius():
    x = torch.tensor([[[0.0, 0, 0], [0.1, 0, 0], [0.25, 0, 0], [1.0, 0, 0]]])
    idx = ball_query(x, x[:, :1], radius=0.3, k=4)
    assert idx.shape == (1, 1, 4)
    assert idx[0, 0].tolist() == [0, 1, 2, 0]  # the far point is replaced by the nearest one


def test_pointnet2_shapes_and_order_invariance():
    torch.manual_seed(0)
    net = PointNet2(_tiny_encoder()).eval()
    xyz, feats = torch.rand(2, 100, 3), torch.rand(2, 100, 3)
    out = net(xyz, feats)
    assert out.shape == (2, 48)
    perm = torch.randperm(100)
    torch.testing.assert_close(net(xyz[:, perm], feats[:, perm]), out, rtol=1e-5, atol=1e-6)


def test_policy_net_shapes_range_and_order_invariance():
    torch.manual_seed(0)
    # the one-frame network (no step / pose inputs): the clouds alone
    cfg = PolicyConfig(action_dim=4, encoder=_tiny_encoder(), head_widths=(32,), step_feature=False, pose_feature=False)
    net = PolicyNet(cfg).eval()
    dough, tool, goal = torch.rand(3, 50, 3) * 0.3, torch.rand(3, 20, 3) * 0.3, torch.rand(3, 40, 3) * 0.3
    with torch.no_grad():
        net.action_head[-1].weight.normal_(0, 3.0)  # push the pre-activation outside [-1, 1]
        action, done = net(dough, tool, goal)
        assert action.shape == (3, 4) and done.shape == (3,)
        assert action.abs().max() <= 1.0
        p = [torch.randperm(n) for n in (50, 20, 40)]
        a2, d2 = net(dough[:, p[0]], tool[:, p[1]], goal[:, p[2]])
    torch.testing.assert_close(a2, action, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(d2, done, rtol=1e-5, atol=1e-6)


def test_policy_config_round_trip():
    cfg = PolicyConfig(action_dim=3, encoder=_tiny_encoder(), head_widths=(32, 16), center_xz=False)
    assert PolicyConfig.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize("m", [1, 5])
def test_fps_small_m(m):
    assert farthest_point_sample(torch.rand(1, 7, 3), m).shape == (1, m)
