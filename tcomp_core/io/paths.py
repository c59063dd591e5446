"""The one place that tells a CSV file from a bag, finds a bag's files and clears an output.

A path is CSV when it ends in ``.csv``; a bag when it is a directory holding ``metadata.yaml``
(rosbag2), an ``.mcap`` file (inside a bag directory: the whole bag; bare: that file alone), a
file starting with the MCAP magic bytes, or a path that does not exist yet (outputs).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ..errors import DataError

__all__ = [
    "MCAP_MAGIC",
    "bag_files",
    "bag_location",
    "check_readable_format",
    "clear_for_writing",
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


def check_readable_format(path: Path) -> None:
    """Refuse an existing non-CSV, non-``.mcap`` file that does not start like an MCAP file.

    Raises
    ------
    DataError
        Naming the file; also when it cannot be opened.
    """
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
    from ruamel.yaml import YAML

    try:
        info = YAML(typ="safe").load((location / "metadata.yaml").read_text("utf8"))
        info = info["rosbag2_bagfile_information"]
        names = list(info["relative_file_paths"])
        storage = str(info.get("storage_identifier", "mcap"))
    except Exception as exc:  # ruamel raises many types; a bad metadata.yaml is a data error
        raise DataError(f"{location}/metadata.yaml: cannot read the file list: {exc}") from exc
    if storage != "mcap":
        raise DataError(
            f"{location}: storage {storage!r}; only rosbag2 MCAP bags are read (convert with "
            "'ros2 bag convert' or 'rosbags-convert')"
        )
    files = [location / name for name in names]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise DataError(f"{location}: metadata.yaml lists missing files: {', '.join(missing)}")
    if not files:
        raise DataError(f"{location}/metadata.yaml lists no files")
    return files


def clear_for_writing(path: Path, overwrite: bool, *, bag: bool) -> None:
    """Refuse an existing output unless ``overwrite``; then remove it.

    Parameters
    ----------
    path : Path
        The output about to be written.
    overwrite : bool
        Replace an existing output.
    bag : bool
        The output is a bag: an existing bag directory (or an empty directory) may be replaced.

    Raises
    ------
    DataError
        The output exists and ``overwrite`` is False, or it is a directory that is not a bag.
    """
    if not (path.exists() or path.is_symlink()):
        return
    if not overwrite:
        raise DataError(f"{path} exists; pass overwrite (--force) to replace it")
    if path.is_dir() and not path.is_symlink():
        if not bag or not (is_bag_directory(path) or not any(path.iterdir())):
            raise DataError(
                f"{path} is a directory that is not a rosbag2 bag; refusing to replace it"
            )
        shutil.rmtree(path)
    else:
        path.unlink()
