"""Byte-reproducible, crash-safe ``.npz`` files (no pickle).

``numpy.savez_compressed`` stamps every zip entry with the current time, so two runs that produce the
same arrays still differ byte for byte. :func:`write_npz` writes the same format (``np.load`` reads it,
``allow_pickle=False`` is enough) with a fixed timestamp, through :func:`pasta.core.files.atomic_write`: a killed run never leaves a
half-written file under the final name, and a link at the target is replaced, not followed.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError
from pasta.core.files import atomic_write

_EPOCH = (1980, 1, 1, 0, 0, 0)


def write_npz(path: str | Path, arrays: Mapping[str, np.ndarray], *, compress: bool = True) -> Path:
    """Write ``arrays`` (name -> array; strings become 0-d unicode arrays) to ``path`` atomically."""
    path = Path(path)
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with atomic_write(path) as fh, zipfile.ZipFile(fh, "w", compression=method) as zf:
        for name, value in arrays.items():
            arr = np.asarray(value)
            if arr.dtype == object:
                raise InputError(f"write_npz: array '{name}' has dtype object (would need pickle)")
            buf = io.BytesIO()
            if arr.ndim and not arr.flags.c_contiguous:  # (ascontiguousarray would turn 0-d into 1-d)
                arr = np.ascontiguousarray(arr)
            np.lib.format.write_array(buf, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_EPOCH)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())
    return path


def read_npz(path: str | Path) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file, loaded eagerly without pickle."""
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
