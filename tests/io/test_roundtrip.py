"""Acceptance 1 and 4, determinism, and error reporting of pasta.io run files."""

import numpy as np
import pytest

from pasta.io import LogEntry, McapFormatError, RunLogger, RunReader, ToolPrimitive


def _bitwise_equal(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_round_trip_every_topic_and_value(sample_run):
    w = sample_run["written"]
    with RunReader(sample_run["path"]) as r:
        assert set(r.topics()) == set(w) | {"/tf"}  # every run log starts with the upright transform
        assert r.count("/tf") == 1
        for topic, items in w.items():
            assert r.count(topic) == len(items), topic
        # clouds: bitwise
        got = list(r.messages("/dough"))
        assert [t for t, _ in got] == [t for t, _ in w["/dough"]]
        assert all(_bitwise_equal(g, e) for (_, g), (_, e) in zip(got, w["/dough"]))
        (t, goal), = r.messages("/goal")
        assert t == 0 and _bitwise_equal(goal, w["/goal"][0][1])
        cols = list(r.point_clouds("/colored"))
        assert len(cols) == len(w["/colored"])
        for (t, p, c), (te, pe, ce) in zip(cols, w["/colored"]):
            assert t == te and _bitwise_equal(p, pe) and _bitwise_equal(c, ce)
        (t, ents), = r.messages("/entities")
        assert len(ents) == 2 and all(_bitwise_equal(g, e) for g, e in zip(ents, w["/entities"][0][1]))
        # entity clouds carry one palette colour per entity
        (_, _, ecol), = r.point_clouds("/entities")
        assert len({tuple(c) for c in ecol[:40]}) == 1 and tuple(ecol[0]) != tuple(ecol[40])
        # tools: exact
        assert list(r.messages("/tools")) == w["/tools"]
        # JSON: equal
        for topic in ("/plan", "/actions", "/metrics", "/step", "/planner/progress", "/custom"):
            assert list(r.messages(topic)) == w[topic], topic
        # logs
        logs = list(r.messages("/log"))
        assert [(t, (e.level, e.text)) for t, e in logs] == w["/log"]
        assert all(isinstance(e, LogEntry) for _, e in logs)
        # attachments, config, metadata
        assert sorted(r.attachment_names()) == sorted(sample_run["attachments"])
        for name, data in sample_run["attachments"].items():
            assert r.attachment(name) == data
        assert r.config() == sample_run["config"]
        assert r.metadata() == sample_run["metadata"]
        assert r.validate() == sum(len(v) for v in w.values()) + 1  # and /tf


def test_channel_encodings_follow_foxglove_rules(sample_run):
    import json

    from mcap.reader import make_reader

    with open(sample_run["path"], "rb") as f:
        summary = make_reader(f).get_summary()
        for ch in summary.channels.values():
            schema = summary.schemas[ch.schema_id]
            if ch.message_encoding == "json":
                assert schema.encoding == "jsonschema"
                assert json.loads(schema.data)["type"] == "object"
            else:
                assert (ch.message_encoding, schema.encoding) == ("protobuf", "protobuf")
        att = {a.name: a for a in make_reader(f).iter_attachments()}
        assert att["config.yaml"].media_type == "application/yaml"


def test_foxglove_schema_names(sample_run):
    names = RunReader(sample_run["path"]).schema_names()
    for well_known in ("foxglove.PointCloud", "foxglove.SceneUpdate", "foxglove.Log"):
        assert well_known in names
    assert {"pasta.Plan", "pasta.Action", "pasta.Metrics"} <= set(names)


def test_same_inputs_give_byte_identical_files(tmp_path, run_factory):
    run_factory(tmp_path / "a.mcap", seed=5)
    run_factory(tmp_path / "b.mcap", seed=5)
    run_factory(tmp_path / "c.mcap", seed=6)
    a, b, c = ((tmp_path / n).read_bytes() for n in ("a.mcap", "b.mcap", "c.mcap"))
    assert a == b
    assert a != c


def test_point_cloud_layout_is_foxglove_pointcloud(sample_run):
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
    from mcap.reader import make_reader

    with open(sample_run["path"], "rb") as f:
        for _s, ch, m in make_reader(f).iter_messages(topics=["/dough"]):
            msg = PointCloud.FromString(m.data)
            assert msg.frame_id == "world" and msg.point_stride == 12
            assert [(fl.name, fl.offset, fl.type) for fl in msg.fields] == [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
            assert msg.timestamp.seconds * 10**9 + msg.timestamp.nanos == m.log_time
            break


def test_not_mcap_file_gives_clear_error(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("hello, this is not a run file at all\n")
    with pytest.raises(McapFormatError, match=r"notes\.txt is not an MCAP file"):
        RunReader(p)
    with pytest.raises(McapFormatError, match="not an MCAP file"):
        RunReader(p, recover=True)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(McapFormatError, match="empty"):
        RunReader(empty)
    with pytest.raises(McapFormatError, match="cannot open"):
        RunReader(tmp_path / "missing.mcap")


def test_corrupt_chunk_is_detected_by_crc(tmp_path):
    path = tmp_path / "r.mcap"
    rng = np.random.default_rng(0)
    with RunLogger(path) as log:
        for i in range(4):
            log.point_cloud("/dough", i, rng.random((2000, 3)))
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside the first chunk's compressed payload
    path.write_bytes(bytes(data))
    r = RunReader(path)  # summary is intact
    with pytest.raises(McapFormatError, match="r.mcap"):
        list(r.messages("/dough"))


def test_corrupt_attachment_is_detected(tmp_path):
    path = tmp_path / "r.mcap"
    payload = b"A" * 1000
    with RunLogger(path) as log:
        log.attach("initial_state.npz", payload)
    data = bytearray(path.read_bytes())
    i = data.index(payload)
    data[i + 10] = ord("B")
    path.write_bytes(bytes(data))
    with pytest.raises(McapFormatError, match="CRC"):
        RunReader(path).attachment("initial_state.npz")


def test_missing_attachment_lists_names(sample_run):
    with pytest.raises(KeyError, match="config.yaml"):
        RunReader(sample_run["path"]).attachment("nope.bin")


def test_file_is_finished_when_block_raises(tmp_path):
    path = tmp_path / "r.mcap"
    with pytest.raises(RuntimeError):
        with RunLogger(path) as log:
            log.point_cloud("/dough", 0, np.zeros((3, 3)))
            raise RuntimeError("boom")
    (t, x), = RunReader(path).messages("/dough")
    assert t == 0 and x.shape == (3, 3)


def test_logger_rejects_bad_input(tmp_path):
    with RunLogger(tmp_path / "r.mcap") as log:
        with pytest.raises(ValueError, match=r"\(N, 3\)"):
            log.point_cloud("/dough", 0, np.zeros((4, 2)))
        with pytest.raises(TypeError, match="uint8"):
            log.point_cloud("/dough", 0, np.zeros((4, 3)), np.zeros((4, 4)))
        with pytest.raises(TypeError, match="integer"):
            log.point_cloud("/dough", 0.5, np.zeros((4, 3)))
        with pytest.raises(ValueError, match="t_ns"):
            log.point_cloud("/dough", -1, np.zeros((4, 3)))
        with pytest.raises(TypeError, match="object"):
            log.json("/x", 0, [1, 2])
        with pytest.raises(ValueError, match="kind"):
            ToolPrimitive("knife", "cone", (1, 1, 1), (0, 0, 0))
        log.point_cloud("/dough", 0, np.zeros((4, 3)))
        with pytest.raises(ValueError, match="already carries"):
            log.json("/dough", 0, {"a": 1})
        log.attach("a.bin", b"1")
        with pytest.raises(ValueError, match="already"):
            log.attach("a.bin", b"2")
    with pytest.raises(ValueError, match="closed"):
        log.point_cloud("/dough", 1, np.zeros((4, 3)))


def test_json_values_are_normalised(tmp_path):
    path = tmp_path / "r.mcap"
    with RunLogger(path) as log:
        log.json("/m", 0, {"a": np.float32(0.5), "b": np.arange(3), "c": (1, 2), "d": float("nan"), "e": np.bool_(True)})
    (_, v), = RunReader(path).messages("/m")
    assert v == {"a": 0.5, "b": [0, 1, 2], "c": [1, 2], "d": None, "e": True}


def test_metadata_is_flattened_to_strings(tmp_path):
    path = tmp_path / "r.mcap"
    with RunLogger(path, metadata={"seed": 3, "plugins": {"cut": "0.1", "roll": "0.2"}}) as log:
        log.add_metadata("extra", {"k": "v"})
    r = RunReader(path)
    assert r.metadata() == {"seed": "3", "plugins.cut": "0.1", "plugins.roll": "0.2"}
    assert r.metadata("extra") == {"k": "v"}
    assert r.metadata("absent") == {}
    assert sorted(r.metadata_names()) == ["extra", "run", "status"]


def test_time_order_and_empty_entities(tmp_path):
    path = tmp_path / "r.mcap"
    with RunLogger(path) as log:
        log.json("/a", 5, {"i": 0})
        log.json("/a", 1, {"i": 1})
        log.entities("/e", 0, [])
        with pytest.raises(ValueError, match="no points"):
            log.entities("/e", 0, [np.zeros((0, 3))])
    r = RunReader(path)
    assert [v["i"] for _, v in r.messages("/a")] == [0, 1]
    assert [v["i"] for _, v in r.messages("/a", time_order=True)] == [1, 0]
    assert list(r.messages("/e")) == [(0, [])]


def test_tools_missing_later_are_deleted_in_the_scene(tmp_path):
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from mcap.reader import make_reader

    knife = ToolPrimitive("knife", "cube", (0.01, 0.1, 0.1), (0.5, 0.2, 0.5))
    roller = ToolPrimitive("roller", "cylinder", (0.04, 0.04, 0.2), (0.3, 0.1, 0.3))
    path = tmp_path / "r.mcap"
    with RunLogger(path) as log:
        log.tools("/tools", 0, [knife, roller])
        log.tools("/tools", 1, [roller])
    assert [v for _, v in RunReader(path).messages("/tools")] == [[knife, roller], [roller]]
    with open(path, "rb") as f:
        msgs = [SceneUpdate.FromString(m.data) for _, c, m in make_reader(f).iter_messages() if c.topic == "/tools"]
    assert [d.id for d in msgs[1].deletions] == ["knife"] and not msgs[0].deletions
