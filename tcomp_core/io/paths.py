"""The one place that tells a CSV file from a bag, finds a bag's files and checks an input.

Inputs must be regular files (a FIFO or a device would block or never end) and a bag's
``metadata.yaml`` may only name files inside its directory. Outputs: :mod:`.outputs`.

A path is CSV when it ends in ``.csv``; a bag when it is a directory holding ``metadata.yaml``
(rosbag2), an ``.mcap`` file (inside a bag directory: the whole bag; bare: that file alone), a
file starting with the MCAP magic bytes, or a path that does not exist yet (outputs).
"""

from __future__ import annotations

import stat
from pathlib import Path
from typing import Any

from ..errors import DataError

__all__ = [
    "MCAP_MAGIC",
    "bag_files",
    "bag_location",
    "bag_topic_names",
    "check_readable_format",
    "check_regular_file",
    "is_bag_directory",
    "is_csv",
    "is_data_file",
]

#: The first bytes of every MCAP file.
MCAP_MAGIC = b"\x89MCAP0\r\n"


def is_csv(path: Path) -> bool:
    """True for a ``*.csv`` path (any case); every other path is treated as a bag."""
    return path.suffix.lower() == ".csv"


def is_bag_directory(path: Path) -> bool:
    """True for a rosbag2 bag directory (one holding ``metadata.yaml``)."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def is_data_file(path: Path) -> bool:
    """True for an input a directory of inputs may hold: a bag directory, ``.mcap``, ``.csv``."""
    return is_bag_directory(path) or (path.is_file() and path.suffix.lower() in (".mcap", ".csv"))


#: Largest ``metadata.yaml`` read, bytes (real ones are a few kB).
MAX_METADATA_BYTES = 16 * 2**20


def check_regular_file(path: Path) -> Path:
    """Refuse anything but a regular file: a FIFO or device would block or never end.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    DataError
        Naming the path: not a regular file, missing, unreadable, or a symlink loop.
    """
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        raise DataError(f"{path}: cannot open: {exc.strerror or exc}") from exc
    except (RuntimeError, ValueError) as exc:  # a symlink loop, a NUL byte in the name
        raise DataError(f"{path}: cannot open: {exc}") from exc
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO"
            if stat.S_ISFIFO(mode)
            else "a device"
            if stat.S_ISCHR(mode) or (stat.S_ISBLK(mode))
            else "a directory"
            if stat.S_ISDIR(mode)
            else "not a regular file"
        )
        raise DataError(f"{path}: {kind}, not a data file; refusing to read it")
    return path


def check_readable_format(path: Path) -> None:
    """Refuse an existing non-CSV, non-``.mcap`` file that does not start like an MCAP file.

    Raises
    ------
    DataError
        Naming the file; also when it cannot be opened.
    """
    if path.exists() and not path.is_dir():
        check_regular_file(path)
    if is_csv(path) or not path.is_file() or path.suffix.lower() == ".mcap":
        return
    try:
        with path.open("rb") as handle:
            magic = handle.read(5)
    except OSError as exc:
        raise DataError(f"{path}: cannot open: {exc.strerror}") from exc
    if magic != MCAP_MAGIC[:5]:
        raise DataError(
            f"{path}: cannot tell the format: expected a .csv file, a rosbag2 bag directory "
            "or an .mcap file"
        )


def bag_location(path: Path) -> Path:
    """The bag to read: a bag directory, or a bare ``.mcap`` file.

    The ``.mcap`` file of a bag directory stands for the whole bag (all its files).

    Raises
    ------
    DataError
        A missing path, or a directory without ``metadata.yaml``.
    """
    if not path.exists():
        raise DataError(f"{path}: no such bag (neither a bag directory nor an .mcap file)")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            mcaps = sorted(item.name for item in path.glob("*.mcap"))
            hint = f"; to read a bare MCAP file, pass it: {', '.join(mcaps)}" if mcaps else ""
            raise DataError(f"{path}: not a rosbag2 bag: the directory has no metadata.yaml{hint}")
        return path
    if path.suffix.lower() == ".mcap" and (path.parent / "metadata.yaml").is_file():
        return path.parent
    return path


def _resolve(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # a symlink loop, a NUL byte
        raise DataError(f"{path}: cannot resolve the path: {exc}") from exc


def _load_yaml(text: str) -> Any:
    """The data of a YAML document, by PyYAML's safe loader (libyaml's parser where built).

    Every bag read parses its ``metadata.yaml``: ruamel.yaml's pure-Python safe loader took
    14 ms of a 15 ms read of a small bag, libyaml 1 ms. Both give plain Python objects; libyaml
    reads YAML 1.1 (``yes`` and ``on`` unquoted are booleans there, which a rosbag2 writer
    never leaves unquoted where a name goes) and keeps the last of duplicated keys.
    """
    import yaml

    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def _bag_information(location: Path, wanted: str) -> dict:
    """``rosbag2_bagfile_information`` of a bag directory's ``metadata.yaml``.

    ``wanted`` (e.g. "the file list") names what was read it for, in the error.

    Raises
    ------
    DataError
        A file too large to be one, or one that cannot be parsed.
    """
    metadata = check_regular_file(location / "metadata.yaml")
    if metadata.stat().st_size > MAX_METADATA_BYTES:
        raise DataError(
            f"{metadata}: {metadata.stat().st_size} bytes; not a rosbag2 metadata file"
        )
    try:
        info = _load_yaml(metadata.read_text("utf8"))["rosbag2_bagfile_information"]
    except Exception as exc:  # the parser raises many types; a bad metadata.yaml is a data error
        raise DataError(f"{metadata}: cannot read {wanted}: {exc}") from exc
    if not isinstance(info, dict):
        raise DataError(f"{metadata}: rosbag2_bagfile_information is not a mapping")
    return info


def bag_topic_names(path: Path, msgtype: str = "sensor_msgs/msg/Temperature") -> list[str]:
    """The topics of type ``msgtype`` a bag directory's ``metadata.yaml`` lists (no data read).

    Raises
    ------
    DataError
        As :func:`bag_location`; an unreadable ``metadata.yaml``.
    """
    location = bag_location(path)
    if location.is_file():
        raise DataError(f"{location}: a bare MCAP file lists no topics without being read")
    entries = _bag_information(location, "the topic list").get("topics_with_message_count") or []
    names = []
    for entry in entries if isinstance(entries, list) else []:
        topic = entry.get("topic_metadata", {}) if isinstance(entry, dict) else {}
        if isinstance(topic, dict) and topic.get("type") == msgtype:
            names.append(str(topic.get("name", "")))
    return [name for name in names if name]


def bag_files(path: Path) -> list[Path]:
    """The MCAP files of a bag directory (from ``metadata.yaml``) or a bare MCAP file.

    Parameters
    ----------
    path : Path
        Bag directory, the ``.mcap`` file of one, or a bare ``.mcap`` file.

    Returns
    -------
    list of Path
        In the order ``metadata.yaml`` lists them.

    Raises
    ------
    DataError
        See :func:`bag_location`; an unreadable ``metadata.yaml``, a storage other than MCAP,
        a listed file that is missing.
    """
    location = bag_location(path)
    if location.is_file():
        return [location]
    metadata = location / "metadata.yaml"
    info = _bag_information(location, "the file list")
    try:
        names = info["relative_file_paths"]
        storage = str(info.get("storage_identifier", "mcap"))
    except Exception as exc:  # a bad metadata.yaml is a data error, whatever it raises
        raise DataError(f"{metadata}: cannot read the file list: {exc}") from exc
    if not isinstance(names, list) or not all(
        isinstance(name, str) and name and "\x00" not in name for name in names
    ):
        raise DataError(
            f"{metadata}: relative_file_paths must be a list of file names, got {names!r:.80}"
        )
    inside = location.resolve()
    for name in names:
        target = location / name
        if Path(name).is_absolute() or not _resolve(target).is_relative_to(inside):
            raise DataError(
                f"{metadata}: relative_file_paths names {name!r}, outside the bag directory; "
                "refusing to read it"
            )
    if storage != "mcap":
        raise DataError(
            f"{location}: storage {storage!r}; only rosbag2 MCAP bags are read (convert with "
            "'ros2 bag convert' or 'rosbags-convert')"
        )
    files = [location / name for name in names]
    missing = [str(f) for f in files if not f.exists()]
    if missing:
        raise DataError(f"{location}: metadata.yaml lists missing files: {', '.join(missing)}")
    for file in files:
        check_regular_file(file)
    if not files:
        raise DataError(f"{location}/metadata.yaml lists no files")
    return files
