"""Data I/O: the one record type, CSV files, rosbag2 MCAP bags and the Temperature CDR codec.

CSV: a header ``time,tc1,tc2`` (seconds, degrees C) and optionally ``ref`` (a fast reference
sensor or the true gas temperature); further columns are allowed and ignored on reading. Bags:
rosbag2 version 9 with MCAP storage, holding ``sensor_msgs/msg/Temperature`` on
``/tc1/temperature``, ``/tc2/temperature`` and optionally ``/tref/temperature``. A sample's time
is its ``header.stamp`` (not the log time).

Every verb, ``tcomp process``, the replay node and the compensator node read and write through
this package, so they accept and refuse the same files with the same one-line messages. Every
error is a :class:`~tcomp_core.errors.DataError` naming the file, the column or topic, the
sample (or the chunk and byte offset) and the value; a cut-off bag is read up to its last
complete record with a :class:`~tcomp_core.errors.TruncatedInputWarning`, and invalid readings
are left out with an :class:`~tcomp_core.errors.InvalidReadingsWarning`.

Modules, one job each: :mod:`.record` (record type, names, stamps), :mod:`.paths` (CSV or bag,
a bag's files, clearing an output), :mod:`.csvfile`, :mod:`.temperature` (the CDR codec),
:mod:`.mcap_records` (records, read-ahead thread, decompression, CRC), :mod:`.mcap_read`
(chunk-wise scanner), :mod:`.mcap_write` (chunk writer), :mod:`.bag`,
:mod:`.stream` (chunk-by-chunk input of ``tcomp process``), :mod:`.windows` (a long record
in windows streamed from its file, for ``tcomp diagnose``), :mod:`.screening` (invalid
readings and repeated times left out, the one boundary of both readers), :mod:`.qos`,
:mod:`.dispatch`, :mod:`.diagnostics` (the ``DiagnosticArray`` encoder of the bags
``tcomp process`` writes).
"""

from __future__ import annotations

from .bag import read_bag, read_topics, write_bag, write_bag_copy
from .csvfile import read_csv, write_csv
from .diagnostics import DiagnosticStatusFields, encode_diagnostic_array
from .dispatch import read_record, write_series
from .mcap_read import ChunkData, McapScan, Truncation, log_times, payloads
from .mcap_write import McapBagWriter
from .outputs import atomic_output, check_output, overlaps
from .paths import (
    bag_files,
    bag_location,
    is_bag_directory,
    is_csv,
    is_data_file,
)
from .qos import offered_qos
from .record import (
    DEFAULT_COLUMNS,
    DEFAULT_TOPICS,
    GAS_TOPIC,
    NS_PER_S,
    TEMPERATURE_TYPE,
    BagOrigin,
    Record,
    check_names,
    format_stamp,
    seconds_to_ns,
    stamps_to_seconds,
)
from .rows import column
from .stream import BagStream, Block, CsvStream, open_stream
from .temperature import (
    Encoder,
    TemperatureBatch,
    decode_message,
    decode_payloads,
    decode_rows,
    encode,
    encode_message,
)

__all__ = [
    "DEFAULT_COLUMNS",
    "DEFAULT_TOPICS",
    "GAS_TOPIC",
    "NS_PER_S",
    "TEMPERATURE_TYPE",
    "BagOrigin",
    "BagStream",
    "Block",
    "ChunkData",
    "CsvStream",
    "DiagnosticStatusFields",
    "Encoder",
    "McapBagWriter",
    "McapScan",
    "Record",
    "TemperatureBatch",
    "Truncation",
    "atomic_output",
    "bag_files",
    "bag_location",
    "check_names",
    "check_output",
    "column",
    "decode_message",
    "decode_payloads",
    "decode_rows",
    "encode",
    "encode_diagnostic_array",
    "encode_message",
    "format_stamp",
    "is_bag_directory",
    "is_csv",
    "is_data_file",
    "log_times",
    "offered_qos",
    "open_stream",
    "overlaps",
    "payloads",
    "read_bag",
    "read_csv",
    "read_record",
    "read_topics",
    "seconds_to_ns",
    "stamps_to_seconds",
    "write_bag",
    "write_bag_copy",
    "write_csv",
    "write_series",
]
