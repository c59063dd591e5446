"""Fast rosbag2 (version 9) MCAP writer: chunks built from numpy arrays of message records.

The file has the layout rosbags writes (and ``ros2 bag``, Foxglove, PlotJuggler, the ``mcap``
and ``rosbags`` readers read): header (profile ``ros2``); schema and channel records before the
first chunk that uses them (``ros2msg`` definitions, ``offered_qos_profiles`` channel metadata);
chunks, each followed by one MessageIndex per channel; a ``rosbag2`` metadata record; DataEnd;
the summary (schemas, channels, chunk indexes, metadata index, statistics, summary offsets) and
the footer. ``metadata.yaml`` is written last, so a bag without it was not finished.

Messages arrive as blocks (one row per message, of one size); a chunk is the list of its
blocks, written one after another with no joining copy, and its message indexes are numpy
arrays. Compression and the file writes run on one background thread, in submission order
(:class:`_OrderedSink`): zstd and the ``write`` system call release the GIL, so on two cores
they overlap with the decoding and estimation of the next chunks. Each chunk carries the
CRC-32 of its records; a zstd chunk is one frame that declares its content size (readers such
as pybag-sdk need it).
"""

from __future__ import annotations

import struct
import zlib
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .mcap_read import MAGIC, MESSAGE_PREFIX
from .qos import qos_from_text, qos_yaml
from .rows import column

__all__ = ["CHUNK_BYTES", "McapBagWriter"]

#: Uncompressed size at which a chunk is closed, bytes.
CHUNK_BYTES = 4 << 20
#: Chunks queued for the background writer before :meth:`McapBagWriter.flush` waits.
QUEUED_CHUNKS = 4
_MAX_TIME = 2**64 - 1


@cache  # one per payload size, reused by every block of that size
def _record_dtype(payload: int) -> np.dtype:
    """A Message record whose serialized message has ``payload`` bytes (packed, no padding)."""
    return np.dtype(
        [
            ("opcode", "u1"),
            ("length", "<u8"),
            ("channel", "<u2"),
            ("sequence", "<u4"),
            ("log_time", "<u8"),
            ("publish_time", "<u8"),
            ("payload", f"V{payload}"),
        ]
    )


def _string(text: str | bytes) -> bytes:
    data = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(data)) + data


def _record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


class _OrderedSink:
    """Run write jobs on one background thread, in the order they were submitted.

    At most ``depth`` jobs wait at a time (bounded memory); an exception raised by a job is
    raised again by the next :meth:`submit` or by :meth:`drain`.
    """

    def __init__(self, depth: int) -> None:
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mcap-writer")
        self._pending: deque[Future[None]] = deque()
        self._depth = depth

    def submit(self, job: Callable[[], None]) -> None:
        while self._pending and (self._pending[0].done() or len(self._pending) >= self._depth):
            self._pending.popleft().result()
        self._pending.append(self._executor.submit(job))

    def drain(self) -> None:
        """Wait for every job; raise the first failure."""
        try:
            while self._pending:
                self._pending.popleft().result()
        finally:
            self._pending.clear()

    def shutdown(self) -> None:
        """Stop the thread after the jobs already queued (failures are dropped)."""
        self._executor.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()


@dataclass
class _Channel:
    id: int
    topic: str
    msgtype: str
    schema_id: int
    qos_text: str
    qos: Any
    digest: str
    count: int = 0
    written: bool = False


@dataclass
class _ChunkIndex:
    start: int
    end: int
    offset: int
    length: int
    index_offsets: dict[int, int]
    index_length: int
    compressed: int
    uncompressed: int


class McapBagWriter:
    """Write a rosbag2 MCAP bag directory block by block.

    Parameters
    ----------
    path : Path
        Bag directory to create (must not exist); the file inside is ``<name>.mcap``.
    compress : bool
        zstd-compress the chunks (level 1).
    chunk_bytes : int
        Uncompressed size at which a chunk is closed.
    name : str, optional
        Stem of the ``.mcap`` file (the directory's name by default; a bag written under a
        temporary name and renamed later passes its final name).

    Notes
    -----
    Blocks handed to :meth:`write_rows` and :meth:`write_records` are kept by reference until
    their chunk is written: the caller must not change them afterwards.
    """

    def __init__(
        self,
        path: Path,
        *,
        compress: bool = False,
        chunk_bytes: int = CHUNK_BYTES,
        name: str | None = None,
    ):
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._compression = "zstd" if compress else ""
        self._compressor = None
        if compress:
            import zstandard

            self._compressor = zstandard.ZstdCompressor(level=1)
        self._chunk_bytes = chunk_bytes
        self.path.mkdir(parents=True)
        self.file = self.path / f"{name or self.path.name}.mcap"
        self._handle = self.file.open("xb", buffering=0)
        self._sink = _OrderedSink(QUEUED_CHUNKS)
        self._schemas: dict[str, tuple[int, str]] = {}  # msgtype -> (id, definition)
        self._channels: dict[int, _Channel] = {}
        self._chunks: list[_ChunkIndex] = []  # appended by the writer thread
        self._blocks: list[tuple[int, NDArray[np.uint8]]] = []
        self._pending_bytes = 0
        self._start = _MAX_TIME
        self._end = 0
        self._write(MAGIC + _record(0x01, _string("ros2") + _string("tcomp")))

    def _write(self, data: bytes) -> None:
        self._sink.submit(lambda: self._write_all(data))

    def _write_all(self, data: bytes | memoryview | NDArray[np.generic]) -> None:
        """Write everything (the raw file may write less than asked per call)."""
        view = memoryview(data if isinstance(data, bytes | memoryview) else data.data).cast("B")
        while view:
            view = view[self._handle.write(view) :]

    @property
    def message_count(self) -> int:
        """Messages written so far (all channels)."""
        return sum(channel.count for channel in self._channels.values())

    def add_channel(
        self,
        topic: str,
        msgtype: str,
        qos: Sequence[Any] = (),
        *,
        channel_id: int | None = None,
        qos_text: str | None = None,
    ) -> int:
        """Register a topic; returns its channel id for :meth:`write_rows` and friends.

        Parameters
        ----------
        topic, msgtype : str
        qos : sequence of rosbags QoS profiles
            The offered QoS, stored as rosbag2 does.
        channel_id : int, optional
            The id to use if it is free (records copied with that id need no rewriting);
            otherwise the next free one.
        qos_text : str, optional
            An ``offered_qos_profiles`` string to store as it is (copied from an input bag),
            in place of ``qos``.
        """
        if msgtype not in self._schemas:
            definition, _ = self._typestore.generate_msgdef(msgtype, ros_version=2)
            self._schemas[msgtype] = (len(self._schemas) + 1, definition)
        if qos_text is None:
            qos_text, qos_profiles = qos_yaml(qos)
        else:
            qos_profiles = qos_from_text(qos_text)
        if channel_id is None or channel_id in self._channels or not 0 < channel_id < 2**16:
            channel_id = max(self._channels, default=0) + 1
        self._channels[channel_id] = _Channel(
            id=channel_id,
            topic=topic,
            msgtype=msgtype,
            schema_id=self._schemas[msgtype][0],
            qos_text=qos_text,
            qos=qos_profiles,
            digest=self._typestore.hash_rihs01(msgtype),
        )
        return channel_id

    def _schema_record(self, msgtype: str) -> bytes:
        schema_id, definition = self._schemas[msgtype]
        return _record(
            0x03,
            struct.pack("<H", schema_id)
            + _string(msgtype)
            + _string("ros2msg")
            + _string(definition),
        )

    def _channel_record(self, channel: _Channel) -> bytes:
        metadata = _string("offered_qos_profiles") + _string(channel.qos_text)
        return _record(
            0x04,
            struct.pack("<HH", channel.id, channel.schema_id)
            + _string(channel.topic)
            + _string("cdr")
            + struct.pack("<I", len(metadata))
            + metadata,
        )

    # -- messages ----------------------------------------------------------------------------
    def write_rows(
        self, channel_id: int, log_times: NDArray[np.int64], rows: NDArray[np.uint8]
    ) -> None:
        """Write serialized messages of one size, one per row of ``rows`` (N, L)."""
        count, size = rows.shape
        if count == 0:
            return
        records = np.empty(count, _record_dtype(size))
        records["opcode"] = 0x05
        records["length"] = MESSAGE_PREFIX - 9 + size
        records["channel"] = channel_id
        records["sequence"] = 0
        records["log_time"] = log_times
        records["publish_time"] = log_times
        records["payload"] = np.ascontiguousarray(rows).view(f"V{size}").ravel()
        self._add(channel_id, records.view(np.uint8).reshape(count, MESSAGE_PREFIX + size))

    def write_records(self, channel_id: int, records: NDArray[np.uint8]) -> None:
        """Copy whole message records (N, R) read from another file onto ``channel_id``.

        Records that already carry ``channel_id`` are kept as they are (no copy).
        """
        if records.shape[0] == 0:
            return
        if not np.all(column(records, 9, "<u2") == channel_id):
            records = np.array(records, copy=True)
            records[:, 9:11] = np.frombuffer(struct.pack("<H", channel_id), np.uint8)
        self._add(channel_id, np.ascontiguousarray(records))

    def write_message(self, channel_id: int, log_time: int, data: bytes) -> None:
        """Write one serialized message."""
        self.write_rows(
            channel_id,
            np.array([log_time], np.int64),
            np.frombuffer(data, np.uint8)[None, :],
        )

    def _add(self, channel_id: int, records: NDArray[np.uint8]) -> None:
        channel = self._channels[channel_id]
        if not channel.written:
            if all(not c.written for c in self._channels.values() if c.msgtype == channel.msgtype):
                self._write(self._schema_record(channel.msgtype))
            self._write(self._channel_record(channel))
            channel.written = True
        channel.count += records.shape[0]
        if self._blocks and self._pending_bytes + records.size > self._chunk_bytes:
            self.flush()  # chunks stay within chunk_bytes unless one block is larger
        self._blocks.append((channel_id, records))
        self._pending_bytes += records.size
        if self._pending_bytes >= self._chunk_bytes:
            self.flush()

    def flush(self) -> None:
        """Close the current chunk (if it holds anything) and queue it with its indexes."""
        if not self._blocks:
            return
        blocks = [block for _, block in self._blocks]
        entries: dict[int, list[NDArray[np.uint64]]] = {}
        start, end, at = _MAX_TIME, 0, 0
        for channel_id, block in self._blocks:
            count, size = block.shape
            times = column(block, 15, "<u8")
            offsets = at + np.arange(count, dtype=np.uint64) * np.uint64(size)
            entries.setdefault(channel_id, []).append(np.column_stack((times, offsets)))
            start, end = min(start, int(times.min())), max(end, int(times.max()))
            at += block.size
        self._blocks, self._pending_bytes = [], 0
        indexes = []
        for channel_id, parts in entries.items():
            table = np.concatenate(parts)
            if np.any(np.diff(table[:, 0].view(np.int64)) < 0):
                table = table[np.argsort(table[:, 0], kind="stable")]
            indexes.append((channel_id, table.astype("<u8", copy=False)))
        self._start, self._end = min(self._start, start), max(self._end, end)
        self._sink.submit(lambda: self._write_chunk(blocks, indexes, start, end, at))

    def _write_chunk(
        self,
        blocks: list[NDArray[np.uint8]],
        indexes: list[tuple[int, NDArray[np.uint64]]],
        start: int,
        end: int,
        size: int,
    ) -> None:
        """On the writer thread: the chunk record, then one MessageIndex per channel."""
        crc = 0
        for block in blocks:
            crc = zlib.crc32(block.data, crc)
        if self._compressor is not None:
            # One frame pledged to ``size`` bytes: the frame header declares its content size.
            stream = self._compressor.compressobj(size=size)
            parts = [stream.compress(block.data) for block in blocks] + [stream.flush()]
            blocks = [np.frombuffer(b"".join(parts), np.uint8)]
        compressed = sum(block.size for block in blocks)
        head = struct.pack("<QQQI", start, end, size, crc) + _string(self._compression)
        head += struct.pack("<Q", compressed)
        chunk_offset = self._handle.tell()
        self._write_all(struct.pack("<BQ", 0x06, len(head) + compressed) + head)
        for block in blocks:
            self._write_all(block)
        chunk_length = self._handle.tell() - chunk_offset
        index_offsets: dict[int, int] = {}
        for channel_id, table in indexes:
            index_offsets[channel_id] = self._handle.tell()
            payload = struct.pack("<HI", channel_id, table.nbytes)
            self._write_all(struct.pack("<BQ", 0x07, len(payload) + table.nbytes) + payload)
            self._write_all(table)
        self._chunks.append(
            _ChunkIndex(
                start=start,
                end=end,
                offset=chunk_offset,
                length=chunk_length,
                index_offsets=index_offsets,
                index_length=self._handle.tell() - chunk_offset - chunk_length,
                compressed=compressed,
                uncompressed=size,
            )
        )

    # -- closing -----------------------------------------------------------------------------
    def _ordered_channels(self) -> list[_Channel]:
        return [self._channels[channel_id] for channel_id in sorted(self._channels)]

    def _bag_information(self) -> dict[str, Any]:
        count = self.message_count
        start = self._start if count else 0
        duration = max(0, self._end - start) if count else 0
        return {
            "version": 9,
            "storage_identifier": "mcap",
            "relative_file_paths": [self.file.name],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": channel.topic,
                        "type": channel.msgtype,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": channel.qos,
                        "type_description_hash": channel.digest,
                    },
                    "message_count": channel.count,
                }
                for channel in self._ordered_channels()
            ],
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {
                    "path": self.file.name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
            ],
            "custom_data": None,
            "ros_distro": "rosbags",
        }

    def close(self) -> Path:
        """Write the last chunk, the summary, the footer and ``metadata.yaml``."""
        from ruamel.yaml import YAML

        self.flush()
        try:
            self._sink.drain()
        finally:
            self._sink.shutdown()
        yaml = YAML(typ="safe")
        yaml.default_flow_style = False
        information = self._bag_information()
        stream = StringIO()
        yaml.dump(information, stream)
        handle = self._handle
        metadata_start = handle.tell()
        inner = _string("serialized_metadata") + _string(stream.getvalue().strip())
        self._write_all(_record(0x0C, _string("rosbag2") + struct.pack("<I", len(inner)) + inner))
        metadata_end = handle.tell()
        self._write_all(_record(0x0F, struct.pack("<I", 0)))
        sections: list[tuple[int, int, int]] = []  # (opcode, start, length)

        def section(opcode: int, records: Sequence[bytes]) -> None:
            if records:
                begin = handle.tell()
                self._write_all(b"".join(records))
                sections.append((opcode, begin, handle.tell() - begin))

        summary_start = handle.tell()
        section(0x03, [self._schema_record(msgtype) for msgtype in self._schemas])
        section(
            0x04,
            [self._channel_record(channel) for channel in self._ordered_channels()],
        )
        section(0x08, [self._chunk_index_record(chunk) for chunk in self._chunks])
        section(
            0x0D,
            [
                _record(
                    0x0D,
                    struct.pack("<QQ", metadata_start, metadata_end - metadata_start)
                    + _string("rosbag2"),
                )
            ],
        )
        section(0x0B, [self._statistics_record()])
        offsets_start = handle.tell()
        for opcode, begin, length in sections:
            self._write_all(_record(0x0E, struct.pack("<BQQ", opcode, begin, length)))
        self._write_all(
            _record(0x02, struct.pack("<QQI", summary_start, offsets_start, 0)) + MAGIC
        )
        handle.close()
        stream = StringIO()
        yaml.dump({"rosbag2_bagfile_information": information}, stream)
        temporary = self.path / "metadata.yaml.tmp"
        temporary.write_text(stream.getvalue(), "utf8")
        temporary.replace(self.path / "metadata.yaml")
        return self.path

    def abort(self) -> None:
        """Close the file without summary or ``metadata.yaml`` (the bag stays unfinished)."""
        self._sink.shutdown()
        if not self._handle.closed:
            self._handle.close()

    def _chunk_index_record(self, chunk: _ChunkIndex) -> bytes:
        offsets = b"".join(
            struct.pack("<HQ", channel_id, offset)
            for channel_id, offset in chunk.index_offsets.items()
        )
        return _record(
            0x08,
            struct.pack("<QQQQ", chunk.start, chunk.end, chunk.offset, chunk.length)
            + struct.pack("<I", len(offsets))
            + offsets
            + struct.pack("<Q", chunk.index_length)
            + _string(self._compression)
            + struct.pack("<QQ", chunk.compressed, chunk.uncompressed),
        )

    def _statistics_record(self) -> bytes:
        counts = b"".join(struct.pack("<HQ", c.id, c.count) for c in self._ordered_channels())
        count = self.message_count
        return _record(
            0x0B,
            struct.pack(
                "<QHIIIIQQ",
                count,
                len(self._schemas),
                len(self._channels),
                0,
                1,
                len(self._chunks),
                self._start if count else 0,
                self._end if count else 0,
            )
            + struct.pack("<I", len(counts))
            + counts,
        )
