"""Where ``tcomp process`` writes: a rosbag2 MCAP bag or a CSV file, both streamed.

Bag topics: the input Temperature topics (from a bag input copied record for record, with the
channel id and the offered QoS they were recorded with; encoded from a CSV input),
:data:`GAS_TOPIC` (one ``sensor_msgs/msg/Temperature`` per reconstructed pair,
stamped and logged at that pair's stamp), :data:`HISTORY_TOPIC` (one
``diagnostic_msgs/msg/DiagnosticArray`` per re-estimation, status ``tcomp: process``, logged at
the newest stamp of the window) and :data:`DIAGNOSIS_TOPIC` (one DiagnosticArray with the
diagnosis verdict, logged at the last stamp). The derived topics, and inputs read from CSV,
are offered reliable, keep-last-10, volatile, as :func:`tcomp_core.io.write_bag` does.

CSV columns: ``time,tc1,tc2[,ref],gas,gas_variance,tau1,tau2``, one row per matched pair
(``time`` in seconds, ``sec + nanosec / 1e9`` of the stamp); ``gas`` is empty where no gas
sample was reconstructed (the first pair, a gap, before the first τ), ``gas_variance`` is its
variance in (degrees C)² as the gas messages carry it, ``tau1``/``tau2`` are the time constants
that reconstructed it.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..io import (
    GAS_TOPIC,
    TEMPERATURE_TYPE,
    DiagnosticStatusFields,
    McapBagWriter,
    TemperatureBatch,
    column,
    encode,
    encode_diagnostic_array,
    offered_qos,
)

__all__ = [
    "DIAGNOSIS_TOPIC",
    "HISTORY_TOPIC",
    "STATUS_NAME",
    "BagOutput",
    "CsvOutput",
]

HISTORY_TOPIC = "/diagnostics"
DIAGNOSIS_TOPIC = "/diagnosis"
STATUS_NAME = "tcomp: process"
DIAGNOSTIC_TYPE = "diagnostic_msgs/msg/DiagnosticArray"
_NS_PER_S = 1_000_000_000
#: Gas samples encoded and written at a time (about 0.3 MB of records).
GAS_BLOCK = 4096
#: Largest distance between a gas sample's stamp and its pair's for the CSV join, ns.
STAMP_TOLERANCE_NS = 512


class BagOutput:
    """Stream the results into a new rosbag2 MCAP bag.

    Parameters
    ----------
    path : Path
        Bag directory to create (cleared beforehand by the caller).
    input_topics : mapping of role to topic
        Topics of the copied inputs ('tc1', 'tc2' and optionally 'ref').
    compress : bool
        zstd-compress the chunks.
    hardware_id : str
        ``hardware_id`` of the diagnostic statuses.
    with_diagnosis : bool
        Offer the :data:`DIAGNOSIS_TOPIC` topic.
    name : str, optional
        Stem of the ``.mcap`` file (``path``'s name by default).
    """

    def __init__(
        self,
        path: Path,
        input_topics: Mapping[str, str],
        *,
        compress: bool = False,
        hardware_id: str = "thermocouple-pair",
        with_diagnosis: bool = True,
        name: str | None = None,
    ) -> None:
        self.path = path
        self._writer = McapBagWriter(path, compress=compress, name=name)
        self._input_topics = dict(input_topics)
        self._inputs: dict[str, int] = {}  # channels of the inputs, added as they appear
        # The derived topics get their channels on first use, after the inputs, so that the
        # inputs keep their channel ids and their records are copied unchanged.
        self._derived = {
            "gas": (GAS_TOPIC, TEMPERATURE_TYPE),
            "history": (HISTORY_TOPIC, DIAGNOSTIC_TYPE),
            **({"diagnosis": (DIAGNOSIS_TOPIC, DIAGNOSTIC_TYPE)} if with_diagnosis else {}),
        }
        self._derived_channels: dict[str, int] = {}
        self._hardware_id = hardware_id
        self.counts = {"gas": 0, "history": 0, "diagnosis": 0}
        self._gas: list[tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]] = []
        self._gas_frame = ""
        self._gas_size = 0

    def _channel(self, name: str) -> int:
        if name not in self._derived_channels:
            topic, msgtype = self._derived[name]
            self._derived_channels[name] = self._writer.add_channel(topic, msgtype, offered_qos())
        return self._derived_channels[name]

    def inputs(
        self,
        role: str,
        batch: TemperatureBatch,
        records: list[NDArray[np.uint8]] | None,
        qos_text: str | None = None,
    ) -> None:
        """Copy input messages: whole MCAP records when given, else encoded from ``batch``.

        ``qos_text`` is the input channel's ``offered_qos_profiles`` (kept as it is); without
        it the topic is offered as :func:`tcomp_core.io.write_bag` does.
        """
        if not len(batch) or role not in self._input_topics:
            return
        if role not in self._inputs:
            topic = self._input_topics[role]
            source_id = int(column(records[0], 9, "<u2")[0]) if records else None
            self._inputs[role] = self._writer.add_channel(
                topic, TEMPERATURE_TYPE, offered_qos(), channel_id=source_id, qos_text=qos_text
            )
        channel = self._inputs[role]
        if records is not None:
            for block in records:
                self._writer.write_records(channel, block)
        else:
            rows = encode(batch.stamps_ns, batch.temperature, batch.variance, batch.frame_id)
            self._writer.write_rows(channel, batch.stamps_ns, rows)

    def pairs(self, *_: Any) -> None:
        """Matched pairs are already in the copied inputs."""

    def gas(
        self,
        stamps_ns: NDArray[np.int64],
        gas: NDArray[np.float64],
        variance: NDArray[np.float64],
        tau: tuple[float, float] | None,
        frame_id: str,
        fed_to_ns: int | None = None,
    ) -> None:
        """Write reconstructed samples on :data:`GAS_TOPIC`.

        They are gathered into blocks of :data:`GAS_BLOCK` samples (one frame id each) and
        encoded and written block by block: per-call costs would dominate at 0.1 s batches.
        """
        del tau, fed_to_ns  # the τ history topic carries τ
        if not stamps_ns.size:
            return
        self._channel("gas")  # the channel ids follow the order the topics first appear in
        if self._gas and frame_id != self._gas_frame:
            self._flush_gas()
        self._gas.append((stamps_ns, gas, variance))
        self._gas_frame = frame_id
        self._gas_size += int(stamps_ns.size)
        self.counts["gas"] += int(stamps_ns.size)
        if self._gas_size >= GAS_BLOCK:
            self._flush_gas()

    def _flush_gas(self) -> None:
        if self._gas:
            stamps, gas, variance = (np.concatenate(part) for part in zip(*self._gas, strict=True))
            rows = encode(stamps, gas, variance, self._gas_frame)
            self._writer.write_rows(self._channel("gas"), stamps, rows)
            self._gas, self._gas_size = [], 0

    def _status_array(
        self, stamp_ns: int, level: int, message: str, values: Mapping[str, str]
    ) -> bytes:
        status = DiagnosticStatusFields(
            level=int(level),
            name=STATUS_NAME,
            message=message,
            hardware_id=self._hardware_id,
            values={key: str(value) for key, value in values.items()},
        )
        return encode_diagnostic_array(int(stamp_ns), [status])

    def report(self, stamp_ns: int, level: int, message: str, values: Mapping[str, str]) -> None:
        """Write one ``/diagnostics`` status (an entry of the τ history)."""
        data = self._status_array(stamp_ns, level, message, values)
        self._writer.write_message(self._channel("history"), int(stamp_ns), data)
        self.counts["history"] += 1

    def diagnosis(
        self, stamp_ns: int, level: int, message: str, values: Mapping[str, str]
    ) -> None:
        """Write the diagnosis verdict."""
        data = self._status_array(stamp_ns, level, message, values)
        self._writer.write_message(self._channel("diagnosis"), int(stamp_ns), data)
        self.counts["diagnosis"] += 1

    def close(self) -> None:
        """Finish the bag (summary, footer, ``metadata.yaml``); topics left empty included."""
        self._flush_gas()
        for name in self._derived:
            self._channel(name)
        self._writer.close()

    def abort(self) -> None:
        """Leave an unfinished bag (no ``metadata.yaml``)."""
        self._writer.abort()


class CsvOutput:
    """Stream matched pairs and their gas samples as CSV rows.

    A row is written once its gas sample is known or can no longer come: the compensator
    returns gas samples in increasing stamp order, so every pair up to the newest gas stamp
    is settled, and a pair more than ``keep_rows`` rows behind the newest one it was given can
    only have been dropped from its backlog.

    Parameters
    ----------
    path : Path
        CSV file to create (cleared beforehand by the caller).
    with_ref : bool
        Write a ``ref`` column.
    """

    def __init__(self, path: Path, *, with_ref: bool) -> None:
        self.path = path
        self._handle = path.open("w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._handle, lineterminator="\n")
        self._with_ref = with_ref
        header = [
            "time",
            "tc1",
            "tc2",
            *(["ref"] if with_ref else []),
            "gas",
            "gas_variance",
            "tau1",
            "tau2",
        ]
        self._writer.writerow(header)
        # columns tc1, tc2, ref, gas, its variance, τ1, τ2
        self._rows: list[NDArray[np.float64]] = []
        self._stamps: list[NDArray[np.int64]] = []
        self.keep_rows = 1 << 20
        self.counts = {"rows": 0, "gas": 0}

    def inputs(self, *_: Any) -> None:
        """Inputs appear as the pairs' columns."""

    def report(self, *_: Any) -> None:
        """The τ history is in the tau columns."""

    def diagnosis(self, *_: Any) -> None:
        """The verdict goes to the summary only."""

    def pairs(
        self,
        stamps_ns: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        ref: NDArray[np.float64],
    ) -> None:
        """Queue matched pairs (stamps in ns, degrees C)."""
        if stamps_ns.size:
            nan = np.full(stamps_ns.size, np.nan)
            self._rows.append(np.column_stack((tc1, tc2, ref, nan, nan, nan, nan)))
            self._stamps.append(stamps_ns)

    def gas(
        self,
        stamps_ns: NDArray[np.int64],
        gas: NDArray[np.float64],
        variance: NDArray[np.float64],
        tau: tuple[float, float] | None,
        frame_id: str,
        fed_to_ns: int | None = None,
    ) -> None:
        """Fill the gas and τ columns of queued pairs and write the settled rows.

        ``fed_to_ns`` is the newest stamp given to the compensator so far.
        """
        del frame_id
        stamps, rows = self._queued()
        if stamps.size:
            # The nearest queued stamp: the compensator passes the stamps of the pairs it
            # learns the sample period from through float64 (exact only to 256 ns at epoch
            # times), so an exact match would miss them.
            after = np.clip(np.searchsorted(stamps, stamps_ns), 0, stamps.size - 1)
            before = np.maximum(after - 1, 0)
            at = np.where(
                np.abs(stamps[after] - stamps_ns) < np.abs(stamps_ns - stamps[before]),
                after,
                before,
            )
            hit = np.abs(stamps[at] - stamps_ns) <= STAMP_TOLERANCE_NS
            rows[at[hit], 3] = gas[hit]
            rows[at[hit], 4] = variance[hit]
            if tau is not None:
                rows[at[hit], 5], rows[at[hit], 6] = tau
            self.counts["gas"] += int(hit.sum())
        self._flush(int(stamps_ns[-1]) if stamps_ns.size else None, fed_to_ns)

    def _queued(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        if len(self._rows) > 1:
            self._rows = [np.concatenate(self._rows)]
            self._stamps = [np.concatenate(self._stamps)]
        if not self._rows:
            return np.empty(0, np.int64), np.empty((0, 7))
        return self._stamps[0], self._rows[0]

    def _flush(
        self, settle_to: int | None, fed_to: int | None = None, everything: bool = False
    ) -> None:
        stamps, rows = self._queued()
        if stamps.size == 0:
            return
        count = stamps.size if everything else 0
        if settle_to is not None:
            count = max(count, int(np.searchsorted(stamps, settle_to, side="right")))
        if fed_to is not None:
            fed = int(np.searchsorted(stamps, fed_to, side="right"))
            count = max(count, fed - self.keep_rows)
        if count <= 0:
            return
        self._write(stamps[:count], rows[:count])
        self._rows, self._stamps = [rows[count:]], [stamps[count:]]

    def _write(self, stamps: NDArray[np.int64], rows: NDArray[np.float64]) -> None:
        seconds, nanoseconds = np.divmod(stamps, _NS_PER_S)
        time = seconds.astype(np.float64) + nanoseconds / _NS_PER_S
        keep = [0, 1, 2, 3, 4, 5, 6] if self._with_ref else [0, 1, 3, 4, 5, 6]
        columns = [time, *(rows[:, k] for k in keep)]
        self._writer.writerows(
            [("" if isinstance(v, float) and math.isnan(v) else v) for v in row]
            for row in zip(*(c.tolist() for c in columns), strict=True)
        )
        self.counts["rows"] += int(stamps.size)

    def close(self) -> None:
        """Write the remaining rows and close the file."""
        self._flush(None, everything=True)
        self._handle.close()

    def abort(self) -> None:
        """Close the file as it is."""
        self._handle.close()
