"""A record in windows of a chosen length, streamed from its file in bounded memory.

``tcomp diagnose`` on a long recording: :class:`WindowReader` reads a bag chunk by chunk
(:class:`~tcomp_core.io.stream.BagStream`, the reader of ``tcomp process``) or a CSV file
:data:`~tcomp_core.io.csvfile.CSV_CHUNK_ROWS` rows at a time
(:class:`~tcomp_core.io.csvfile.CsvChunks`, the parser of :func:`~tcomp_core.io.read_csv`) and
hands over one :class:`Window` per stretch of ``window_s`` seconds of sample time, counted from
the first sample. It holds at most a window, the samples that arrived ahead of it (a chunk, and
for a bag :data:`LATE_S` of stamps, since log order need not be stamp order) and nothing else,
whatever the length of the record (:attr:`WindowReader.peak_held` counts it).

Each window's record is built as the whole file's would be (:func:`~tcomp_core.io.bag.
paired_record`, :meth:`~tcomp_core.io.csvfile.CsvChunks.record`): the same pairing of stamps,
the same screening of invalid readings and repeated samples (:mod:`.screening`), the same check
of a uniform rate. A window that fails one of them carries the one-line message as its
:attr:`Window.problem` and the others carry on; the warnings of a window (readings left out and
bridged) are its :attr:`Window.notes`.

Without a window length the choice is automatic: a record of at most :data:`WHOLE_SAMPLES`
samples is handed over whole (one window, exactly the record :func:`~tcomp_core.io.read_record`
reads, errors and warnings raised as it raises them); a longer one in windows of
:data:`WINDOW_SAMPLES` samples, rounded down to whole seconds (60 s at 5 kHz).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, InvalidReadingsWarning, TruncatedInputWarning
from .bag import paired_record
from .csvfile import CSV_CHUNK_ROWS, CsvChunks
from .paths import check_readable_format, is_csv
from .record import DEFAULT_COLUMNS, DEFAULT_TOPICS, NS_PER_S, Record, check_names
from .stream import BagStream
from .temperature import TemperatureBatch

__all__ = ["LATE_S", "WHOLE_SAMPLES", "WINDOW_SAMPLES", "Window", "WindowReader"]

#: A record of more samples than this is diagnosed in windows unless a length is chosen: the
#: whole-record diagnosis holds about 1.5 kB per sample (4.7 GB for 3 M samples), so this
#: keeps it under 1 GB.
WHOLE_SAMPLES = 600_000
#: Samples of an automatic window (rounded down to whole seconds): 60 s at 5 kHz.
WINDOW_SAMPLES = 300_000
#: A bag's window is closed once every topic has reached this far beyond its end (seconds of
#: stamp time): a recorder logs a message when it arrives, a little after its stamp.
LATE_S = 1.0


@dataclass(frozen=True)
class Window:
    """One stretch of a record.

    Attributes
    ----------
    index : int
        0, 1, ... in time order.
    start_s : float
        Start, seconds from the record's first sample.
    length_s : float
        The window's length, seconds (a gap's length for a window that is a gap).
    samples : int
        tc1 samples read in the window (before screening).
    record : Record or None
        The window's record (times as read); None when it has a problem.
    problem : str
        Why there is no record: the reader's one-line message ('' when there is one).
    notes : tuple of str
        Warnings raised while building it (readings left out or bridged).
    """

    index: int
    start_s: float
    length_s: float
    samples: int
    record: Record | None
    problem: str = ""
    notes: tuple[str, ...] = ()


class _Held:
    """The samples of one series read but not yet handed over, in read order.

    ``keys`` are stamps (ns) or times (s), shape (n,) per part read; ``values`` the columns,
    shape (n, m); ``newest`` the largest key read so far.
    """

    def __init__(self) -> None:
        self.keys: list[NDArray[Any]] = []
        self.values: list[NDArray[np.float64]] = []
        self.count = 0
        self.newest = -math.inf

    def add(self, keys: NDArray[Any], values: NDArray[np.float64]) -> None:
        if keys.size:
            self.keys.append(keys)
            self.values.append(values)
            self.count += keys.size
            self.newest = max(self.newest, float(keys.max()))

    def oldest(self) -> float:
        return min((float(keys.min()) for keys in self.keys), default=math.inf)

    def take(self, end: float, *, prefix: bool) -> tuple[NDArray[Any], NDArray[np.float64]]:
        """Remove and return the samples before ``end`` (their leading run if ``prefix``)."""
        taken: list[tuple[NDArray[Any], NDArray[np.float64]]] = []
        kept: list[tuple[NDArray[Any], NDArray[np.float64]]] = []
        stopped = False
        for keys, values in zip(self.keys, self.values, strict=True):
            if stopped:
                kept.append((keys, values))
                continue
            if prefix:
                after = keys >= end
                count = int(np.argmax(after)) if after.any() else keys.size
                before = np.arange(keys.size) < count
                stopped = count < keys.size
            else:
                before = keys < end
            taken.append((keys[before], values[before]))
            if not before.all():
                kept.append((keys[~before], values[~before]))
        self.keys = [keys for keys, _ in kept]
        self.values = [values for _, values in kept]
        self.count = sum(keys.size for keys in self.keys)
        if not taken:
            return np.empty(0), np.empty((0, 1))
        return (
            np.concatenate([keys for keys, _ in taken]),
            np.concatenate([values for _, values in taken]),
        )


class WindowReader:
    """A bag or CSV record handed over in windows, read as it streams (see the module).

    Parameters
    ----------
    path : str or Path
        CSV file or MCAP bag.
    window_s : float or None
        Window length, seconds of sample time; ``math.inf`` for the whole record in one
        window; None to choose (:data:`WHOLE_SAMPLES`, :data:`WINDOW_SAMPLES`).
    topics, columns : (tc1, tc2[, ref or None]), optional
        As :func:`~tcomp_core.io.read_record`.
    whole_samples, window_samples : int
        The automatic choice's limits.
    csv_rows : int
        Rows of a CSV file parsed at a time.

    Attributes
    ----------
    whole : bool
        The record is handed over whole (known once the first window is).
    automatic : bool
        The window length was chosen here (known once the first window is).
    peak_held : int
        The most samples of one series held at once, for the bound on memory.
    fraction : float
        The share of the input read so far, 0..1.
    samples_read : int
        tc1 samples (CSV rows) read so far.
    late : int
        A bag's samples left out because they came after their window was handed over
        (stamped more than :data:`LATE_S` before the newest of every topic; warned at the end).

    Raises
    ------
    DataError
        While iterating: as the readers raise it on the file as a whole (a corrupt chunk, a
        missing topic, a malformed row); in windows, a window's own problems become its
        :attr:`Window.problem` instead. On creation: a window length that is not > 0.
    """

    def __init__(
        self,
        path: str | Path,
        window_s: float | None = None,
        *,
        topics: Sequence[str | None] | None = None,
        columns: Sequence[str | None] | None = None,
        whole_samples: int = WHOLE_SAMPLES,
        window_samples: int = WINDOW_SAMPLES,
        csv_rows: int = CSV_CHUNK_ROWS,
    ) -> None:
        if window_s is not None and not window_s > 0.0:
            raise DataError(f"window length {window_s!r} s must be > 0")
        self.path = Path(path)
        self.window_s = window_s
        self.whole = window_s is not None and math.isinf(window_s)
        self.automatic = window_s is None
        self.whole_samples = whole_samples
        self.window_samples = window_samples
        self.peak_held = 0
        self.fraction = 0.0
        self.samples_read = 0
        self.late = 0
        self._csv: CsvChunks | None = None
        self._bag: BagStream | None = None
        self._frame_id = ""
        self._ref_required = False
        if is_csv(self.path):
            self._csv = CsvChunks(
                self.path,
                columns=check_names(columns, DEFAULT_COLUMNS, "columns"),
                rows=csv_rows,
            )
            self.roles: tuple[str, ...] = ("rows",)
        else:
            check_readable_format(self.path)
            tc1, tc2, ref = check_names(topics, DEFAULT_TOPICS, "topics")
            # As read_bag: the default reference topic is read when present, another must exist.
            self._ref_required = ref is not None and ref != DEFAULT_TOPICS[2]
            self._bag = BagStream(
                self.path, {"tc1": tc1, "tc2": tc2, **({"ref": ref} if ref else {})}
            )
            self.roles = tuple(self._bag.topics)
        self._held = {role: _Held() for role in self.roles}
        self._unit = 1.0 if self._csv is not None else float(NS_PER_S)

    def _parts(self) -> Iterator[None]:
        """Read the input a block at a time into the held series."""
        if self._csv is not None:
            chunks = self._csv
            for first, arrays in chunks:
                rows = np.arange(first, first + arrays[0].size, dtype=np.float64)
                self._held["rows"].add(arrays[0], np.column_stack([*arrays, rows]))
                self.samples_read += arrays[0].size
                self.fraction = chunks.bytes_read / max(chunks.bytes_total, 1)
                yield
        elif self._bag is not None:
            for block in self._bag:
                for role, batch in block.series.items():
                    if role == "tc1" and not self._frame_id:
                        self._frame_id = batch.frame_id
                    self._held[role].add(batch.stamps_ns, batch.temperature[:, None])
                self.samples_read += len(block.series["tc1"]) if "tc1" in block.series else 0
                self.fraction = block.fraction
                yield

    def __iter__(self) -> Iterator[Window]:
        first = self._held[self.roles[0]]
        origin: float | None = None
        index = 0
        start = 0.0  # of the next window, key units after the origin
        for _ in self._parts():
            self.peak_held = max(self.peak_held, *(h.count for h in self._held.values()))
            if origin is None and first.count:
                origin = first.oldest()
            if origin is None or self.whole:
                continue
            if self.window_s is None:
                if first.count <= self.whole_samples:
                    continue
                self.window_s = self._automatic_length()
            width = self.window_s * self._unit
            while self._closed(origin + start + width):
                window, start = self._next(index, origin, start, width, None)
                index += 1
                yield window
        truncation = None
        if self._bag is not None:
            self._bag.check_topics()
            truncation = self._bag.truncation
            ref = self._bag.topics.get("ref")
            if self._ref_required and ref not in self._bag.scan.types:
                listed = self._bag.scan.listed_topics() or "no topics"
                raise DataError(f"{self.path}: no topic {ref}; the bag has {listed}")
        if truncation is not None:
            warnings.warn(str(truncation), TruncatedInputWarning, stacklevel=2)
        # Nothing read (origin None) is refused as the whole file's reader refuses it.
        if self.window_s is None or self.whole or origin is None:
            self.whole = True
            self.window_s = math.inf
            record = self._record(math.inf, truncated=truncation is not None)
            yield Window(0, 0.0, math.inf, record.time.size, record)
            return
        width = self.window_s * self._unit
        while any(h.count for h in self._held.values()):
            window, start = self._next(index, origin, start, width, truncation)
            index += 1
            yield window
        if self.late:
            warnings.warn(
                f"{self.path}: left out {self.late} sample(s) stamped more than {LATE_S:g} s "
                "before the newest of every topic, after their window was diagnosed",
                InvalidReadingsWarning,
                stacklevel=2,
            )

    def _automatic_length(self) -> float:
        """Whole seconds holding about ``window_samples`` samples at the record's rate."""
        keys = np.sort(np.concatenate(self._held[self.roles[0]].keys))
        dt = float(np.median(np.diff(keys))) / self._unit if keys.size > 1 else 1.0
        return float(max(1.0, math.floor(self.window_samples * dt)))

    def _closed(self, end: float) -> bool:
        """Whether every series read has reached ``end`` (a bag's: plus :data:`LATE_S`)."""
        late = 0.0 if self._csv is not None else LATE_S * self._unit
        return all(h.newest >= end + late for h in self._held.values() if h.newest > -math.inf)

    def _next(
        self, index: int, origin: float, start: float, width: float, truncation: object
    ) -> tuple[Window, float]:
        """The window from ``start`` (or the gap up to the next sample) and the next start.

        ``truncation`` is the bag's :class:`~tcomp_core.io.mcap_read.Truncation` once the
        input has ended (None before, or when it ended cleanly).
        """
        if self._bag is not None:  # a sample stamped before a window handed over is late
            for held in self._held.values():
                self.late += held.take(origin + start, prefix=False)[0].size
        oldest = min(held.oldest() for held in self._held.values())
        if math.isfinite(oldest) and oldest >= origin + start + width:
            skip = math.floor((oldest - origin - start) / width) * width
            gap = Window(
                index,
                start / self._unit,
                skip / self._unit,
                0,
                None,
                f"no samples for {skip / self._unit:g} s (a gap in the record)",
            )
            return gap, start + skip
        end = origin + start + width
        first = self._held[self.roles[0]]
        before = first.count
        problem, record = "", None
        last = not any(h.newest >= end for h in self._held.values())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                record = self._record(end, truncated=last and truncation is not None)
            except (DataError, ValueError) as exc:
                problem = " ".join(str(exc).split())
        notes = tuple(" ".join(str(w.message).split()) for w in caught)
        window = Window(
            index,
            start / self._unit,
            width / self._unit,
            before - first.count,
            record,
            problem,
            notes,
        )
        return window, start + width

    def _record(self, end: float, *, truncated: bool) -> Record:
        """The record of the held samples before ``end``, built as the whole file's is.

        Raises
        ------
        DataError
            As the whole file's reader raises it; a topic without samples there.
        """
        if self._csv is not None:
            _, values = self._held["rows"].take(end, prefix=True)
            if not values.shape[0]:
                raise DataError(f"{self.path}: no rows here")
            columns = [values[:, k] for k in range(values.shape[1] - 1)]
            return self._csv.record(int(values[0, -1]), columns)
        bag = cast(BagStream, self._bag)  # one of the two is set on creation
        found: dict[str, TemperatureBatch] = {}
        for role, topic in bag.topics.items():
            keys, values = self._held[role].take(end, prefix=False)
            if role == "ref" and topic not in bag.scan.types:
                continue
            if not keys.size and self.whole:  # as read_bag says it
                listed = bag.scan.listed_topics()
                raise DataError(
                    f"{self.path}: topic {topic} has no messages; the bag has {listed}"
                )
            if not keys.size:
                raise DataError(f"{self.path}: topic {topic} has no messages in this window")
            found[topic] = TemperatureBatch(
                keys.astype(np.int64), values[:, 0], np.zeros(keys.size), self._frame_id
            )
        files = tuple(bag.scan.files)
        return paired_record(self.path, list(found), found, files, truncated=truncated)
