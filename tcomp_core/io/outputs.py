"""Writing outputs safely: never over an input, never over a file without leave, never half.

Every output of tcomp (CSV, bag directory, JSON, PNG, HTML report directory) goes through
:func:`atomic_output`: it is written under a hidden temporary name beside its target and renamed
into place once complete, so a run that fails or is killed half way leaves the previous output
(or nothing), and a rerun is never blocked by a partial one. :func:`check_output` refuses an
output that would replace or sit inside an input (or contain it), ``--force`` or not, and an
existing output without ``overwrite``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import DataError

__all__ = ["atomic_output", "check_output", "overlaps"]


def _resolved(path: Path) -> Path:
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # a symlink loop, a NUL byte
        raise DataError(f"{path}: cannot resolve the path: {exc}") from exc


def overlaps(output: Path, source: Path) -> bool:
    """Whether writing ``output`` could replace or change ``source`` (or the reverse).

    True when the two resolve to the same path, or one lies inside the other (a bag directory
    and its ``.mcap`` file, a directory of inputs and an output in it...).
    """
    out, src = _resolved(output), _resolved(source)
    return out == src or out.is_relative_to(src) or src.is_relative_to(out)


def check_output(
    path: Path, overwrite: bool, inputs: Iterable[Path] = (), *, directory: bool = False
) -> None:
    """Refuse an output that overlaps an input, or exists without ``overwrite``.

    Parameters
    ----------
    path : Path
        The output about to be written.
    overwrite : bool
        Replace an existing output (``--force``).
    inputs : iterable of Path
        The files and directories the run reads.
    directory : bool
        The output is a directory (a bag or a report): an existing one may be replaced only if
        it is empty or of that kind (``metadata.yaml`` or ``index.html`` inside).

    Raises
    ------
    DataError
        Naming the output and, for an overlap, the input.
    """
    path = Path(path)
    for source in inputs:
        if overlaps(path, Path(source)):
            raise DataError(
                f"{path}: the output would overwrite or sit inside the input {source} (or "
                "contain it); choose another output path"
            )
    if not (path.exists() or path.is_symlink()):
        return
    if not overwrite:
        raise DataError(f"{path} exists; pass --force (overwrite=True) to replace it")
    if path.is_dir() and not path.is_symlink():
        known = any((path / name).is_file() for name in ("metadata.yaml", "index.html"))
        if not directory or not (known or not any(path.iterdir())):
            raise DataError(
                f"{path} is a directory that is not a rosbag2 bag or a tcomp report; refusing "
                "to replace it"
            )
    elif directory and not path.is_symlink() and path.exists() and not path.is_dir():
        raise DataError(f"{path} is a file; the output is a directory")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


@contextlib.contextmanager
def atomic_output(
    path: Path, overwrite: bool = False, inputs: Iterable[Path] = (), *, directory: bool = False
) -> Iterator[Path]:
    """Write ``path`` through a temporary sibling, renamed into place when the block succeeds.

    Parameters
    ----------
    path : Path
        The output.
    overwrite, inputs, directory
        As :func:`check_output`, which runs first.

    Yields
    ------
    Path
        Where to write: a hidden name in the output's directory (not yet existing). A
        directory output keeps the final name for what it holds (pass ``path.name`` on).

    Raises
    ------
    DataError
        From :func:`check_output`; an OSError while writing or renaming names the output.
    """
    path = Path(path)
    inputs = list(inputs)
    check_output(path, overwrite, inputs, directory=directory)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"{path}: cannot create its directory: {exc.strerror}") from exc
    temporary = path.with_name(f".{path.name}.partial-{os.getpid()}")
    _remove(temporary)  # left by an earlier run of this process id
    try:
        yield temporary
        check_output(path, overwrite, inputs, directory=directory)  # still true after the run
        _remove(path)
        os.replace(temporary, path)
    except OSError as exc:
        _remove(temporary)
        raise DataError(f"{path}: cannot write: {exc.strerror or exc}") from exc
    except BaseException:
        _remove(temporary)
        raise
