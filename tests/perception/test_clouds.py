"""Reading clouds (PLY ascii / binary little and big endian, organised .npy with holes) and the input frame."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.errors import InputError
from pasta.perception import CloudFrame, read_cloud, read_ply, read_transform
from pasta.perception.synthetic import camera_transform


def _points(n=50, seed=0):
    return np.random.default_rng(seed).uniform(0.1, 0.9, (n, 3))


def _binary_ply(path, pts, order, *, face_first=False):
    """x, y, z as float, a uchar colour and a double between them; a face element before or after."""
    dt = np.dtype([("x", order + "f4"), ("red", "u1"), ("y", order + "f4"), ("q", order + "f8"), ("z", order + "f4")])
    rows = np.zeros(len(pts), dt)
    rows["x"], rows["y"], rows["z"], rows["red"], rows["q"] = pts[:, 0], pts[:, 1], pts[:, 2], 7, -1.5
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    head = [f"ply", f"format {fmt} 1.0", "comment made by a test"]
    vert = [f"element vertex {len(pts)}", "property float x", "property uchar red", "property float y",
            "property double q", "property float z"]
    edge = ["element edge 2", "property int vertex1", "property int vertex2"]
    head += (edge + vert) if face_first else (vert + ["element face 1", "property list uchar int vertex_indices"])
    body = rows.tobytes()
    if face_first:
        body = np.array([0, 1, 1, 2], dtype=order + "i4").tobytes() + body
    else:
        body += bytes([3]) + np.array([0, 1, 2], dtype=order + "i4").tobytes()
    path.write_bytes(("\n".join(head) + "\nend_header\n").encode() + body)
    return path


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("face_first", [False, True])
def test_binary_ply_both_endians(tmp_path, order, face_first):
    pts = _points()
    got = read_ply(_binary_ply(tmp_path / "c.ply", pts, order, face_first=face_first))
    np.testing.assert_allclose(got, pts.astype(np.float32), rtol=0, atol=0)


def test_ascii_ply_and_bad_ply(tmp_path):
    pts = _points(5)
    text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty double z\nproperty double x\nproperty double y\n" \
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    text += "".join(f"{z} {x} {y}\n" for x, y, z in pts) + "3 0 1 2\n"
    (tmp_path / "a.ply").write_text(text)
    np.testing.assert_allclose(read_ply(tmp_path / "a.ply"), pts)
    trunc = _binary_ply(tmp_path / "t.ply", pts, "<")
    trunc.write_bytes(trunc.read_bytes()[:-40])  # cuts into the vertices (the face takes 13 bytes)
    with pytest.raises(InputError, match="ends before its 5 vertices"):
        read_ply(trunc)
    (tmp_path / "f.ply").write_text("ply\nformat binary_middle_endian 1.0\nelement vertex 1\nproperty float x\n"
                                    "end_header\n")
    with pytest.raises(InputError, match="binary_middle_endian"):
        read_ply(tmp_path / "f.ply")
    (tmp_path / "n.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
    with pytest.raises(InputError, match="x, y, z"):
        read_ply(tmp_path / "n.ply")


def test_organised_cloud_with_holes(tmp_path):
    grid = _points(12).reshape(3, 4, 3)
    grid[0, 1] = np.nan
    grid[2, 3] = 0.0  # a pixel without depth
    grid[1, 2, 0] = np.inf
    np.save(tmp_path / "o.npy", grid)
    c = read_cloud(tmp_path / "o.npy")
    assert c.shape == (3, 4) and c.valid.sum() == 9 and len(c.points) == 9
    assert not c.valid.reshape(3, 4)[0, 1] and not c.valid.reshape(3, 4)[2, 3]
    np.save(tmp_path / "empty.npy", np.full((2, 2, 3), np.nan))
    with pytest.raises(InputError, match="no valid point"):
        read_cloud(tmp_path / "empty.npy")
    flat = _points(10)
    flat[2, 0] = np.nan
    np.save(tmp_path / "f.npy", flat)
    with pytest.raises(InputError, match="only an organised"):
        read_cloud(tmp_path / "f.npy")


@pytest.mark.parametrize("frame", [CloudFrame(units="mm"), CloudFrame(up="z"),
                                   CloudFrame(units="mm", up="z", transform=camera_transform())])
def test_frame_round_trip(frame):
    ws = _points(30)
    given = frame.from_workspace(ws)
    assert not np.allclose(given, ws)
    np.testing.assert_allclose(frame.to_workspace(given), ws, atol=1e-12)


def test_frame_semantics():
    p = np.array([[0.1, 0.2, 0.3]])
    assert CloudFrame(up="z").to_workspace(p).tolist() == [[0.2, 0.3, 0.1]]  # z-up height 0.3 becomes y
    np.testing.assert_allclose(CloudFrame(units="mm").to_workspace(p * 1000), p)
    t = camera_transform(height=1.2)
    # the camera's origin is 1.2 above the workspace centre and its z axis points down
    np.testing.assert_allclose(CloudFrame(transform=t).to_workspace(np.array([[0, 0, 1.0]])), [[0.5, 0.2, 0.5]],
                               atol=1e-12)


def test_bad_transforms(tmp_path):
    for bad, message in [(np.eye(3), "4x4"), (np.diag([1, 1, 0, 1.0]), "singular")]:
        np.save(tmp_path / "t.npy", bad)
        with pytest.raises(InputError, match=message):
            read_transform(tmp_path / "t.npy")
    m = np.eye(4)
    m[3, 0] = 1
    np.savetxt(tmp_path / "t.txt", m)
    with pytest.raises(InputError, match="last row"):
        read_transform(tmp_path / "t.txt")
    np.savetxt(tmp_path / "ok.txt", camera_transform())
    np.testing.assert_allclose(read_transform(tmp_path / "ok.txt"), camera_transform())
