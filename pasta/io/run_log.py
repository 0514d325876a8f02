"""Write one run to one MCAP file: :class:`RunLogger`.

Every message is stamped with simulation time the caller passes (integer ns, e.g.
``step_time_ns(env_step, dt)``); nothing in the file depends on the wall clock, so the same run
gives byte-identical files. Chunks are zstd-compressed with chunk, data-section and summary CRCs.

Crash safety: the file is written as ``FILE.partial`` next to ``FILE`` and renamed to ``FILE`` when it is
closed, so an existing ``FILE`` is only replaced by a finished run; one process writes a ``FILE`` at a
time (:class:`pasta.core.files.OutputLock`: a second one gets :class:`~pasta.core.files.OutputBusyError`
before it writes anything), and a symbolic link at ``FILE`` or ``FILE.partial`` is replaced, not followed. Closing records the run's status in
the metadata record ``status`` (``complete``, or ``failed`` with the error, also logged as an error line
on ``/log``); a killed run leaves ``FILE.partial``, readable with ``RunReader(path, recover=True)`` /
``pasta replay FILE.partial --recover``.

Shapes: ``points`` (N, 3) numeric, stored as float32; ``colors`` (N, 4) uint8 RGBA; entity lists are
lists of (P_i, 3) arrays. See :mod:`pasta.io.schemas` for the byte layouts.
"""

from __future__ import annotations

import errno
import json
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from pasta.core.files import OutputLock
from pasta.io import schemas as S
from pasta.io.schemas import ToolPrimitive, _check_time

LIBRARY = f"pasta.io {LIBRARY_IDENTIFIER}"

# Well-known topics (callers may use others).
DOUGH = "/dough"  # foxglove.PointCloud: observed dough
GOAL = "/goal"  # foxglove.PointCloud: goal cloud
ENTITIES = "/entities"  # foxglove.PointCloud: decomposition, one colour + `entity` id per entity
SUBGOALS = "/plan/subgoals"  # foxglove.PointCloud: decoded sub-goal entities of a plan step
TOOLS = "/tools"  # foxglove.SceneUpdate: tool primitives
PLAN = "/plan"  # json pasta.Plan
ACTIONS = "/actions"  # json pasta.Action, one per env step / teleport
STEP = "/step"  # json pasta.StepResult
METRICS = "/metrics"  # json pasta.Metrics
PROGRESS = "/planner/progress"  # json pasta.PlannerProgress
LOG = "/log"  # foxglove.Log
TF = "/tf"  # foxglove.FrameTransform: the world (y up) under a z-up root, written once at the start

# Well-known attachments.
CONFIG_ATTACHMENT = "config.yaml"
INITIAL_STATE = "initial_state.npz"
FINAL_STATE = "final_state.npz"
SIM_CONFIG = "sim_config.json"
RUN_METADATA = "run"
RUN_STATUS = "status"  # metadata record written on close: {"status": "complete" | "failed", "error": ...}
PARTIAL_SUFFIX = ".partial"
#: what a message's log time is: the simulation time the caller passes, or the wall clock (:class:`RunLogger`)
CLOCKS = ("sim", "wall")


def partial_path(path: str | os.PathLike[str]) -> Path:
    """Where :class:`RunLogger` writes ``path`` until it is closed: ``path`` + ``.partial``."""
    path = Path(path)
    return path.with_name(path.name + PARTIAL_SUFFIX)


def _create(path: Path) -> Any:
    """A new, empty file at ``path``, opened for binary writing. What is there is ours to replace (the caller
    holds the log's lock): a stale ``.partial`` of a killed run, or a link, which is removed, never followed."""
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    return os.fdopen(fd, "wb")


def _error_text(error: BaseException | str) -> str:
    if isinstance(error, BaseException):
        text = str(error)
        return f"{type(error).__name__}: {text}" if text else type(error).__name__
    return str(error)


def flatten_metadata(data: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """``{"seed": 3, "packages": {"numpy": "2.4"}}`` -> ``{"seed": "3", "packages.numpy": "2.4"}``."""
    out: dict[str, str] = {}
    for key, value in data.items():
        if not isinstance(key, str):
            raise TypeError(f"metadata keys must be strings, got {key!r}")
        full = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten_metadata(value, full + "."))
        elif isinstance(value, str):
            out[full] = value
        elif value is None or isinstance(value, (bool, int, float)):
            out[full] = json.dumps(value)
        else:
            out[full] = str(value)
    return out


class RunLogger:
    """Writer of one run file. Use as a context manager; the file is finished on exit, also when
    the block raises (then its status is ``failed`` and the exception is recorded).

    >>> with RunLogger("runs/r1.mcap", config_yaml=cfg_yaml, metadata={"seed": 3}) as log:
    ...     log.point_cloud("/dough", step_time_ns(0, dt), points)

    ``path``: the file (parents are created). It is written as ``path.partial`` (:attr:`partial_path`)
    and renamed to ``path`` by :meth:`close`; an existing ``path`` is replaced only then.
    ``config_yaml``: resolved config text, stored as attachment ``config.yaml``.
    ``metadata``: run facts (seed, package and plugin versions ...), nested mappings are flattened
    with dotted keys and values turned into strings; stored as the metadata record ``"run"``.
    ``chunk_size``: bytes of uncompressed messages per chunk; a crash loses at most the open chunk
    (call :meth:`flush` to close it early).
    ``clock``: ``sim`` (default) stamps every message with the time the caller passes (simulation time: the
    same run gives the same bytes); ``wall`` stamps it with the wall-clock time since the logger was created,
    so planning and slow steps take their real length on a viewer's timeline (the file is then not
    byte-reproducible).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        config_yaml: str | None = None,
        metadata: Mapping[str, Any] | None = None,
        *,
        chunk_size: int = 1024 * 1024,
        clock: str = "sim",
    ) -> None:
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {', '.join(CLOCKS)}, got {clock!r}")
        self.clock = clock
        self._t0 = time.monotonic_ns()
        self.path = Path(path)
        if self.path.is_dir():  # found now, not at the rename after the whole run
            raise IsADirectoryError(errno.EISDIR, "run log target is a directory", str(self.path))
        self.partial_path = partial_path(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = OutputLock(self.path, "log").acquire()  # one writer per log (OutputBusyError otherwise)
        try:
            self._stream = _create(self.partial_path)
        except BaseException:
            self._lock.release()
            raise
        self._last_t = 0  # latest message time: where a failure is logged
        try:
            self._writer = Writer(
                self._stream,
                chunk_size=chunk_size,
                compression=CompressionType.ZSTD,
                enable_crcs=True,
                enable_data_crcs=True,
            )
            self._writer.start(profile="", library=LIBRARY)
        except BaseException:
            self._stream.close()
            self._lock.release()
            raise
        self._schemas: dict[tuple[str, str], int] = {}  # (name, encoding) -> schema id
        self._channels: dict[str, tuple[int, str]] = {}  # topic -> (channel id, schema name)
        self._sequence: dict[int, int] = {}
        self._attachments: set[str] = set()
        self._metadata_names: set[str] = set()
        self._tool_names: dict[str, list[str]] = {}
        self._closed = False
        if metadata is not None:
            self.add_metadata(RUN_METADATA, metadata)
        if config_yaml is not None:
            self.attach(CONFIG_ATTACHMENT, config_yaml.encode("utf-8"), "application/yaml")
        self._write_proto(TF, 0, S.encode_world_upright(0))  # viewers show the y-up world upright
        self._stream.flush()  # header, metadata and config reach the disk before the run starts

    # ---------------------------------------------------------------- lifecycle

    def __enter__(self) -> RunLogger:
        return self

    def __exit__(self, exc_type: Any, exc: BaseException | None, tb: Any) -> None:
        self.close(error=exc)

    def flush(self) -> None:
        """Close the current chunk and flush it to the OS, bounding what a crash can lose."""
        self._check_open()
        self._writer.flush()

    def close(self, error: BaseException | str | None = None) -> None:
        """Record the run's status, write the summary and footer, and rename the file to :attr:`path`
        (idempotent). ``error``: the exception (or text) that ended the run; the status is then ``failed``,
        the error is stored in the ``status`` record and logged as an error line on ``/log``."""
        if self._closed:
            return
        self._closed = True
        try:
            status = {"status": "complete"}
            if error is not None:
                text = _error_text(error)
                status = {"status": "failed", "error": text}
                try:
                    line = S.encode_log(self._last_t, "error", f"run failed: {text}", "pasta")
                    self._write_proto(LOG, self._last_t, line)
                except ValueError:  # /log carries another type in this run: the status record still says it
                    pass
            self._writer.add_metadata(RUN_STATUS, status)
            self._writer.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())  # the data is on disk before the name says it is complete
        finally:
            self._stream.close()
        try:
            os.replace(self.partial_path, self.path)  # a link at ``path`` is replaced, never written through
        finally:
            self._lock.release()

    def fail(self, error: BaseException | str) -> None:
        """Close the file recording that the run failed with ``error`` (see :meth:`close`)."""
        self.close(error=error)

    @property
    def closed(self) -> bool:
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"RunLogger for {self.path} is closed")

    # ---------------------------------------------------------------- channels

    def _schema_id(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding)
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(name=name, encoding=encoding, data=data)
        return self._schemas[key]

    def _channel(self, topic: str, schema_name: str, make: Any) -> int:
        """Channel id of ``topic``; ``make()`` -> (schema_encoding, schema_data, message_encoding)."""
        if not isinstance(topic, str) or not topic:
            raise ValueError(f"topic must be a non-empty string, got {topic!r}")
        if topic in self._channels:
            cid, existing = self._channels[topic]
            if existing != schema_name:
                raise ValueError(
                    f"topic {topic!r} already carries {existing} messages, cannot log {schema_name}"
                )
            return cid
        schema_encoding, schema_data, message_encoding = make()
        sid = self._schema_id(schema_name, schema_encoding, schema_data)
        cid = self._writer.register_channel(topic=topic, message_encoding=message_encoding, schema_id=sid)
        self._channels[topic] = (cid, schema_name)
        return cid

    def _time(self, t_ns: Any) -> int:
        """The log time of a message the caller stamps ``t_ns`` (checked): itself, or the wall clock."""
        t = _check_time(t_ns)
        return time.monotonic_ns() - self._t0 if self.clock == "wall" else t

    def _write(self, cid: int, t_ns: int, data: bytes) -> None:
        self._last_t = max(self._last_t, t_ns)
        seq = self._sequence.get(cid, 0)
        self._sequence[cid] = seq + 1
        self._writer.add_message(channel_id=cid, log_time=t_ns, data=data, publish_time=t_ns, sequence=seq)

    def _write_proto(self, topic: str, t_ns: int, msg: Any) -> None:
        name = msg.DESCRIPTOR.full_name
        cls = type(msg)

        def make() -> tuple[str, bytes, str]:
            fds = build_file_descriptor_set(cls).SerializeToString(deterministic=True)
            return SchemaEncoding.Protobuf, fds, MessageEncoding.Protobuf

        cid = self._channel(topic, name, make)
        self._write(cid, t_ns, msg.SerializeToString(deterministic=True))

    # ---------------------------------------------------------------- messages

    def point_cloud(self, topic: str, t_ns: int, points: Any, colors: Any = None) -> None:
        """Log ``points`` (N, 3) (stored as float32) with optional ``colors`` (N, 4) uint8 RGBA as a
        ``foxglove.PointCloud`` in frame ``world``."""
        self._check_open()
        t = self._time(t_ns)
        self._write_proto(topic, t, S.encode_point_cloud(t, points, colors))

    def entities(self, topic: str, t_ns: int, entities: Sequence[Any]) -> None:
        """Log a decomposition: a list of (P_i, 3) clouds as ONE ``foxglove.PointCloud``, entity i
        coloured with palette colour i and tagged with a uint32 ``entity`` field = i (Foxglove can
        colour by that field too). Read back as the same list of float32 arrays."""
        self._check_open()
        t = self._time(t_ns)
        self._write_proto(topic, t, S.encode_entities(t, list(entities)))

    def tools(self, topic: str, t_ns: int, tools: Sequence[ToolPrimitive]) -> None:
        """Log tool poses as a ``foxglove.SceneUpdate`` (one entity per tool, id = tool name).
        Tools shown earlier on ``topic`` but absent now are deleted from the scene."""
        self._check_open()
        t = self._time(t_ns)
        tools = list(tools)
        shown = self._tool_names.setdefault(topic, [])
        now = [tool.name for tool in tools if isinstance(tool, ToolPrimitive)]
        removed = [n for n in shown if n not in now]
        self._write_proto(topic, t, S.encode_tools(t, tools, removed=removed))
        self._tool_names[topic] = now

    def message(self, t_ns: int, level: int | str, text: str, *, name: str = "pasta", topic: str = LOG) -> None:
        """Log a text line as ``foxglove.Log``; ``level`` is a name (``"info"``, ``"warning"`` ...),
        a Foxglove level code 0-5 or a stdlib ``logging`` level (10-50)."""
        self._check_open()
        t = self._time(t_ns)
        self._write_proto(topic, t, S.encode_log(t, level, text, name))

    def json(
        self,
        topic: str,
        t_ns: int,
        obj: Mapping[str, Any],
        *,
        schema: Mapping[str, Any] | None = None,
    ) -> None:
        """Log a JSON object. ``schema`` (a JSON object schema with a ``title``; the title is the
        schema name) is used when the topic is first seen; default ``{"type": "object"}`` titled
        ``pasta.json<topic>``. Numpy values are converted to lists/numbers, non-finite floats to null."""
        self._check_open()
        t = self._time(t_ns)
        data = S.encode_json(obj)
        if schema is None:
            schema = S.generic_schema("pasta.json" + topic.replace("/", "."))
        name = str(schema.get("title") or "pasta.json" + topic.replace("/", "."))
        cid = self._channel(topic, name, lambda: (SchemaEncoding.JSONSchema, S.schema_bytes(schema), MessageEncoding.JSON))
        self._write(cid, t, data)

    def plan(self, t_ns: int, plan: Mapping[str, Any], *, topic: str = PLAN) -> None:
        """Log a plan (``{"skills": [...], "steps": [...], "score": ...}``; extra keys allowed)."""
        self.json(topic, t_ns, plan, schema=S.PLAN_SCHEMA)

    def metrics(self, t_ns: int, metrics: Mapping[str, Any], *, topic: str = METRICS) -> None:
        """Log named scalar metrics (the last message of ``/metrics`` is the run's final result)."""
        self.json(topic, t_ns, metrics, schema=S.METRICS_SCHEMA)

    def step_result(self, t_ns: int, result: Mapping[str, Any], *, topic: str = STEP) -> None:
        """Log the result of one plan step (``{"step": h, "skill": ..., "score": ...}``)."""
        self.json(topic, t_ns, result, schema=S.STEP_SCHEMA)

    def planner_progress(self, t_ns: int, progress: Mapping[str, Any], *, topic: str = PROGRESS) -> None:
        """Log planner optimisation progress (``{"iteration": i, "best_score": ...}``)."""
        self.json(topic, t_ns, progress, schema=S.PROGRESS_SCHEMA)

    def action(self, t_ns: int, step: int, tool: str, action: Any, *, topic: str = ACTIONS) -> None:
        """Log the action applied to ``tool`` at env step ``step`` (``action``: 1-D numbers, exactly
        what was passed to the simulator, so ``pasta replay --verify`` can re-apply it)."""
        self.json(topic, t_ns, {"step": int(step), "tool": tool, "action": action}, schema=S.ACTION_SCHEMA)

    def set_tool_pose(
        self, t_ns: int, step: int, name: str, position: Any, yaw: float = 0.0, *, topic: str = ACTIONS
    ) -> None:
        """Log a tool teleport (``Simulator.set_tool_pose(name, position, yaw=yaw)``)."""
        pose = {"name": name, "position": position, "yaw": float(yaw)}
        self.json(topic, t_ns, {"step": int(step), "set_tool_pose": pose}, schema=S.ACTION_SCHEMA)

    def park_tool(self, t_ns: int, step: int, name: str, *, topic: str = ACTIONS) -> None:
        """Log that ``name`` was parked (``Simulator.park_tool(name)``)."""
        self.json(topic, t_ns, {"step": int(step), "park_tool": name}, schema=S.ACTION_SCHEMA)

    # ---------------------------------------------------------------- attachments / metadata

    def attach(self, name: str, data: bytes, media_type: str = "application/octet-stream", *, t_ns: int = 0) -> None:
        """Store ``data`` as an attachment (e.g. ``initial_state.npz``); names are unique."""
        self._check_open()
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError(f"attachment data must be bytes, got {type(data).__name__}")
        if name in self._attachments:
            raise ValueError(f"attachment {name!r} already written to {self.path}")
        self._attachments.add(name)
        t = self._time(t_ns)
        self._writer.add_attachment(create_time=t, log_time=t, name=name, media_type=media_type, data=bytes(data))

    def attach_json(self, name: str, obj: Mapping[str, Any], *, t_ns: int = 0) -> None:
        """Store a JSON object as an attachment (media type application/json), e.g. ``sim_config.json``."""
        data = json.dumps(S.to_jsonable(obj), sort_keys=True, indent=1).encode("utf-8")
        self.attach(name, data, "application/json", t_ns=t_ns)

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> None:
        """Write an MCAP metadata record ``name`` (flattened to ``dict[str, str]``)."""
        self._check_open()
        if name == RUN_STATUS:
            raise ValueError(f"metadata record {RUN_STATUS!r} is written by close(); use another name")
        if name in self._metadata_names:
            raise ValueError(f"metadata record {name!r} already written to {self.path}")
        self._metadata_names.add(name)
        self._writer.add_metadata(name, flatten_metadata(data))
