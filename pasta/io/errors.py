"""Errors raised when a run file cannot be read."""

from __future__ import annotations


class McapFormatError(Exception):
    """The file is not a readable MCAP run file (bad magic, corrupt record, CRC mismatch).

    The message always names the file.
    """


class McapTruncatedError(McapFormatError):
    """The file ends before the MCAP footer: the writer never finished (killed process, full disk,
    partial copy). Open it with ``RunReader(path, recover=True)`` or ``pasta replay --recover`` to get
    every message of the complete chunks before the cut."""
