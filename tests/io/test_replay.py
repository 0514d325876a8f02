"""pasta replay: timeline, --topics, --export, exit codes, demo export."""

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
    assert replay.run(_parse([str(sample_run["path"]), "--topics", "/metrics,/log"])) == 0
    out = capsys.readouterr().out
    assert "final metrics" in out and "knife stopped early" in out
    assert "cut -> push" not in out and "/dough" not in out


def test_export_pngs_and_gif(sample_run, tmp_path, capsys):
    out_dir = tmp_path / "frames"
    assert replay.run(_parse([str(sample_run["path"]), "--export", str(out_dir), "--every", "3"])) == 0
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
    assert replay.run(_parse([str(sample_run["path"]), "--export", str(out2), "--topics", "/colored", "/entities", "--max-frames", "2"])) == 0
    assert len(list(out2.glob("colored_*.png"))) == 2 and (out2 / "entities.gif").exists()


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
