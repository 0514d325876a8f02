"""The Tool contract: a rigid simulator tool that a skill plugin registers (geometry, actions, parking).

A :class:`ToolSpec` is plain data, known without importing numpy or taichi, so the plugin registry can
list tools and check, at load time, that every skill's ``SkillSpec.tool`` names a registered tool. The
simulator (``pasta.sim``) turns it into runtime kernel data; adding a tool never recompiles a kernel.

Geometry is a union of primitives from the kernel's menu (:data:`PRIMITIVE_KINDS`), each placed by an
offset in the tool frame (y up; yaw turns the frame about the world y axis):

- :class:`Box`: half extents ``half`` (3,).
- :class:`Capsule`: a cylinder of ``radius`` along the local z axis, ``half_length`` (axis half length),
  with round caps.
- :class:`WedgeBlade`: a box whose bottom is a downward wedge (the knife): the box ``half`` intersected
  with a wedge of half angle ``half_angle`` degrees whose edge is the box's bottom face centre line
  (along local z).
- :class:`FingerPair`: a parallel gripper, two boxes of half extents ``half`` either side of the local
  y-z plane; the gap between their inner faces is the tool's aperture (an ``open`` action channel
  changes it, between ``min_aperture`` and ``max_aperture``).

Actions (:data:`CHANNELS`), every component in [-1, 1] times its channel's scale per env step:

- ``x``, ``y``, ``z``: translation along the world axis; ``yaw``: rotation about world y (radians);
- ``roll``: roll about the local z axis by that angle (radians): the tool moves along its local x by
  angle * radius of its capsule and spins (a rolling pin);
- ``slide``: translation along the local x axis;
- ``open``: aperture change of the finger pair.

Trailing components may be optional (``required_action``): missing ones are 0. A tool with no channels
is a static obstacle (e.g. a raised board), placed with ``Simulator.set_tool_pose``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import KW_ONLY, dataclass, field
from typing import Any, ClassVar, cast

from pasta.core.errors import PluginValidationError

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")

#: the primitive kinds the simulator kernel supports
PRIMITIVE_KINDS: tuple[str, ...] = ("box", "capsule", "wedge_blade", "finger_pair")
#: the action channels the simulator supports
CHANNELS: tuple[str, ...] = ("x", "y", "z", "yaw", "roll", "slide", "open")
#: at most this many primitives per tool (the kernel's slots per tool)
MAX_PRIMITIVES = 4

Vec3 = tuple[float, float, float]


def _xyz(values: Iterable[float]) -> Vec3:
    x, y, z = values
    return x, y, z


def _vec(value: Any, n: int, where: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise PluginValidationError(f"{where} must be {n} numbers, got {value!r}") from None
    if len(out) != n or not all(math.isfinite(v) for v in out):
        raise PluginValidationError(f"{where} must be {n} finite numbers, got {value!r}")
    return out


def _number(value: object, where: str, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise PluginValidationError(f"{where} must be a finite number, got {value!r}")
    v = float(value)
    if positive and v <= 0:
        raise PluginValidationError(f"{where} must be > 0, got {value!r}")
    if nonneg and v < 0:
        raise PluginValidationError(f"{where} must be >= 0, got {value!r}")
    return v


@dataclass(frozen=True, kw_only=True)
class Primitive:
    """Base of the geometry menu: a shape placed at ``offset`` (3,) in the tool frame."""

    offset: Vec3 = (0.0, 0.0, 0.0)
    kind: ClassVar[str] = ""

    def _check(self, where: str) -> None:
        object.__setattr__(self, "offset", _vec(self.offset, 3, f"{where}.offset"))

    def box_extent(self, aperture: float | None = None) -> tuple[Vec3, Vec3]:
        """Axis-aligned (lo, hi) corners in the tool frame (finger pairs at ``aperture``, default the widest)."""
        raise NotImplementedError

    def reach(self) -> float:
        """Distance from ``offset`` to the farthest point of the shape (finger pairs at their widest)."""
        raise NotImplementedError

    def draw(self, aperture: float | None = None) -> list[tuple[str, Vec3, Vec3]]:
        """Shapes for a viewer: [(``"cube"`` | ``"cylinder"``, full size (3,), centre offset (3,))]; a
        cylinder's axis is the local z axis."""
        raise NotImplementedError


def _box_extent(offset: Vec3, half: Vec3) -> tuple[Vec3, Vec3]:
    return _xyz(o - h for o, h in zip(offset, half)), _xyz(o + h for o, h in zip(offset, half))


@dataclass(frozen=True, kw_only=True)
class Box(Primitive):
    """A box of half extents ``half`` (3,)."""

    half: Vec3
    kind: ClassVar[str] = "box"

    def _check(self, where: str) -> None:
        super()._check(where)
        half = _vec(self.half, 3, f"{where}.half")
        if min(half) <= 0:
            raise PluginValidationError(f"{where}.half must be > 0, got {self.half!r}")
        object.__setattr__(self, "half", half)

    def box_extent(self, aperture: float | None = None) -> tuple[Vec3, Vec3]:
        return _box_extent(self.offset, self.half)

    def reach(self) -> float:
        return math.sqrt(sum(h * h for h in self.half))

    def draw(self, aperture: float | None = None) -> list[tuple[str, Vec3, Vec3]]:
        return [("cube", _xyz(2 * h for h in self.half), self.offset)]


@dataclass(frozen=True, kw_only=True)
class WedgeBlade(Box):
    """A blade: the box ``half`` (3,) cut below by a downward wedge of half angle ``half_angle`` degrees;
    the edge runs along local z at the box's bottom (``offset_y - half[1]``)."""

    half_angle: float = 30.0
    kind: ClassVar[str] = "wedge_blade"

    def _check(self, where: str) -> None:
        super()._check(where)
        a = _number(self.half_angle, f"{where}.half_angle")
        if not 0.0 < a < 90.0:
            raise PluginValidationError(f"{where}.half_angle must be in (0, 90) degrees, got {self.half_angle!r}")
        object.__setattr__(self, "half_angle", a)


@dataclass(frozen=True, kw_only=True)
class Capsule(Primitive):
    """A capsule along the local z axis: ``radius``, axis half length ``half_length`` (caps excluded)."""

    radius: float
    half_length: float
    kind: ClassVar[str] = "capsule"

    def _check(self, where: str) -> None:
        super()._check(where)
        object.__setattr__(self, "radius", _number(self.radius, f"{where}.radius", positive=True))
        object.__setattr__(self, "half_length", _number(self.half_length, f"{where}.half_length", nonneg=True))

    def box_extent(self, aperture: float | None = None) -> tuple[Vec3, Vec3]:
        r = self.radius
        return _box_extent(self.offset, (r, r, self.half_length + r))

    def reach(self) -> float:
        return self.radius + self.half_length

    def draw(self, aperture: float | None = None) -> list[tuple[str, Vec3, Vec3]]:
        r = self.radius
        return [("cylinder", (2 * r, 2 * r, 2 * self.half_length), self.offset)]


@dataclass(frozen=True, kw_only=True)
class FingerPair(Primitive):
    """Two parallel fingers, boxes of half extents ``half`` (3,), at local x = +-(aperture / 2 + half[0])
    from ``offset``. ``aperture`` is the starting gap between the inner faces (every reset and parking
    restores it); an ``open`` action changes it within [``min_aperture``, ``max_aperture``]."""

    half: Vec3
    aperture: float
    min_aperture: float = 0.0
    max_aperture: float | None = None
    kind: ClassVar[str] = "finger_pair"

    def _check(self, where: str) -> None:
        super()._check(where)
        half = _vec(self.half, 3, f"{where}.half")
        if min(half) <= 0:
            raise PluginValidationError(f"{where}.half must be > 0, got {self.half!r}")
        object.__setattr__(self, "half", half)
        ap = _number(self.aperture, f"{where}.aperture", nonneg=True)
        lo = _number(self.min_aperture, f"{where}.min_aperture", nonneg=True)
        hi = ap if self.max_aperture is None else _number(self.max_aperture, f"{where}.max_aperture", nonneg=True)
        if not lo <= ap <= hi:
            raise PluginValidationError(
                f"{where}: need min_aperture <= aperture <= max_aperture, got {lo} <= {ap} <= {hi}")
        object.__setattr__(self, "aperture", ap)
        object.__setattr__(self, "min_aperture", lo)
        object.__setattr__(self, "max_aperture", hi)

    def finger_x(self, aperture: float) -> float:
        """Local x distance of each finger's centre from ``offset`` at ``aperture``."""
        return aperture / 2 + self.half[0]

    @property
    def _widest(self) -> float:
        # _check sets max_aperture (to aperture when not given) before a pair is used
        return cast(float, self.max_aperture)

    def box_extent(self, aperture: float | None = None) -> tuple[Vec3, Vec3]:
        ap = self._widest if aperture is None else aperture
        cx = self.finger_x(ap)
        hx, hy, hz = self.half
        return _box_extent(self.offset, (cx + hx, hy, hz))

    def reach(self) -> float:
        hx, hy, hz = self.half
        return math.sqrt((self.finger_x(self._widest) + hx) ** 2 + hy * hy + hz * hz)

    def draw(self, aperture: float | None = None) -> list[tuple[str, Vec3, Vec3]]:
        ap = self.aperture if aperture is None else aperture
        cx = self.finger_x(ap)
        size = _xyz(2 * h for h in self.half)
        ox, oy, oz = self.offset
        return [("cube", size, (ox - cx, oy, oz)), ("cube", size, (ox + cx, oy, oz))]


@dataclass(frozen=True)
class ActionChannel:
    """One action component: ``kind`` from :data:`CHANNELS`, ``scale`` its size per env step at 1
    (metres; radians for ``yaw`` and ``roll``)."""

    kind: str
    scale: float


@dataclass(frozen=True)
class ToolSpec:
    """A simulator tool, registered by a plugin through ``pasta_register_tools``.

    Attributes:
        name: registry name, lower case (``"knife"``); ``SkillSpec.tool`` refers to it.
        description: one line for ``pasta plugins``.
        primitives: the geometry, a union of 1..:data:`MAX_PRIMITIVES` primitives. Empty: the tool is a
            name only (analytic or test plugins that simulate nothing); the simulator refuses it.
        action: the action layout, one :class:`ActionChannel` per component (empty: a static obstacle).
        required_action: how many leading components an action must have (the rest are optional and
            default to 0); ``None`` means all.
        park: where the tool waits, centre (3,), yaw 0; also its pose after ``reset``.
        stand: where tasks and demonstration scenes stand the tool, centre (3,), yaw 0 (a static obstacle
            such as the raised board: :attr:`stand_top` is its top); ``None``: nowhere in particular. Other
            plugins find it here through the registry instead of importing the plugin that registers it.
            Left out of ``repr``: task cache keys hash the repr of the tools a chain uses, and declaring
            where a tool stands changes no generated instance.
        min_height: lowest allowed centre height y; ``None``: the geometry's lowest point may reach y = 0.
        friction: Coulomb friction of dough against the tool (``SimConfig.tool_friction`` overrides it).
        surface_points: (T, 3) observed points in the tool frame; ``None``: generated from the primitives.
        color: a matplotlib colour name for pictures ("" = the renderer picks one).
    """

    name: str
    description: str = ""
    _: KW_ONLY
    primitives: tuple[Primitive, ...] = ()
    action: tuple[ActionChannel, ...] = ()
    required_action: int | None = None
    park: Vec3 | None = None
    stand: Vec3 | None = field(default=None, repr=False)
    min_height: float | None = None
    friction: float = 0.0
    surface_points: tuple[Vec3, ...] | None = None
    color: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise PluginValidationError(
                f"tool name {self.name!r} must be lower case letters, digits and '_', starting with a letter"
            )
        where = f"tool '{self.name}'"
        if not isinstance(self.description, str):
            raise PluginValidationError(f"{where}: description must be a string")
        if not isinstance(self.color, str):
            raise PluginValidationError(f"{where}: color must be a string")
        if not isinstance(self.primitives, (list, tuple)):
            raise PluginValidationError(f"{where}: primitives must be a tuple of pasta.core.tool primitives")
        prims = tuple(self.primitives)
        if not prims:  # a name only: nothing else may be set
            if self.action or self.park is not None or self.stand is not None or self.surface_points is not None:
                raise PluginValidationError(
                    f"{where}: has no primitives (a name-only tool) but sets action, park, stand or surface_points; "
                    "give it geometry (primitives=(Box(half=...), ...)) to simulate it")
            object.__setattr__(self, "primitives", ())
            object.__setattr__(self, "action", ())
            object.__setattr__(self, "required_action", 0)
            return
        if len(prims) > MAX_PRIMITIVES:
            raise PluginValidationError(f"{where}: {len(prims)} primitives, the simulator supports at most {MAX_PRIMITIVES}")
        for i, p in enumerate(prims):
            if not isinstance(p, Primitive) or p.kind not in PRIMITIVE_KINDS:
                raise PluginValidationError(
                    f"{where}: primitives[{i}] must be one of Box, Capsule, WedgeBlade, FingerPair, got {p!r}")
            p._check(f"{where}: primitives[{i}] ({p.kind})")
        object.__setattr__(self, "primitives", prims)

        chans = tuple(self.action) if isinstance(self.action, (list, tuple)) else None
        if chans is None:
            raise PluginValidationError(f"{where}: action must be a tuple of ActionChannel")
        seen = set()
        for i, c in enumerate(chans):
            if not isinstance(c, ActionChannel):
                raise PluginValidationError(f"{where}: action[{i}] must be an ActionChannel, got {c!r}")
            if c.kind not in CHANNELS:
                raise PluginValidationError(f"{where}: action[{i}] channel {c.kind!r} is not one of {', '.join(CHANNELS)}")
            if c.kind in seen:
                raise PluginValidationError(f"{where}: action channel {c.kind!r} appears twice")
            seen.add(c.kind)
            _number(c.scale, f"{where}: action[{i}] ({c.kind}).scale", positive=True)
        object.__setattr__(self, "action", chans)
        req = len(chans) if self.required_action is None else self.required_action
        if isinstance(req, bool) or not isinstance(req, int) or not 0 <= req <= len(chans) or (chans and req == 0):
            raise PluginValidationError(
                f"{where}: required_action must be an int in [1, {len(chans)}] (the number of action channels), "
                f"got {self.required_action!r}")
        object.__setattr__(self, "required_action", req)
        if "roll" in seen:
            caps = [p for p in prims if isinstance(p, Capsule)]
            if len(caps) != len(prims) or any(p.offset[0] != 0.0 or p.offset[1] != 0.0 for p in caps):
                raise PluginValidationError(
                    f"{where}: a 'roll' channel needs a tool of capsules on its local z axis (offset x = y = 0): "
                    "the simulator spins the tool about that axis and treats it as round")
        fingers = [p for p in prims if isinstance(p, FingerPair)]
        if len(fingers) > 1:
            raise PluginValidationError(f"{where}: at most one finger_pair primitive (the tool has one aperture)")
        if "open" in seen and not fingers:
            raise PluginValidationError(f"{where}: an 'open' channel needs a finger_pair primitive")

        if self.park is None:
            raise PluginValidationError(f"{where}: park (the parking centre (x, y, z)) is required")
        park = _vec(self.park, 3, f"{where}: park")
        if not all(0.0 < v < 1.0 for v in park):
            raise PluginValidationError(f"{where}: park {park} must lie inside the unit-cube workspace")
        object.__setattr__(self, "park", park)
        if self.stand is not None:
            stand = _vec(self.stand, 3, f"{where}: stand")
            if not all(0.0 < v < 1.0 for v in stand):
                raise PluginValidationError(f"{where}: stand {stand} must lie inside the unit-cube workspace")
            object.__setattr__(self, "stand", stand)
        if self.min_height is not None:
            object.__setattr__(self, "min_height", _number(self.min_height, f"{where}: min_height"))
        object.__setattr__(self, "friction", _number(self.friction, f"{where}: friction", nonneg=True))
        if self.surface_points is not None:
            try:
                pts = tuple(_vec(p, 3, f"{where}: surface_points[{i}]") for i, p in enumerate(self.surface_points))
            except TypeError:
                raise PluginValidationError(f"{where}: surface_points must be (T, 3) numbers") from None
            if not pts:
                raise PluginValidationError(f"{where}: surface_points must hold at least one point (or be None)")
            object.__setattr__(self, "surface_points", pts)

    # ------------------------------------------------------------------ derived facts
    @property
    def simulated(self) -> bool:
        """Whether the tool has geometry (name-only tools cannot be put into a simulator)."""
        return bool(self.primitives)

    @property
    def action_dim(self) -> int:
        """Number of action components (0 for a static obstacle)."""
        return len(self.action)

    @property
    def action_scales(self) -> tuple[float, ...]:
        return tuple(c.scale for c in self.action)

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(c.kind for c in self.action)

    @property
    def is_static(self) -> bool:
        return not self.action

    def scale(self, channel: str) -> float:
        """Scale of ``channel``; PluginValidationError naming the tool if it has no such channel."""
        for c in self.action:
            if c.kind == channel:
                return c.scale
        raise PluginValidationError(f"tool '{self.name}' has no '{channel}' action channel (has {', '.join(self.channels) or 'none'})")

    @property
    def finger_pair(self) -> FingerPair | None:
        return next((p for p in self.primitives if isinstance(p, FingerPair)), None)

    @property
    def default_aperture(self) -> float:
        """The finger pair's starting aperture (0 for tools without one)."""
        fp = self.finger_pair
        return fp.aperture if fp is not None else 0.0

    @property
    def roll_radius(self) -> float:
        """Radius that converts a roll angle into travel (the largest capsule radius)."""
        caps = [p.radius for p in self.primitives if isinstance(p, Capsule)]
        if not caps:
            raise PluginValidationError(f"tool '{self.name}' has no capsule to roll on")
        return max(caps)

    def extent(self) -> tuple[Vec3, Vec3]:
        """(lo, hi) corners of the tool's local bounding box (finger pairs at their widest)."""
        boxes = [p.box_extent() for p in self.primitives]
        lo = _xyz(min(b[0][d] for b in boxes) for d in range(3))
        hi = _xyz(max(b[1][d] for b in boxes) for d in range(3))
        return lo, hi

    @property
    def lowest_centre(self) -> float:
        """Lowest allowed centre height y: ``min_height`` or the height where the geometry's bottom is at y = 0."""
        if self.min_height is not None:
            return self.min_height
        return -self.extent()[0][1]

    @property
    def stand_top(self) -> float:
        """Height y of the tool's top where it stands (:attr:`stand`); PluginValidationError naming the tool
        when it has no stand pose."""
        if self.stand is None:
            raise PluginValidationError(f"tool '{self.name}' has no stand pose (ToolSpec.stand)")
        return self.stand[1] + self.extent()[1][1]

    @property
    def bound_radius(self) -> float:
        """Radius of a sphere around the tool centre that holds the whole tool, for any yaw and aperture."""
        return max((math.sqrt(sum(o * o for o in p.offset)) + p.reach() for p in self.primitives), default=0.0)

    def draw(self, aperture: float | None = None) -> list[tuple[str, Vec3, Vec3]]:
        """Viewer shapes of the whole tool: [(``"cube"`` | ``"cylinder"``, full size (3,), centre offset (3,))]."""
        return [s for p in self.primitives for s in p.draw(aperture)]
