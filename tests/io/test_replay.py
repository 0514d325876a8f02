"""pasta replay: timeline, topics=, export=, exit codes, demo export."""

import argparse

import numpy as np

from pasta.io import RunReader, ToolPrimitive, export_demo_to_mcap
from pasta.io import replay


def _parse(argv):
    parser = argparse.ArgumentParser(prog="pasta replay")
    replay.add_arguments(parser)
    return parser.parse_args(argv)


def test_timeline(sample_run, capsys):
    assert replay.run(_parse([str(sample_run["path"])])) == 0
    out = capsys.readouterr().out
    for needle in ("/dough", "foxglove.PointCloud", "cut -> push -> roll", "score=0.75",
                   "step 0 cut", "final metrics", "normalized_improvement=0.81", "knife stopped early",
                   "seed=3", "config.yaml"):
        assert needle in out, needle


def test_timeline_topic_filter(sample_run, capsys):
    assert replay.run(_parse([str(sample_run["path"]), "topics=/metrics,/log"])) == 0
    out = capsys.readouterr().out
    assert "final metrics" in out and "knife stopped early" in out
    assert "cut -> push" not in out and "/dough" not in out


def test_export_pngs_and_gif(sample_run, tmp_path, capsys):
    out_dir = tmp_path / "frames"
    assert replay.run(_parse([str(sample_run["path"]), f"export={out_dir}", "every=3"])) == 0
    pngs = sorted(out_dir.glob("dough_*.png"))
    assert len(pngs) == 4  # 12 clouds, every 3rd
    gif = out_dir / "dough.gif"
    assert gif.exists()
    from PIL import Image

    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == 4
    with Image.open(pngs[0]) as im:
        assert im.format == "PNG" and im.size[0] > 100
    # explicit topics: coloured clouds too
    out2 = tmp_path / "f2"
    assert replay.run(_parse([str(sample_run["path"]), f"export={out2}", "topics=/colored,/entities", "max_frames=2"])) == 0
    assert len(list(out2.glob("colored_*.png"))) == 2 and (out2 / "entities.gif").exists()


def test_export_draws_tools_as_shapes_in_their_colours(tmp_path):
    """A green knife over the right end of the dough is drawn there in both views; a blue tool parked high
    above is not drawn at all."""
    from matplotlib.image import imread

    from pasta.io import RunLogger

    rng = np.random.default_rng(0)
    dough = (rng.random((400, 3)) * [0.4, 0.05, 0.1] + [0.3, 0.02, 0.45]).astype(np.float32)
    green, blue = (0.0, 0.8, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0)
    path = tmp_path / "tools.mcap"
    with RunLogger(path) as log:
        log.point_cloud("/dough", 0, dough)
        log.tools("/tools", 0, [ToolPrimitive("knife", "cube", (0.03, 0.1, 0.12), (0.65, 0.08, 0.5), color=green),
                                ToolPrimitive("spatula", "cube", (0.14, 0.03, 0.14), (0.4, 0.85, 0.5), color=blue)])
    with RunReader(path) as reader:
        [png, _gif] = replay.export_frames(reader, tmp_path / "frames")
    img = imread(png)[..., :3]
    height = img.shape[0]
    body = img[: int(0.88 * height)]  # the views; the legend at the bottom left out

    def near(rgb):
        return np.abs(body - np.array(rgb)).max(-1) < 0.1

    rows, cols = np.nonzero(near(green[:3]))
    assert len(cols) > 20
    assert np.all(cols > 0.6 * img.shape[1])  # the knife is at the right end of the dough, in both views
    assert rows.min() < 0.45 * height < rows.max()  # top view (upper half) and side view (lower half)
    assert not near(blue[:3]).any()  # parked high above the dough: not drawn
    assert (np.abs(img - np.array(green[:3])).max(-1) < 0.1)[int(0.88 * height):].any()  # the legend names the knife
    assert not (np.abs(img - np.array(blue[:3])).max(-1) < 0.1).any()  # and not the parked spatula


def test_not_mcap_exit_code(tmp_path, capsys):
    p = tmp_path / "x.mcap"
    p.write_text("nope")
    assert replay.run(_parse([str(p)])) == replay.EXIT_BAD_FILE
    assert "not an MCAP file" in capsys.readouterr().err


def test_verify_without_initial_state_fails_cleanly(tmp_path, capsys):
    from pasta.io import RunLogger

    p = tmp_path / "r.mcap"
    with RunLogger(p) as log:
        log.point_cloud("/dough", 0, np.zeros((2, 3)))
    assert replay.run(_parse([str(p), "--verify"])) == replay.EXIT_VERIFY_FAILED
    assert "initial_state.npz" in capsys.readouterr().out


def test_export_demo_to_mcap(tmp_path):
    rng = np.random.default_rng(0)
    T, P = 6, 64
    pts = rng.random((T, P, 3)).astype(np.float32)
    poses = {"knife": np.concatenate([rng.random((T, 3)), np.zeros((T, 1))], axis=1)}
    shapes = {"knife": ("cube", (0.005, 0.1, 0.08))}
    acts = rng.normal(size=(T - 1, 3))
    path = tmp_path / "demo.mcap"
    export_demo_to_mcap(pts, poses, acts, path, dt=0.01, tool_shapes=shapes, tool_name="knife",
                        goal=pts[-1], metadata={"skill": "cut"})
    r = RunReader(path)
    clouds = list(r.messages("/dough"))
    assert len(clouds) == T and all(c.tobytes() == pts[i].tobytes() for i, (_, c) in enumerate(clouds))
    assert [t for t, _ in clouds] == [i * 10_000_000 for i in range(T)]
    tools = list(r.messages("/tools"))
    assert tools[2][1][0].position == tuple(poses["knife"][2, :3])
    actions = [a for _, a in r.messages("/actions")]
    assert [a["action"] for a in actions] == acts.tolist()
    assert r.metadata() == {"skill": "cut"}
    # per-step ToolPrimitive lists work too
    seq = [[ToolPrimitive("roller", "cylinder", (0.04, 0.04, 0.2), (0.3, 0.1, i / 10))] for i in range(T)]
    export_demo_to_mcap(pts, seq, None, tmp_path / "d2.mcap")
    assert list(RunReader(tmp_path / "d2.mcap").messages("/tools"))[3][1] == seq[3]
