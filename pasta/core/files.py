"""How pasta writes files: whole, never through a link, one writer per output.

Every file a command writes goes through :func:`atomic_write` (or :func:`write_bytes`, :func:`write_text`,
:func:`write_json`, which wrap it): the bytes go to a fresh temporary file in the target's directory
(created with ``O_EXCL`` under a random name, so a link planted under a predictable name is never opened),
are flushed and fsynced, and the temporary is renamed over the target. A rename replaces a symbolic link
at the target *itself*, never the file it points to, so a link planted in ``out=`` cannot redirect a
write outside it; a reader never sees a half-written file under the final name.

Append-only logs (``pasta eval``'s per-episode lines) are opened with ``O_NOFOLLOW`` (:func:`append_text`):
a link there is refused with a message, not followed.

:class:`OutputLock` makes one process the only writer of an output (a run log, an ``out=`` directory): a
second process that targets it fails at once with a message naming the holder, before any work. The lock is
an advisory ``flock`` on a file named after the output in this user's lock folder (:func:`lock_path`); the
kernel releases it when the holder exits, however it exits, so a killed run never leaves a stale lock behind.
"""

from __future__ import annotations

import errno
import functools
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, ClassVar

from pasta.core.errors import InputError, PastaError

__all__ = ["atomic_write", "write_bytes", "write_text", "write_json", "append_text", "OutputLock", "OutputBusyError",
           "lock_path"]


@contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file for ``path`` (``mode`` ``"wb"`` or ``"w"``); on a clean exit it replaces ``path``.

    The parents of ``path`` are created. When the block raises, the temporary is removed and ``path`` is
    untouched (an earlier file of that name survives whole).
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_write: mode must be 'wb' or 'w', got {mode!r}")
    target = Path(path)
    if target.is_dir() and not target.is_symlink():
        raise IsADirectoryError(errno.EISDIR, "cannot write a file over a directory", str(target))
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        text = mode == "w"
        with os.fdopen(fd, mode, encoding="utf-8" if text else None, newline="" if text else None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644 & ~_umask())
        os.replace(tmp, target)  # replaces a link at ``target`` itself: the link's target is never written
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    _fsync_dir(target.parent)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` whole (:func:`atomic_write`)."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` whole (:func:`atomic_write`)."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | os.PathLike[str], doc: Any, *, indent: int | None = 2, sort_keys: bool = False) -> Path:
    """Write ``doc`` as JSON with a final newline to ``path`` whole."""
    return write_text(path, json.dumps(doc, indent=indent, sort_keys=sort_keys) + "\n")


def save_with(path: str | os.PathLike[str], save: Callable[[IO[bytes]], Any]) -> Path:
    """``save(file_object)`` into a temporary, then replace ``path`` (for writers that take a file object:
    ``fig.savefig(fh, format="png")``, ``np.save(fh, a)``, ``image.save(fh, format="gif")``)."""
    with atomic_write(path, "wb") as fh:
        save(fh)
    return Path(path)


def append_text(path: str | os.PathLike[str], text: str) -> None:
    """Append ``text`` to ``path`` (created when absent) and fsync; a symbolic link at ``path`` is refused."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(target, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"{target} is a symbolic link; pasta does not write through links (remove it)") from None
        raise
    with os.fdopen(fd, "a", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def refuse_link(path: str | os.PathLike[str], key: str) -> None:
    """Raise :class:`InputError` when ``path`` is a symbolic link (an output that is appended to, or read
    back and extended, would follow it)."""
    if Path(path).is_symlink():
        raise InputError(f"{key}={path}: is a symbolic link; pasta does not write through links (remove it or "
                         f"choose another path)")


class OutputBusyError(PastaError):
    """Another process is writing the same output (a run log or an ``out=`` directory)."""


def lock_path(output: str | os.PathLike[str]) -> Path:
    """The lock file of ``output`` (a file or a folder, existing or not): named by the hash of its resolved path
    in this user's lock folder under the system's temporary directory, so claiming an output creates
    nothing in or beside it (a refused command leaves no trace) and ``out=x`` and ``out=./x`` are one output."""
    import hashlib
    import tempfile

    folder = Path(tempfile.gettempdir()) / f"pasta-locks-{os.getuid()}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
    except FileExistsError:
        pass
    st = os.lstat(folder)
    if not os.path.isdir(folder) or os.path.islink(folder) or st.st_uid != os.getuid():
        raise InputError(f"{folder} is not a private folder of this user (a link, or someone else's); pasta keeps its "
                         "output locks there: remove it")
    digest = hashlib.sha256(os.path.realpath(output).encode("utf-8", "surrogateescape")).hexdigest()[:32]
    return folder / f"{digest}.lock"


class OutputLock:
    """Exclusive claim on an output for the life of this process (or until :meth:`release`).

    ``OutputLock(path, key).acquire()`` raises :class:`OutputBusyError` at once (no waiting) when another
    process holds it. Within one process the claim is re-entrant (``pasta pipeline`` holds its models root
    and calls the trainers, which claim their own folders in it). Use as a context manager, or keep it for
    the process's lifetime: the kernel drops the lock when the process ends, however it ends.
    """

    #: lock file (resolved) -> [fd, holders] of the claims this process holds
    _held: ClassVar[dict[str, list[int]]] = {}

    def __init__(self, output: str | os.PathLike[str], key: str = "out") -> None:
        self.output, self.key = Path(output), key
        self._path: Path | None = None

    def acquire(self) -> OutputLock:
        if self._path is not None:
            return self
        path = lock_path(self.output)
        held = self._held.get(str(path))
        if held is not None:
            held[1] += 1
        else:
            self._held[str(path)] = [self._claim(path), 1]
        self._path = path
        return self

    def _claim(self, path: Path) -> int:
        import fcntl

        while True:
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    raise InputError(f"{path} is a symbolic link; pasta does not write through links (remove it)") from None
                raise
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                os.close(fd)
                raise OutputBusyError(f"{self.key}={self.output} is in use by another pasta process{holder}; wait for "
                                      f"it to finish or choose another {self.key}=") from None
            # the previous holder may have removed the file between our open and our lock: lock the file that
            # is there now, not an unlinked one
            try:
                same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                return fd
            os.close(fd)

    def release(self) -> None:
        if self._path is None:
            return
        key, self._path = str(self._path), None
        held = self._held.get(key)
        if held is None:  # released by release_all()
            return
        held[1] -= 1
        if held[1] <= 0:
            self._drop(key)

    @classmethod
    def release_all(cls) -> None:
        """Release every claim of this process (the command line calls it when a command ends)."""
        for key in list(cls._held):
            cls._drop(key)

    @classmethod
    def _drop(cls, key: str) -> None:
        fd = cls._held.pop(key)[0]
        try:
            os.unlink(key)  # while still locked: a process that opened it meanwhile sees another inode and retries
        except FileNotFoundError:
            pass
        os.close(fd)

    def __enter__(self) -> OutputLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()


def _read_holder(fd: int) -> str:
    try:
        pid = os.pread(fd, 32, 0).decode().strip()
    except (OSError, UnicodeDecodeError):
        return ""
    return f" (pid {pid})" if pid.isdigit() else ""


@functools.cache
def _umask() -> int:
    """The process's umask, read once: reading it means setting it, and a file another thread created in
    between would get the temporary mask."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync_dir(directory: Path) -> None:
    """Make the rename durable (POSIX: the directory entry lives in the directory)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
