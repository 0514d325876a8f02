"""Read a run file written by :class:`pasta.io.RunLogger`: :class:`RunReader`.

Checks done while reading (the ``mcap`` library alone skips some and reports truncation with
misleading errors, so they are done here):

- on open: MCAP magic at the start (else :class:`McapFormatError` "not an MCAP file"), footer magic
  at the end (else :class:`McapTruncatedError`, which points to ``recover=True`` / ``--recover``),
  and the summary CRC;
- every chunk's CRC when the chunk is read, every attachment's CRC when it is read;
- :meth:`RunReader.validate` reads the whole data section once and also checks its CRC.

With ``recover=True`` the file is streamed from the start and everything up to the first broken
or missing record is kept (in memory): all messages of the complete chunks before a cut.

:attr:`RunReader.status` tells a finished run (``complete``), one that raised (``failed``, with
:attr:`RunReader.error`) and one whose writer was killed (``truncated``, read with ``recover=True``; the
file is then usually still named ``FILE.partial``) apart.
"""

from __future__ import annotations

import io
import json
import os
import struct
import zlib
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import zstandard
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.summary import Summary
from mcap.well_known import MessageEncoding
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from pasta.io import schemas as S
from pasta.io.errors import McapFormatError, McapTruncatedError
from pasta.io.run_log import CONFIG_ATTACHMENT, RUN_METADATA, RUN_STATUS, partial_path

MAGIC = b"\x89MCAP0\r\n"
_FOOTER_LEN = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, summary_crc
_READ_ERRORS = (McapError, ValueError, struct.error, zstandard.ZstdError, EOFError, RuntimeError, KeyError)


class LoggedMessage(NamedTuple):
    topic: str
    t_ns: int
    value: Any


@dataclass(frozen=True)
class TopicInfo:
    topic: str
    schema_name: str
    schema_encoding: str
    message_encoding: str
    count: int


class RunReader:
    """Reader of one run file.

    ``RunReader(path)`` raises :class:`McapFormatError` when ``path`` is not MCAP or is corrupt and
    :class:`McapTruncatedError` when it was cut before its footer. ``RunReader(path, recover=True)``
    returns whatever complete chunks precede a cut; then ``complete`` is False and ``recover_error``
    says where reading stopped.

    Decoded values (``messages``): ``foxglove.PointCloud`` -> (N, 3) float32 array, or for entity
    clouds a list of (P_i, 3) float32 arrays; ``foxglove.SceneUpdate`` -> ``list[ToolPrimitive]``;
    ``foxglove.Log`` -> ``LogEntry``; JSON -> dict; other protobuf -> the protobuf message; anything
    else -> bytes. Messages come in the order they were written unless ``time_order=True``.
    """

    def __init__(self, path: str | os.PathLike[str], *, recover: bool = False) -> None:
        self.path = Path(path)
        self.recover = recover
        self.complete = True
        self.recover_error: str | None = None
        self._proto_decoders = ProtobufDecoderFactory()
        self._decoder_cache: dict[int, Any] = {}
        try:
            self._file = open(self.path, "rb")  # noqa: SIM115 - open for the reader's lifetime; close() closes it
        except OSError as e:
            hint = ""
            if not self.path.exists() and partial_path(self.path).exists():
                partial = partial_path(self.path)
                hint = (f"; {partial} exists: the run was killed or is still running. Read what it wrote "
                        f"with `pasta replay {partial} --recover`")
            raise McapFormatError(f"cannot open run file {self.path}: {e.strerror or e}{hint}") from e
        try:
            self._size = os.fstat(self._file.fileno()).st_size
            self._check_start()
            if recover:
                self._load_stream()
            else:
                self._open_indexed()
        except BaseException:
            self._file.close()
            raise

    # ---------------------------------------------------------------- opening

    def _check_start(self) -> None:
        if self._size == 0:
            raise McapFormatError(f"{self.path} is empty, not an MCAP run file")
        head = self._file.read(len(MAGIC))
        if head != MAGIC[: len(head)] or (len(head) < len(MAGIC) and self._size >= len(MAGIC)):
            raise McapFormatError(
                f"{self.path} is not an MCAP file (it does not start with the MCAP magic bytes)"
            )
        if len(head) < len(MAGIC):
            self._truncated("the file ends inside the MCAP magic bytes")

    def _truncated(self, why: str) -> None:
        raise McapTruncatedError(
            f"{self.path} is truncated: {why} (the writer did not finish, e.g. the process was killed "
            "or the copy is partial). Read the complete part with `pasta replay --recover "
            f"{self.path}` or RunReader(path, recover=True)."
        )

    @contextmanager
    def _errors(self, what: str) -> Iterator[None]:
        try:
            yield
        except McapFormatError:
            raise
        except CRCValidationError as e:
            raise McapFormatError(f"{self.path} is corrupt: {what}: {e}") from e
        except _READ_ERRORS as e:
            raise McapFormatError(f"{self.path} is corrupt or unreadable: {what}: {type(e).__name__}: {e}") from e

    def _tail_problem(self) -> tuple[str, str] | None:
        """What is wrong with the end of the file (footer, closing magic, summary CRC), as ``(kind, why)``
        with kind ``truncated`` (the file was cut: nothing after the last byte) or ``corrupt`` (the end is
        there but damaged, e.g. a flipped byte), or None when the end is sound."""
        if self._size < 2 * len(MAGIC) + _FOOTER_LEN:
            return "truncated", f"only {self._size} bytes, too short for an MCAP footer"
        self._file.seek(self._size - len(MAGIC) - _FOOTER_LEN)
        tail = self._file.read(_FOOTER_LEN + len(MAGIC))
        magic = tail[-len(MAGIC):]
        if magic != MAGIC:
            if sum(a != b for a, b in zip(magic, MAGIC)) <= 2:  # the closing magic is there, a byte or two off
                return "corrupt", "the closing MCAP magic bytes are damaged"
            return "truncated", "no MCAP footer at the end of the file"
        if tail[0] != 0x02 or struct.unpack("<Q", tail[1:9])[0] != 20:
            return "corrupt", "the footer record before the closing magic bytes is damaged"
        summary_start, _offsets_start, summary_crc = struct.unpack("<QQI", tail[9:_FOOTER_LEN])
        footer_pos = self._size - len(MAGIC) - _FOOTER_LEN
        if summary_start and summary_crc:
            if summary_start > footer_pos:
                return "corrupt", "the footer points past the end of the file"
            self._file.seek(summary_start)
            covered = self._file.read(footer_pos - summary_start) + tail[: _FOOTER_LEN - 4]
            if zlib.crc32(covered) != summary_crc:
                return "corrupt", "summary section CRC mismatch"
        return None

    def _open_indexed(self) -> None:
        problem = self._tail_problem()
        if problem is not None:
            kind, why = problem
            if kind == "truncated":
                self._truncated(why)
            raise McapFormatError(f"{self.path} is corrupt: {why}. Read the messages before the damage with "
                                  f"`pasta replay --recover {self.path}` or RunReader(path, recover=True).")
        self._file.seek(0)
        with self._errors("reading the summary"):
            self._reader = SeekingReader(self._file, validate_crcs=True, record_size_limit=max(self._size, 1024))
            self._header: Header | None = self._reader.get_header()
            summary = self._reader.get_summary()
        if summary is None:
            # No summary section (not written by RunLogger): fall back to one streamed pass.
            self._file.seek(0)
            self._load_stream(strict=True)
            return
        self._summary: Summary | None = summary
        self._schemas: dict[int, Schema] = dict(summary.schemas)
        self._channels: dict[int, Channel] = dict(summary.channels)
        stats = summary.statistics
        self._counts = dict(stats.channel_message_counts) if stats is not None else None
        self._stream_messages: list[Message] | None = None

    def _load_stream(self, strict: bool = False) -> None:
        """One sequential pass keeping every record up to the first failure (recover mode) or
        raising on it (``strict``)."""
        self._file.seek(0)
        self._summary = None
        self._header = None
        self._schemas = {}
        self._channels = {}
        self._stream_messages = []
        self._stream_attachments: list[Attachment] = []
        self._stream_metadata: list[Metadata] = []
        reader = StreamReader(self._file, validate_crcs=True, record_size_limit=max(self._size, 1024))
        self.complete = False
        whole = 0  # where the last complete record ends
        try:
            for record in reader.records:
                whole = self._file.tell()
                if isinstance(record, Header):
                    self._header = record
                elif isinstance(record, Schema):
                    self._schemas[record.id] = record
                elif isinstance(record, Channel):
                    self._channels[record.id] = record
                elif isinstance(record, Message):
                    self._stream_messages.append(record)
                elif isinstance(record, Attachment):
                    self._stream_attachments.append(record)
                elif isinstance(record, Metadata):
                    self._stream_metadata.append(record)
                elif isinstance(record, (DataEnd, Footer)):
                    self.complete = True
                    break
        except _READ_ERRORS as e:
            if strict:
                raise McapFormatError(f"{self.path} is corrupt: {type(e).__name__}: {e}") from e
            cut = type(e).__name__ == "EndOfFile"
            self.recover_error = "the file ends inside a record (it was cut)" if cut else f"{type(e).__name__}: {e}"
        if not self.complete and self.recover_error is None:
            self.recover_error = "file ended before the data-section end record"
        if not self.complete and whole < self._size:  # say what was left out: nothing past it is read
            self.recover_error = (f"{self.recover_error}; kept the records up to byte {whole}, skipped the last "
                                  f"{self._size - whole} bytes of {self._size}")
        elif self.complete and not strict:
            problem = self._tail_problem()  # the data section is whole: is what follows it (summary, footer)?
            if problem is not None:
                self.recover_error = (f"the data section is whole but the end of the file is damaged ({problem[1]}); "
                                      "skipped the summary and footer, read every message from the data section")
        counts: dict[int, int] = {}
        for m in self._stream_messages:
            counts[m.channel_id] = counts.get(m.channel_id, 0) + 1
        self._counts = counts

    # ---------------------------------------------------------------- lifecycle

    def close(self) -> None:
        self._file.close()

    def __del__(self) -> None:  # readers used without `with` must not leak file handles
        f = getattr(self, "_file", None)
        if f is not None:
            f.close()

    def __enter__(self) -> RunReader:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---------------------------------------------------------------- run status

    @property
    def status(self) -> str:
        """How the run ended: ``"complete"``; ``"failed"`` (it raised, see :attr:`error`); ``"truncated"``
        (the writer never finished, e.g. the process was killed; only readable with ``recover=True``);
        ``"unknown"`` (a finished file without a status record: older pasta or another writer)."""
        if not self.complete:
            return "truncated"
        value = self.metadata(RUN_STATUS).get("status")
        return value if value in ("complete", "failed") else "unknown"

    @property
    def error(self) -> str | None:
        """The error that ended a ``failed`` run (``"ExceptionType: message"``), else None."""
        return self.metadata(RUN_STATUS).get("error") if self.status == "failed" else None

    # ---------------------------------------------------------------- catalogue

    @property
    def library(self) -> str:
        """Writer library named in the MCAP header ("" if unknown)."""
        return self._header.library if self._header is not None else ""

    def topics(self) -> list[str]:
        """Topics in order of first registration."""
        return [c.topic for _, c in sorted(self._channels.items())]

    def topic_info(self) -> dict[str, TopicInfo]:
        out = {}
        for cid, ch in sorted(self._channels.items()):
            schema = self._schemas.get(ch.schema_id)
            out[ch.topic] = TopicInfo(
                topic=ch.topic,
                schema_name=schema.name if schema else "",
                schema_encoding=schema.encoding if schema else "",
                message_encoding=ch.message_encoding,
                count=int((self._counts or {}).get(cid, 0)),
            )
        return out

    def schema_names(self) -> list[str]:
        """Sorted names of every schema in the file (e.g. ``foxglove.PointCloud``)."""
        return sorted({s.name for s in self._schemas.values()})

    def count(self, topic: str) -> int:
        info = self.topic_info().get(topic)
        return info.count if info else 0

    def time_range(self) -> tuple[int, int] | None:
        """(first, last) log time in ns over all messages, None when there are none."""
        if self._summary is not None and self._summary.statistics is not None:
            st = self._summary.statistics
            return (st.message_start_time, st.message_end_time) if st.message_count else None
        times = [m.log_time for m in self._stream_messages or []]
        return (min(times), max(times)) if times else None

    # ---------------------------------------------------------------- messages

    def _raw(self, topics: Iterable[str] | None, time_order: bool) -> Iterator[tuple[Channel, Schema | None, Message]]:
        wanted = None if topics is None else set(topics)
        if self._stream_messages is not None:
            msgs = self._stream_messages
            if time_order:
                msgs = sorted(msgs, key=lambda m: m.log_time)  # stable: ties keep file order
            for m in msgs:
                ch = self._channels[m.channel_id]
                if wanted is None or ch.topic in wanted:
                    yield ch, self._schemas.get(ch.schema_id), m
            return
        if wanted is not None and not wanted & set(self.topics()):
            return
        it = self._reader.iter_messages(topics=None if wanted is None else sorted(wanted), log_time_order=time_order)
        while True:
            with self._errors("reading messages"):
                try:
                    schema, ch, m = next(it)
                except StopIteration:
                    return
            yield ch, schema, m

    def _decode(self, ch: Channel, schema: Schema | None, data: bytes) -> Any:
        enc = ch.message_encoding
        if enc == MessageEncoding.JSON:
            return json.loads(data)
        if enc == MessageEncoding.Protobuf and schema is not None:
            if schema.name == S.POINT_CLOUD_SCHEMA:
                pts, _colors, ids = S.decode_point_cloud(PointCloud.FromString(data))
                return pts if ids is None else S.split_entities(pts, ids)
            if schema.name == S.SCENE_UPDATE_SCHEMA:
                return S.decode_tools(SceneUpdate.FromString(data))
            if schema.name == S.LOG_SCHEMA:
                return S.decode_log(Log.FromString(data))
            dec = self._decoder_cache.get(schema.id)
            if dec is None:
                dec = self._proto_decoders.decoder_for(enc, schema)
                self._decoder_cache[schema.id] = dec
            if dec is not None:
                return dec(data)
        return bytes(data)

    def iter_messages(self, topics: Iterable[str] | str | None = None, *, time_order: bool = False) -> Iterator[LoggedMessage]:
        """Every message of ``topics`` (all when None) as ``LoggedMessage(topic, t_ns, value)``."""
        if isinstance(topics, str):
            topics = [topics]
        for ch, schema, m in self._raw(topics, time_order):
            with self._errors(f"decoding a message on {ch.topic}"):
                value = self._decode(ch, schema, m.data)
            yield LoggedMessage(ch.topic, m.log_time, value)

    def messages(self, topic: str, *, time_order: bool = False) -> Iterator[tuple[int, Any]]:
        """``(t_ns, value)`` for every message on ``topic`` (see the class doc for value types)."""
        for rec in self.iter_messages([topic], time_order=time_order):
            yield rec.t_ns, rec.value

    def point_clouds(self, topic: str) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        """``(t_ns, points (N, 3) float32, colors (N, 4) uint8 or None)`` for a point-cloud topic
        (entity clouds come back concatenated, with their palette colours)."""
        for _ch, schema, m in self._raw([topic], False):
            if schema is None or schema.name != S.POINT_CLOUD_SCHEMA:
                raise TypeError(f"{topic} carries {schema.name if schema else 'schemaless'} messages, not point clouds")
            with self._errors(f"decoding a point cloud on {topic}"):
                pts, colors, _ = S.decode_point_cloud(PointCloud.FromString(m.data))
            yield m.log_time, pts, colors

    def last(self, topic: str) -> tuple[int, Any] | None:
        """The last-written message on ``topic`` as ``(t_ns, value)``, None if there is none."""
        out = None
        for rec in self.messages(topic):
            out = rec
        return out

    # ---------------------------------------------------------------- attachments / metadata

    @property
    def _index(self) -> Summary:
        """The summary section of a file read through its index (not streamed)."""
        assert self._summary is not None  # _open_indexed sets it whenever _stream_messages is None
        return self._summary

    def attachment_names(self) -> list[str]:
        if self._stream_messages is not None:
            return [a.name for a in self._stream_attachments]
        return [a.name for a in self._index.attachment_indexes]

    def attachment(self, name: str) -> bytes:
        """Bytes of attachment ``name`` (CRC-checked); KeyError listing the names if absent."""
        if self._stream_messages is not None:
            for a in self._stream_attachments:
                if a.name == name:
                    return bytes(a.data)
        else:
            for idx in self._index.attachment_indexes:
                if idx.name == name:
                    return self._read_attachment(idx)
        raise KeyError(f"{self.path} has no attachment {name!r}; it has {self.attachment_names()}")

    def _read_attachment(self, idx: Any) -> bytes:
        with self._errors(f"reading attachment {idx.name!r}"):
            self._file.seek(idx.offset)
            raw = self._file.read(idx.length)
            if len(raw) != idx.length or raw[0] != 0x09:
                raise McapFormatError(f"{self.path} is corrupt: attachment {idx.name!r} index is wrong")
            stored = struct.unpack("<I", raw[-4:])[0]
            if stored and zlib.crc32(raw[9:-4]) != stored:
                raise McapFormatError(f"{self.path} is corrupt: attachment {idx.name!r} CRC mismatch")
            att = Attachment.read(ReadDataStream(io.BytesIO(raw[9:])))
        return bytes(att.data)

    def config(self) -> str | None:
        """The resolved config YAML (attachment ``config.yaml``), None if not logged."""
        try:
            return self.attachment(CONFIG_ATTACHMENT).decode("utf-8")
        except KeyError:
            return None

    def metadata_names(self) -> list[str]:
        if self._stream_messages is not None:
            return [m.name for m in self._stream_metadata]
        return [m.name for m in self._index.metadata_indexes]

    def metadata(self, name: str = RUN_METADATA) -> dict[str, str]:
        """Metadata record ``name`` (default: the run metadata passed to RunLogger); {} if absent."""
        if self._stream_messages is not None:
            for m in self._stream_metadata:
                if m.name == name:
                    return dict(m.metadata)
            return {}
        with self._errors("reading metadata"):
            for m in self._reader.iter_metadata():
                if m.name == name:
                    return dict(m.metadata)
        return {}

    # ---------------------------------------------------------------- full check

    def validate(self) -> int:
        """Stream the whole file checking every chunk CRC and the data-section CRC; returns the
        number of messages. Raises :class:`McapFormatError` on the first problem."""
        with open(self.path, "rb") as f:
            reader = StreamReader(f, validate_crcs=True, record_size_limit=max(self._size, 1024))
            n = 0
            with self._errors("validating"):
                for record in reader.records:
                    if isinstance(record, Message):
                        n += 1
                    elif isinstance(record, Footer):
                        break
        return n

