"""MCAP files record by record: a read-ahead thread, chunk decompression and CRC-32.

:func:`raw_records` yields each top-level record of a file (its head, its body read no further
than the end of the file and, for a complete chunk, the decompressed records and their CRC-32 or
the failure); :func:`read_ahead` runs such an iterator on a thread a few records ahead: file
reads, zstd/lz4 decompression and ``zlib.crc32`` release the GIL, so on two cores the next chunks
are read while the current one is decoded. The record layout is the MCAP specification's
(https://mcap.dev/spec).
"""

from __future__ import annotations

import queue
import struct
import threading
import zlib
from collections.abc import Iterator
from typing import Any, BinaryIO

from ..errors import DataError

__all__ = [
    "CHUNK",
    "HEAD",
    "READ_AHEAD",
    "RawRecord",
    "chunk_length_error",
    "decompress",
    "raw_records",
    "read_ahead",
    "read_string",
    "unpack_chunk",
]

#: Opcode of a Chunk record.
CHUNK = 0x06
#: Opcode and length in front of every record.
HEAD = struct.Struct("<BQ")


def read_string(body: bytes | memoryview, at: int) -> tuple[str, int]:
    """The MCAP string (uint32 length, UTF-8 bytes) at byte ``at``, and the offset after it."""
    (length,) = struct.unpack_from("<I", body, at)
    at += 4
    return bytes(body[at : at + length]).decode(errors="replace"), at + length


def decompress(data: bytes, compression: str, size: int, partial: bool) -> bytes:
    """Decompress a chunk; with ``partial`` whatever a cut-off stream yields."""
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        if partial:
            return zstandard.ZstdDecompressor().decompressobj().decompress(data)
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        if partial:
            return lz4.frame.LZ4FrameDecompressor().decompress(data)
        return lz4.frame.decompress(data)
    raise DataError(f"unsupported MCAP chunk compression {compression!r}")


#: Records read (and chunks decompressed) ahead of the one being split, on a thread.
READ_AHEAD = 8


def unpack_chunk(body: bytes, partial: bool = False) -> tuple[bytes, int]:
    """The records of a chunk record's body, decompressed, and their CRC-32 (0: not checked).

    The CRC is computed only when the chunk declares one. Raises what the codec raises.
    """
    _, _, raw_size, crc = struct.unpack_from("<QQQI", body, 0)
    compression, at = read_string(body, 28)
    (compressed_size,) = struct.unpack_from("<Q", body, at)
    raw = decompress(body[at + 8 : at + 8 + compressed_size], compression, raw_size, partial)
    return raw, (zlib.crc32(raw) if crc and not partial else 0)


def chunk_length_error(body: bytes, length: int) -> str | None:
    """Why a chunk record's length disagrees with its own fields (None if it agrees).

    ``body`` may be cut short; the check needs only the chunk's header fields.
    """
    try:
        compression, at = read_string(body, 28)
        (compressed_size,) = struct.unpack_from("<Q", body, at)
    except struct.error:
        return None  # too little of the record to judge
    expected = at + 8 + compressed_size
    if expected != length:
        return (
            f"its record length is {length} bytes but its header and {compressed_size} "
            f"compressed bytes ({compression or 'uncompressed'}) take {expected}"
        )
    return None


RawRecord = tuple[bytes, bytes, "tuple[bytes, int] | Exception | None"]


def raw_records(handle: BinaryIO, size: int) -> Iterator[RawRecord]:
    """Head, body and (for a whole chunk) the decompressed records or the failure, in order.

    ``size`` is the file's size: a body is read no further than the end of the file (a
    corrupt length must not allocate what it says). The last item has a head shorter than a
    record head (the end of the file).
    """
    position = handle.tell()
    while True:
        head = handle.read(HEAD.size)
        if len(head) < HEAD.size:
            yield head, b"", None
            return
        opcode, length = HEAD.unpack(head)
        body = handle.read(min(length, max(size - position - HEAD.size, 0)))
        position += HEAD.size + len(body)
        unpacked: tuple[bytes, int] | Exception | None = None
        if opcode == CHUNK and len(body) == length:
            try:
                unpacked = unpack_chunk(body)
            except Exception as exc:  # judged by the reader, in order, like any other record
                unpacked = exc
        yield head, body, unpacked


def read_ahead(items: Iterator[RawRecord], depth: int) -> Iterator[RawRecord]:
    """Run ``items`` on a thread, at most ``depth`` items ahead of the consumer.

    File reads and zstd/lz4 decompression release the GIL, so on two cores the next chunks are
    read and decompressed while the current one is decoded. Closing this generator early
    stops the thread.
    """
    ahead: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                while not stop.is_set():
                    try:
                        ahead.put(("item", item), timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            ahead.put(("end", None))
        except BaseException as exc:  # handed to the consumer, raised there
            ahead.put(("error", exc))

    thread = threading.Thread(target=produce, name="mcap-read-ahead", daemon=True)
    thread.start()
    try:
        while True:
            kind, value = ahead.get()
            if kind == "end":
                return
            if kind == "error":
                raise value
            yield value
    finally:
        stop.set()
        thread.join()
