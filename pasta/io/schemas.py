"""Message encodings of a run file: Foxglove protobuf messages and pasta JSON channels.

Pure conversion functions between numpy / plain Python values and the bytes stored in MCAP
messages. No file I/O here and no ``mcap`` import: :mod:`pasta.io.run_log` and
:mod:`pasta.io.run_reader` do the file side.

Encodings:

- point clouds: ``foxglove.PointCloud`` (protobuf), frame ``"world"``, little-endian packed points:
  ``x, y, z`` float32 at offsets 0/4/8, then optionally ``red, green, blue, alpha`` uint8 at 12..15,
  then optionally ``entity`` uint32 at 16 (entity clouds only). ``point_stride`` is 12, 16 or 20.
- tools: ``foxglove.SceneUpdate``, one ``SceneEntity`` per tool (``id`` = tool name) holding one
  cube, cylinder or sphere primitive.
- log lines: ``foxglove.Log``.
- JSON channels: message encoding ``json``, schema encoding ``jsonschema``; every schema is a JSON
  object schema (``"type": "object"``) as Foxglove requires.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

WORLD_FRAME = "world"
#: the root frame of a run log: z up, as viewers (Foxglove, Lichtblick, Rerun) show by default; ``world`` (y up,
#: the simulator's frame) hangs below it, turned +90 degrees about x, so the dough appears upright unasked
Z_UP_FRAME = "z_up"

POINT_CLOUD_SCHEMA = "foxglove.PointCloud"
SCENE_UPDATE_SCHEMA = "foxglove.SceneUpdate"
LOG_SCHEMA = "foxglove.Log"

TOOL_KINDS = ("cube", "cylinder", "sphere")
DEFAULT_TOOL_COLOR = (0.55, 0.57, 0.62, 1.0)

LOG_LEVELS = {"unknown": 0, "debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}
_LEVEL_NAMES = {v: k for k, v in LOG_LEVELS.items()}

# Entity colours (RGBA uint8), cycled when there are more entities than colours.
ENTITY_PALETTE = np.array(
    [
        [31, 119, 180, 255],
        [255, 127, 14, 255],
        [44, 160, 44, 255],
        [214, 39, 40, 255],
        [148, 103, 189, 255],
        [140, 86, 75, 255],
        [227, 119, 194, 255],
        [127, 127, 127, 255],
        [188, 189, 34, 255],
        [23, 190, 207, 255],
    ],
    dtype=np.uint8,
)

_NUMERIC = {  # foxglove.PackedElementField.NumericType -> numpy little-endian dtype
    PackedElementField.UINT8: "u1",
    PackedElementField.INT8: "i1",
    PackedElementField.UINT16: "<u2",
    PackedElementField.INT16: "<i2",
    PackedElementField.UINT32: "<u4",
    PackedElementField.INT32: "<i4",
    PackedElementField.FLOAT32: "<f4",
    PackedElementField.FLOAT64: "<f8",
}


# --------------------------------------------------------------------------------------------
# time


def step_time_ns(step: int, dt: float) -> int:
    """Simulation time of env step ``step`` with step length ``dt`` seconds, in integer ns."""
    return int(round(step * dt * 1e9))


def _check_time(t_ns: Any) -> int:
    if isinstance(t_ns, (bool, float)) or not isinstance(t_ns, (int, np.integer)):
        raise TypeError(f"t_ns must be an integer number of nanoseconds, got {t_ns!r}")
    t = int(t_ns)
    if t < 0 or t >= 2**64:
        raise ValueError(f"t_ns must be in [0, 2**64), got {t}")
    return t


def _stamp(msg_timestamp: Any, t_ns: int) -> None:
    msg_timestamp.seconds = t_ns // 1_000_000_000
    msg_timestamp.nanos = t_ns % 1_000_000_000


# --------------------------------------------------------------------------------------------
# point clouds


def _as_points(points: Any, what: str = "points") -> np.ndarray:
    arr = np.asarray(points)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{what} must have shape (N, 3), got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise TypeError(f"{what} must be numeric, got dtype {arr.dtype}")
    return arr.astype("<f4", copy=False)


def _as_colors(colors: Any, n: int) -> np.ndarray:
    arr = np.asarray(colors)
    if arr.shape != (n, 4):
        raise ValueError(f"colors must have shape ({n}, 4) to match the points, got {arr.shape}")
    if arr.dtype != np.uint8:
        raise TypeError(f"colors must be uint8 RGBA, got dtype {arr.dtype}")
    return arr


def encode_point_cloud(
    t_ns: int,
    points: Any,
    colors: Any = None,
    entity_ids: np.ndarray | None = None,
    frame_id: str = WORLD_FRAME,
) -> PointCloud:
    """Pack ``points`` (N, 3) (cast to float32), optional ``colors`` (N, 4) uint8 RGBA and optional
    ``entity_ids`` (N,) into a ``foxglove.PointCloud``."""
    pts = _as_points(points)
    n = pts.shape[0]
    names = ["x", "y", "z"]
    formats = ["<f4", "<f4", "<f4"]
    if colors is not None:
        names += ["red", "green", "blue", "alpha"]
        formats += ["u1"] * 4
    if entity_ids is not None:
        names.append("entity")
        formats.append("<u4")
    packed = np.zeros(n, dtype=np.dtype({"names": names, "formats": formats}))  # packed, no gaps
    packed["x"], packed["y"], packed["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if colors is not None:
        col = _as_colors(colors, n)
        for i, c in enumerate(("red", "green", "blue", "alpha")):
            packed[c] = col[:, i]
    if entity_ids is not None:
        packed["entity"] = entity_ids
    msg = PointCloud(frame_id=frame_id, point_stride=packed.dtype.itemsize, data=packed.tobytes())
    _stamp(msg.timestamp, t_ns)
    msg.pose.position.SetInParent()  # present, at the origin: readers that require a full pose (Rerun) accept it
    msg.pose.orientation.w = 1.0
    fields = packed.dtype.fields
    assert fields is not None  # a structured dtype
    for name in names:
        offset = fields[name][1]
        ftype = PackedElementField.FLOAT32 if name in ("x", "y", "z") else PackedElementField.UINT8
        if name == "entity":
            ftype = PackedElementField.UINT32
        msg.fields.add(name=name, offset=offset, type=ftype)
    return msg


def encode_entities(t_ns: int, entities: Sequence[Any], frame_id: str = WORLD_FRAME) -> PointCloud:
    """One cloud holding every entity: entity ``i`` gets palette colour ``i`` and ``entity = i``."""
    clouds = [_as_points(e, f"entity {i}") for i, e in enumerate(entities)]
    for i, c in enumerate(clouds):
        if c.shape[0] == 0:
            raise ValueError(f"entity {i} has no points; entity clouds must be non-empty")
    sizes = [c.shape[0] for c in clouds]
    ids = np.repeat(np.arange(len(clouds), dtype=np.uint32), sizes)
    pts = np.concatenate(clouds, axis=0) if clouds else np.zeros((0, 3), np.float32)
    colors = ENTITY_PALETTE[ids % len(ENTITY_PALETTE)]
    return encode_point_cloud(t_ns, pts, colors, entity_ids=ids, frame_id=frame_id)


def _unpack_cloud(msg: PointCloud) -> np.ndarray:
    stride = msg.point_stride
    if stride <= 0:
        raise ValueError("point cloud with point_stride 0")
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.type not in _NUMERIC:
            raise ValueError(f"point cloud field {f.name!r} has unsupported numeric type {f.type}")
        names.append(f.name)
        formats.append(_NUMERIC[f.type])
        offsets.append(f.offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": stride})
    if len(msg.data) % stride:
        raise ValueError(f"point cloud data of {len(msg.data)} bytes is not a multiple of {stride}")
    return np.frombuffer(msg.data, dtype=dtype)


def decode_point_cloud(msg: PointCloud) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """``(points (N, 3) float32, colors (N, 4) uint8 or None, entity ids (N,) or None)``.

    Arrays are fresh copies (writable). Missing colour channels default to 0 (alpha to 255)."""
    packed = _unpack_cloud(msg)
    fields = packed.dtype.names or ()
    n = packed.shape[0]
    pts = np.zeros((n, 3), dtype=np.float32)
    for i, axis in enumerate("xyz"):
        if axis in fields:
            pts[:, i] = packed[axis]
    colors = None
    if any(c in fields for c in ("red", "green", "blue", "alpha")):
        colors = np.zeros((n, 4), dtype=np.uint8)
        colors[:, 3] = 255
        for i, c in enumerate(("red", "green", "blue", "alpha")):
            if c in fields:
                colors[:, i] = packed[c]
    ids = np.array(packed["entity"], dtype=np.int64) if "entity" in fields else None
    return pts, colors, ids


def split_entities(points: np.ndarray, ids: np.ndarray) -> list[np.ndarray]:
    """Split a decoded entity cloud into its entities, ordered by entity id."""
    if ids.size == 0:
        return []
    return [points[ids == i] for i in range(int(ids.max()) + 1)]


# --------------------------------------------------------------------------------------------
# tools


def _floats(values: Any, n: int, what: str) -> tuple[float, ...]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (n,):
        raise ValueError(f"{what} must have {n} numbers, got shape {np.shape(values)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class ToolPrimitive:
    """A tool drawn as one primitive, independent of the simulator.

    - ``name``: entity id in the scene (e.g. ``"knife"``), unique per message.
    - ``kind``: ``"cube"`` (knife, pusher), ``"cylinder"`` (roller) or ``"sphere"``.
    - ``size`` (3,): full extents along the primitive's local x, y, z (metres / workspace units);
      a cylinder's axis is its local z, so a roller of radius r and length L has size (2r, 2r, L).
    - ``position`` (3,): centre in the world frame.
    - ``quat_wxyz`` (4,): orientation, scalar first.
    - ``color`` (4,): RGBA in [0, 1].
    """

    name: str
    kind: str
    size: Sequence[float] | np.ndarray
    position: Sequence[float] | np.ndarray
    quat_wxyz: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0)
    color: Sequence[float] | np.ndarray = field(default=DEFAULT_TOOL_COLOR)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"tool name must be a non-empty string, got {self.name!r}")
        if self.kind not in TOOL_KINDS:
            raise ValueError(f"tool kind must be one of {TOOL_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "size", _floats(self.size, 3, "size"))
        object.__setattr__(self, "position", _floats(self.position, 3, "position"))
        q = _floats(self.quat_wxyz, 4, "quat_wxyz")
        if sum(v * v for v in q) == 0.0:
            raise ValueError("quat_wxyz must not be all zeros")
        object.__setattr__(self, "quat_wxyz", q)
        object.__setattr__(self, "color", _floats(self.color, 4, "color"))


def encode_tools(
    t_ns: int, tools: Sequence[ToolPrimitive], frame_id: str = WORLD_FRAME, removed: Sequence[str] = ()
) -> SceneUpdate:
    """SceneUpdate with one entity per tool; ``removed`` names get a deletion (so Foxglove stops
    drawing tools that are no longer listed, e.g. parked ones)."""
    names = [t.name for t in tools]
    if len(set(names)) != len(names):
        raise ValueError(f"tool names must be unique in one message, got {names}")
    update = SceneUpdate()
    for name in removed:
        deletion = update.deletions.add(type=SceneEntityDeletion.MATCHING_ID, id=name)
        _stamp(deletion.timestamp, t_ns)
    for tool in tools:
        if not isinstance(tool, ToolPrimitive):
            raise TypeError(f"tools must be ToolPrimitive instances, got {type(tool).__name__}")
        ent: SceneEntity = update.entities.add(id=tool.name, frame_id=frame_id)
        _stamp(ent.timestamp, t_ns)
        if tool.kind == "cube":
            prim = ent.cubes.add()
        elif tool.kind == "cylinder":
            prim = ent.cylinders.add(bottom_scale=1.0, top_scale=1.0)
        else:
            prim = ent.spheres.add()
        prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = tool.position
        w, x, y, z = tool.quat_wxyz
        o = prim.pose.orientation
        o.x, o.y, o.z, o.w = x, y, z, w
        prim.size.x, prim.size.y, prim.size.z = tool.size
        prim.color.CopyFrom(Color(r=tool.color[0], g=tool.color[1], b=tool.color[2], a=tool.color[3]))
    return update


def decode_tools(msg: SceneUpdate) -> list[ToolPrimitive]:
    tools = []
    for ent in msg.entities:
        for kind, prims in (("cube", ent.cubes), ("cylinder", ent.cylinders), ("sphere", ent.spheres)):
            for prim in prims:
                p, o, s, c = prim.pose.position, prim.pose.orientation, prim.size, prim.color
                tools.append(
                    ToolPrimitive(
                        name=ent.id,
                        kind=kind,
                        size=(s.x, s.y, s.z),
                        position=(p.x, p.y, p.z),
                        quat_wxyz=(o.w, o.x, o.y, o.z),
                        color=(c.r, c.g, c.b, c.a),
                    )
                )
    return tools


# --------------------------------------------------------------------------------------------
# log lines


@dataclass(frozen=True)
class LogEntry:
    """A ``foxglove.Log`` line: ``level`` is one of ``LOG_LEVELS`` (lower-case name)."""

    level: str
    text: str
    name: str = "pasta"


def level_code(level: int | str) -> int:
    if isinstance(level, str):
        key = level.lower()
        if key == "warn":
            key = "warning"
        if key not in LOG_LEVELS:
            raise ValueError(f"unknown log level {level!r}; use one of {list(LOG_LEVELS)}")
        return LOG_LEVELS[key]
    code = int(level)
    if code not in _LEVEL_NAMES:
        # stdlib logging numbers (10, 20, 30, 40, 50) map onto foxglove levels
        std = {10: 1, 20: 2, 30: 3, 40: 4, 50: 5}
        if code in std:
            return std[code]
        raise ValueError(f"unknown log level {level!r}")
    return code


def encode_world_upright(t_ns: int = 0) -> FrameTransform:
    """The transform from :data:`WORLD_FRAME` (y up) to :data:`Z_UP_FRAME` (z up): +90 degrees about x, which
    takes the world's y axis to z and its z axis to -y."""
    msg = FrameTransform(parent_frame_id=Z_UP_FRAME, child_frame_id=WORLD_FRAME)
    _stamp(msg.timestamp, t_ns)
    msg.translation.SetInParent()
    half = math.sqrt(0.5)
    msg.rotation.x, msg.rotation.y, msg.rotation.z, msg.rotation.w = half, 0.0, 0.0, half
    return msg


def encode_log(t_ns: int, level: int | str, text: str, name: str = "pasta") -> Log:
    msg = Log(level=Log.Level.ValueType(level_code(level)), message=str(text), name=name)
    _stamp(msg.timestamp, t_ns)
    return msg


def decode_log(msg: Log) -> LogEntry:
    return LogEntry(level=_LEVEL_NAMES.get(msg.level, "unknown"), text=msg.message, name=msg.name)


# --------------------------------------------------------------------------------------------
# JSON channels


def to_jsonable(obj: Any, _path: str = "$") -> Any:
    """Convert ``obj`` to plain JSON types: numpy arrays/scalars become lists/numbers, tuples become
    lists, mappings need string keys; non-finite floats become ``None`` (strict JSON has no NaN)."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, np.bool_):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist(), _path)
    if isinstance(obj, Mapping):
        out = {}
        for k, v in obj.items():
            if not isinstance(k, str):
                raise TypeError(f"JSON object keys must be strings, got {k!r} at {_path}")
            out[k] = to_jsonable(v, f"{_path}.{k}")
        return out
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, f"{_path}[{i}]") for i, v in enumerate(obj)]
    raise TypeError(f"cannot log {type(obj).__name__} at {_path} as JSON")


def encode_json(obj: Mapping[str, Any]) -> bytes:
    if not isinstance(obj, Mapping):
        raise TypeError(f"JSON messages must be objects (dict), got {type(obj).__name__}")
    return json.dumps(to_jsonable(obj), separators=(",", ":"), allow_nan=False).encode("utf-8")


def schema_bytes(schema: Mapping[str, Any]) -> bytes:
    """Canonical (sorted, compact) bytes of a JSON schema, so equal schemas give equal files."""
    if schema.get("type") != "object":
        raise ValueError('JSON channel schemas must be object schemas ("type": "object")')
    return json.dumps(schema, sort_keys=True, separators=(",", ":")).encode("utf-8")


_NUM = {"type": "number"}
_INT = {"type": "integer"}
_STR = {"type": "string"}
_VEC = {"type": "array", "items": _NUM}

PLAN_SCHEMA: dict[str, Any] = {
    "title": "pasta.Plan",
    "description": "A plan: the skill sequence, per-step attention and sub-goals, and its score.",
    "type": "object",
    "properties": {
        "skills": {"type": "array", "items": _STR},
        "steps": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "skill": _STR,
                    "inputs": {"type": "array", "items": _INT},
                    "outputs": {"type": "integer", "minimum": 0,
                                "description": "how many pieces the step produces (its skill's M_k)"},
                    "feasibility": _NUM,
                },
            },
        },
        "score": _NUM,
        "cost": _NUM,
    },
}

ACTION_SCHEMA: dict[str, Any] = {
    "title": "pasta.Action",
    "description": (
        "One env step's tool action ({step, tool, action}), a tool teleport "
        "({step, set_tool_pose: {name, position, yaw}} / {step, park_tool}), or a disturbance of the dough "
        "({step, disturb: the attachment that holds it})."
    ),
    "type": "object",
    "properties": {
        "step": _INT,
        "tool": _STR,
        "action": _VEC,
        "actions": {"type": "object", "additionalProperties": _VEC},
        "set_tool_pose": {
            "type": "object",
            "properties": {"name": _STR, "position": _VEC, "yaw": _NUM},
            "required": ["name", "position"],
        },
        "park_tool": _STR,
        "disturb": _STR,
    },
}

DECISION_SCHEMA: dict[str, Any] = {
    "title": "pasta.LoopDecision",
    "description": "The closed loop's verdict after an executed step: the plan kept or re-planned, and why.",
    "type": "object",
    "properties": {
        "after_step": _INT,
        "decision": {"type": "string", "enum": ["kept", "replanned"]},
        "reason": _STR,
        "distance_m": {"type": ["number", "null"]},
        "observed": _INT,
        "expected": _INT,
        "remaining": {"type": "array", "items": _STR},
        "new": {"type": "array", "items": _STR},
        "cost": _NUM,
        "seconds": _NUM,
    },
    "required": ["after_step", "decision", "reason"],
}

METRICS_SCHEMA: dict[str, Any] = {
    "title": "pasta.Metrics",
    "description": "Named scalar metrics, e.g. normalised improvement, EMD, success.",
    "type": "object",
    "additionalProperties": {"type": ["number", "boolean", "string", "null"]},
}

STEP_SCHEMA: dict[str, Any] = {
    "title": "pasta.StepResult",
    "description": "Result of one executed plan step.",
    "type": "object",
    "properties": {"step": _INT, "skill": _STR, "score": _NUM, "env_steps": _INT},
}

PROGRESS_SCHEMA: dict[str, Any] = {
    "title": "pasta.PlannerProgress",
    "description": "Planner optimisation progress.",
    "type": "object",
    "properties": {
        "stage": _STR,
        "iteration": _INT,
        "iterations": _INT,
        "best_score": _NUM,
        "mean_score": _NUM,
        "samples": _INT,
        "evaluations": _INT,
        "sequence": {"type": "array", "items": _STR},
    },
}


def generic_schema(title: str) -> dict[str, Any]:
    return {"title": title, "type": "object"}
