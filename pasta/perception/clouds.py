"""Reading point-cloud files and the input frame of ``pasta plan``.

Files: ``.npy`` holding ``(P, 3)`` or an organised ``(H, W, 3)`` cloud, and PLY (``ascii``,
``binary_little_endian``, ``binary_big_endian``; the vertex properties ``x``, ``y``, ``z`` of any numeric
type). An organised cloud may have holes: rows with a NaN or infinite coordinate, or exactly ``(0, 0, 0)``
(how depth cameras mark pixels without depth); they are dropped and get label ``-1`` in the per-point
outputs. An unorganised ``(P, 3)`` cloud with a NaN is refused (it is a broken file, not a camera hole).

The frame (:class:`CloudFrame`): input points are first scaled to metres (``units=m|mm``), then mapped
by the optional 4x4 ``transform`` (camera to workspace, in metres), then, for ``up=z``, rotated from a
z-up frame to pasta's y-up one by the cyclic permutation ``(x, y, z) -> (y, z, x)`` (a proper rotation
that keeps the unit cube). :meth:`CloudFrame.from_workspace` is the exact inverse, used to write
sub-goals back in the input's frame and units.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError

__all__ = ["CloudFrame", "LoadedCloud", "read_cloud", "read_ply", "read_transform", "MAX_FILE_POINTS"]

#: a cloud file with more points is refused before it is read (loading and downsampling cost ~80 bytes a point)
MAX_FILE_POINTS = 10_000_000

UNITS = {"m": 1.0, "mm": 1e-3}
UPS = ("y", "z")

#: PLY scalar types -> numpy
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


@dataclass(frozen=True)
class LoadedCloud:
    """A cloud as read from its file.

    Attributes:
        points: ``(P, 3)`` float64, the valid points (holes removed), in the file's frame and units.
        valid: ``(N,)`` bool, which of the file's ``N`` points are in ``points``.
        shape: the shape labels are written in: ``(N,)``, or ``(H, W)`` for an organised cloud.
    """

    points: np.ndarray
    valid: np.ndarray
    shape: tuple[int, ...]


@dataclass(frozen=True)
class CloudFrame:
    """Input frame -> pasta's workspace frame (metres, y up): units, then ``transform``, then ``up``.

    Attributes:
        units: ``"m"`` or ``"mm"``.
        up: ``"y"`` (pasta's frame) or ``"z"``.
        transform: ``(4, 4)`` homogeneous rigid (or affine) map applied after unit conversion, or None.
    """

    units: str = "m"
    up: str = "y"
    transform: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.units not in UNITS:
            raise InputError(f"units={self.units}: allowed m, mm")
        if self.up not in UPS:
            raise InputError(f"up={self.up}: allowed y, z")
        if self.transform is not None:
            t = np.asarray(self.transform, dtype=np.float64)
            if t.shape != (4, 4) or not np.isfinite(t).all():
                raise InputError(f"transform must be a finite 4x4 matrix, got shape {t.shape}")
            if not np.allclose(t[3], [0, 0, 0, 1]):
                raise InputError(f"transform: the last row must be 0 0 0 1, got {t[3].tolist()}")
            if abs(np.linalg.det(t[:3, :3])) < 1e-9:
                raise InputError("transform: its 3x3 part is singular (it cannot be inverted)")
            object.__setattr__(self, "transform", t)

    @property
    def identity(self) -> bool:
        return self.units == "m" and self.up == "y" and self.transform is None

    def to_workspace(self, points: np.ndarray) -> np.ndarray:
        """``(P, 3)`` input points -> ``(P, 3)`` float64 workspace points."""
        p = np.asarray(points, dtype=np.float64) * UNITS[self.units]
        if self.transform is not None:
            p = p @ self.transform[:3, :3].T + self.transform[:3, 3]
        if self.up == "z":
            p = p[:, [1, 2, 0]]
        return p

    def from_workspace(self, points: np.ndarray) -> np.ndarray:
        """``(..., 3)`` workspace points -> the input frame and units (inverse of :meth:`to_workspace`)."""
        p = np.asarray(points, dtype=np.float64)
        shape = p.shape
        p = p.reshape(-1, 3)
        if self.up == "z":
            p = p[:, [2, 0, 1]]
        if self.transform is not None:
            p = np.linalg.solve(self.transform[:3, :3], (p - self.transform[:3, 3]).T).T
        return (p / UNITS[self.units]).reshape(shape)

    def describe(self) -> dict:
        return {"units": self.units, "up": self.up,
                "transform": None if self.transform is None else self.transform.tolist()}


def read_transform(path: str | Path) -> np.ndarray:
    """A 4x4 matrix from ``.npy`` or a text file of 4 rows of 4 numbers; bad files raise InputError."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"transform file {str(p)!r} does not exist")
    try:
        t = np.load(p, allow_pickle=False) if p.suffix.lower() == ".npy" else np.loadtxt(p, ndmin=2)
    except Exception as exc:  # noqa: BLE001 - any parse failure becomes a clear input error
        raise InputError(f"transform file {str(p)!r} cannot be read: {exc}") from None
    t = np.asarray(t, dtype=np.float64)
    if t.shape != (4, 4):
        raise InputError(f"transform file {str(p)!r} must hold a 4x4 matrix, got shape {t.shape}")
    CloudFrame(transform=t)  # the same checks
    return t


def read_cloud(path: str | Path, name: str = "cloud", *, max_file_points: int = MAX_FILE_POINTS) -> LoadedCloud:
    """Read ``.npy`` ``(P, 3)`` / ``(H, W, 3)`` or PLY; bad files raise :class:`InputError` naming the problem."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{name}={str(p)!r} is a directory; give a cloud file (.npy or .ply)")
    if not p.exists():
        raise InputError(f"{name} file {str(p)!r} does not exist")
    if not p.is_file():
        raise InputError(f"{name} file {str(p)!r} is not a regular file (a device, pipe or socket)")
    suffix = p.suffix.lower()
    try:
        if suffix == ".npy":
            shape = _npy_shape(p, name)  # reads the header, not the data
            count = int(np.prod(shape[:-1])) if shape else 0
            _check_file_size(count, name, p, max_file_points)
            arr = np.load(p, allow_pickle=False)
        elif suffix == ".ply":
            arr = read_ply(p, name, max_file_points=max_file_points)
        else:
            raise InputError(f"{name} file {str(p)!r}: unsupported extension {suffix!r}; use .npy or .ply")
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - any parse failure becomes a clear input error
        raise InputError(f"{name} file {str(p)!r} cannot be read: {exc}") from None
    arr = np.asarray(arr)
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name} file {str(p)!r} must hold numbers, got dtype {arr.dtype}")
    label = f"{name} cloud {p.name}"
    if arr.ndim == 3 and arr.shape[-1] == 3:  # organised (H, W, 3): holes are NaN/inf or (0, 0, 0)
        flat = arr.reshape(-1, 3).astype(np.float64)
        valid = np.isfinite(flat).all(1) & (flat != 0).any(1)
        if not valid.any():
            raise InputError(f"{label}: the organised {arr.shape[0]}x{arr.shape[1]} cloud has no valid point "
                             "(every pixel is NaN, infinite or (0, 0, 0))")
        return LoadedCloud(flat[valid], valid, tuple(arr.shape[:2]))
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{label} must be an array of shape (P, 3) or an organised (H, W, 3), got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise InputError(f"{label} is empty: a dough cloud needs at least one point")
    flat = arr.astype(np.float64)
    if not np.isfinite(flat).all():
        bad = int((~np.isfinite(flat).all(1)).sum())
        raise InputError(f"{label} contains NaN or infinite values ({bad} of {len(flat)} points); only an organised "
                         "(H, W, 3) cloud may have NaN holes")
    return LoadedCloud(flat, np.ones(len(flat), bool), (len(flat),))


def _npy_shape(path: Path, name: str) -> tuple[int, ...]:
    """The array shape a ``.npy`` header declares. A file without the ``\\x93NUMPY`` magic is not a .npy (numpy
    would try to unpickle its bytes, and its error would call any file "pickled data"); an object array is
    named as one (reading it would need pickle)."""
    with open(path, "rb") as fh:
        if fh.read(6) != b"\x93NUMPY":
            raise InputError(f"{name} file {str(path)!r} is not a .npy file (it does not start with the NumPy magic "
                             "bytes \\x93NUMPY): save the cloud with numpy.save, or give a .ply")
        fh.seek(0)
        version = np.lib.format.read_magic(fh)
        if version not in ((1, 0), (2, 0)):  # a newer format: numpy reads its header (mapped, not loaded)
            header = np.load(path, mmap_mode="r", allow_pickle=False)
            return tuple(header.shape)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _fortran, dtype = read(fh)
    if dtype.hasobject:
        raise InputError(f"{name} file {str(path)!r} holds pickled Python objects (dtype object); pasta reads numeric "
                         "arrays only, without pickle")
    return tuple(shape)


def _check_file_size(count: int, name: str, path: Path, limit: int) -> None:
    if count > limit:
        raise InputError(f"{name} file {str(path)!r} has {count:,} points, more than pasta plan reads "
                         f"({limit:,}); downsample it first (max_points= bounds what reaches decomposition)")


def read_ply(path: str | Path, name: str = "cloud", *, max_file_points: int = MAX_FILE_POINTS) -> np.ndarray:
    """The ``(P, 3)`` float64 ``x, y, z`` of a PLY file's vertices (ascii, binary little or big endian)."""
    path = Path(path)
    with open(path, "rb") as f:
        raw = f.read()
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise InputError(f"{str(path)!r} is not a PLY file (no 'ply' magic line or no end_header)")
    nl = raw.find(b"\n", end)
    body_start = len(raw) if nl < 0 else nl + 1
    header = raw[:end].decode("ascii", errors="replace").splitlines()
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, str | None]]]] = []  # (name, count, [(prop, type or None: a list)])
    for line in header[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) >= 3:
            try:
                count = int(words[2])
            except ValueError:
                raise InputError(f"{str(path)!r}: bad element line {line!r}") from None
            if count < 0:
                raise InputError(f"{str(path)!r}: bad element line {line!r}")
            elements.append((words[1], count, []))
        elif words[0] == "property" and elements:
            if len(words) >= 5 and words[1] == "list":
                elements[-1][2].append((words[-1], None))
            elif len(words) >= 3:
                if words[1] not in _PLY_TYPES:
                    raise InputError(f"{str(path)!r}: unknown PLY property type {words[1]!r}")
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{str(path)!r}: PLY format {fmt!r} is not one of ascii, binary_little_endian, "
                         "binary_big_endian")
    vertex = next((e for e in elements if e[0] == "vertex"), None)
    if vertex is None or not {"x", "y", "z"} <= {n for n, _ in vertex[2]}:
        raise InputError(f"{str(path)!r}: PLY header must declare vertex properties x, y, z")
    _check_file_size(vertex[1], name, path, max_file_points)
    if any(t is None for _, t in vertex[2]):
        raise InputError(f"{str(path)!r}: list properties in the vertex element are not supported")
    if vertex[1] == 0:
        return np.zeros((0, 3))
    names = [n for n, _ in vertex[2]]
    if fmt == "ascii":
        lines = raw[body_start:].decode("ascii", errors="replace").splitlines()
        skip = 0
        for e in elements:  # elements before the vertices take one line per item
            if e is vertex:
                break
            skip += e[1]
        rows = list(lines[skip:skip + vertex[1]])
        expected = f"{str(path)!r}: expected {vertex[1]} vertex rows of {len(names)} values"
        if len(rows) != vertex[1]:
            raise InputError(expected)
        try:  # numpy's C parser: a 1e6-point file without a Python list per row
            data = np.loadtxt(rows, dtype=np.float64, ndmin=2, usecols=[names.index(c) for c in "xyz"])
        except ValueError:
            raise InputError(expected) from None
        return data.reshape(-1, 3)
    order = "<" if fmt == "binary_little_endian" else ">"
    offset = body_start
    for e in elements:
        if e is vertex:
            break
        if any(t is None for _, t in e[2]):
            raise InputError(f"{str(path)!r}: element {e[0]!r} with list properties before the vertices is not supported")
        offset += e[1] * int(sum(np.dtype(t).itemsize for _, t in e[2]))
    dtype = np.dtype([(n, f"{order}{t}") for n, t in vertex[2]])  # no list properties (t is not None): checked
    need = vertex[1] * dtype.itemsize
    if len(raw) - offset < need:
        raise InputError(f"{str(path)!r}: the file ends before its {vertex[1]} vertices ({len(raw) - offset} of "
                         f"{need} bytes)")
    records = np.frombuffer(raw, dtype=dtype, count=vertex[1], offset=offset)
    return np.stack([records[c].astype(np.float64) for c in "xyz"], 1)
