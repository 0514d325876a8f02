"""Every message of a real ``pasta run`` log matches the schema its channel declares (issue 40): each JSON
message validates against the channel's JSON schema, and every point cloud carries a full pose (position and
orientation), which stricter readers (Rerun's MCAP import) require."""

from __future__ import annotations

import json

import pytest

from pasta.cli import main
from pasta_runs import RUN



@pytest.fixture(scope="module")
def run_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("run") / "run.mcap"
    assert main([*RUN, f"log={path}"]) == 0
    return path


def _messages(path):
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        yield from make_reader(fh).iter_messages()


@pytest.mark.sim
def test_every_json_message_validates_against_its_channels_schema(run_log):
    import jsonschema

    seen: dict[str, int] = {}
    for schema, channel, message in _messages(run_log):
        if schema is None or schema.encoding != "jsonschema":
            continue
        doc = json.loads(schema.data)
        jsonschema.Draft202012Validator.check_schema(doc)
        jsonschema.validate(json.loads(message.data), doc)  # raises, naming the field, on a mismatch
        seen[channel.topic] = seen.get(channel.topic, 0) + 1
    assert {"/plan", "/actions", "/step", "/metrics", "/planner/progress"} <= set(seen), seen


@pytest.mark.sim
def test_every_point_cloud_has_a_full_pose(run_log):
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

    clouds = 0
    for schema, channel, message in _messages(run_log):
        if schema is not None and schema.name == "foxglove.PointCloud":
            msg = PointCloud.FromString(message.data)
            assert msg.HasField("pose") and msg.pose.HasField("position") and msg.pose.HasField("orientation"), channel.topic
            clouds += 1
    assert clouds > 10


@pytest.mark.sim
def test_planning_progress_is_logged_and_wall_clock_log_time_spreads_it(run_log, tmp_path, capsys):
    """The planner's progress is a channel; with log_time=wall the timeline shows planning's real length, and
    the run still re-simulates exactly (replay --verify follows the actions, not their times)."""
    from pasta.io import RunReader

    sim_times = [t for t, _ in RunReader(run_log).messages("/planner/progress")]
    assert len(sim_times) >= 10 and len(set(sim_times)) == 1  # simulation time stands still while it plans
    wall = tmp_path / "wall.mcap"
    assert main([*RUN, f"log={wall}", "log_time=wall"]) == 0
    reader = RunReader(wall)
    assert reader.metadata()["log_time"] == "wall"
    progress = list(reader.messages("/planner/progress"))
    times = [t for t, _ in progress]
    assert times == sorted(times) and times[-1] - times[0] > 0  # spread over the planning time
    stages = {m["stage"] for _, m in progress}
    assert "optimise" in stages and all(m["iteration"] <= m["iterations"] for _, m in progress)
    (t_plan, _), = list(reader.messages("/plan"))
    assert t_plan >= times[-1]  # the plan is logged after its search
    assert main(["replay", str(wall), "--verify"]) == 0
    assert ": OK" in capsys.readouterr().out


def test_log_time_is_checked(capsys):
    assert main([*RUN, "log_time=walltime"]) == 2
    assert "log_time" in capsys.readouterr().err


def test_the_log_carries_the_transform_that_shows_the_world_upright(tmp_path):
    """A viewer's default is z up; the simulator's world is y up: /tf hangs `world` under a z-up root."""
    import numpy as np
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform

    from pasta.io import RunLogger

    path = tmp_path / "r.mcap"
    with RunLogger(path) as log:
        log.point_cloud("/dough", 0, np.zeros((3, 3), np.float32))
    (tf,) = [FrameTransform.FromString(m.data) for s, c, m in _messages(path) if c.topic == "/tf"]
    assert (tf.parent_frame_id, tf.child_frame_id) == ("z_up", "world")
    q = tf.rotation
    w, v = q.w, np.array([q.x, q.y, q.z])
    up = np.array([0.0, 1.0, 0.0])  # the world's up
    rotated = up + 2 * w * np.cross(v, up) + 2 * np.cross(v, np.cross(v, up))
    assert np.allclose(rotated, [0.0, 0.0, 1.0])  # is the viewer's up
