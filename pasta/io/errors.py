"""Errors raised when a run file cannot be read."""

from __future__ import annotations

from pasta.core.errors import PastaError


class McapFormatError(PastaError):
    """The file is not a readable MCAP run file (bad magic, corrupt record, CRC mismatch).

    The message always names the file. A :class:`pasta.core.errors.PastaError`, so the CLI prints it
    as a one-line error.
    """


class McapTruncatedError(McapFormatError):
    """The file ends before the MCAP footer: the writer never finished (killed process, full disk,
    partial copy). Open it with ``RunReader(path, recover=True)`` or ``pasta replay --recover`` to get
    every message of the complete chunks before the cut."""
