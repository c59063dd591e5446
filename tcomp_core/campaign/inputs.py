"""The recordings of a campaign: found under directories or by glob, each with its probe id.

A campaign input is a directory (walked recursively: every bag directory, ``.mcap`` and ``.csv``
file under it, a bag's own files not counted twice), a glob (``cells/*/day*.mcap``, ``**``
allowed) or one recording. Each recording gets a name unique in the campaign (its path relative
to the input, ``/`` written ``__``), under which its outputs are kept.

The probe a recording belongs to comes from a :class:`ProbeRule`:

* ``dir`` (default) or ``dir:N``: the name of the directory N levels above the recording
  (``cellA/probe3/day07.mcap`` → ``probe3`` for N = 1, ``cellA`` for N = 2);
* ``topic``: the namespace of the tc1 topic. A bag directory that holds several probes
  (``/probe1/tc1/temperature``, ``/probe2/tc1/temperature``, ...) is one recording per namespace
  whose topics end as ``--topics`` do (read from its ``metadata.yaml``, no data read);
* ``frame``: the ``header.frame_id`` of the first tc1 message (bags);
* ``map:FILE``: a CSV file of ``pattern,probe`` rows; the first pattern (a glob on the
  recording's path as found) that matches names the probe.
"""

from __future__ import annotations

import csv
import fnmatch
import glob
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..errors import DataError
from ..io.paths import is_bag_directory, is_data_file

__all__ = ["ProbeRule", "Recording", "find_recordings"]

#: Characters that make an input a glob rather than a path.
GLOB_CHARACTERS = frozenset("*?[")


@dataclass(frozen=True)
class Recording:
    """One recording of the campaign.

    Attributes
    ----------
    path : Path
        Bag directory, ``.mcap`` or ``.csv`` file.
    name : str
        Unique in the campaign, safe as a file name: outputs are kept under it.
    topics : (tc1, tc2, ref or None) or None
        The topics to read when the probe rule chose them (``topic`` on a bag holding several
        probes); None: the campaign's ``--topics``.
    probe : str
        The probe id when the rule could give it without reading data ('' otherwise: the
        worker finds it, :meth:`ProbeRule.probe`).
    """

    path: Path
    name: str
    topics: tuple[str, str, str | None] | None = None
    probe: str = ""


@dataclass(frozen=True)
class ProbeRule:
    """Where a recording's probe id comes from (see the module).

    Attributes
    ----------
    kind : {'dir', 'topic', 'frame', 'map'}
    level : int
        Directory levels above the recording (``dir``).
    mapping : tuple of (pattern, probe)
        ``map`` rows in file order.
    """

    kind: str = "dir"
    level: int = 1
    mapping: tuple[tuple[str, str], ...] = ()

    @classmethod
    def parse(cls, text: str) -> ProbeRule:
        """``dir``, ``dir:N``, ``topic``, ``frame`` or ``map:FILE``.

        Raises
        ------
        DataError
            On another text, a level that is not an integer ≥ 1, or a mapping file that
            cannot be read or holds a row without two fields.
        """
        kind, _, argument = text.partition(":")
        if kind == "dir":
            try:
                level = int(argument) if argument else 1
            except ValueError:
                level = 0
            if level < 1:
                raise DataError(f"--probe {text}: the level after dir: must be an integer >= 1")
            return cls("dir", level)
        if kind in ("topic", "frame") and not argument:
            return cls(kind)
        if kind == "map" and argument:
            return cls("map", mapping=_read_mapping(Path(argument)))
        raise DataError(f"--probe {text}: expected dir, dir:N, topic, frame or map:FILE")

    def probe(self, recording: Recording, tc1_topic: str | None, frame_id: str) -> str:
        """The probe id of ``recording`` read with ``tc1_topic`` (bags) and ``frame_id``.

        Raises
        ------
        DataError
            When the rule cannot name the probe (no directory that high, a topic without a
            namespace, a CSV file with ``frame``, no pattern matching), naming the recording.
        """
        if recording.probe:
            return recording.probe
        where = recording.path
        if self.kind == "dir":
            parents = recording.path.resolve().parents
            if self.level > len(parents) - 1:
                raise DataError(f"{where}: no directory {self.level} levels up for --probe dir")
            return parents[self.level - 1].name
        if self.kind == "topic":
            # /probe3/tc1/temperature → /probe3: the namespace above the sensor's own topic.
            topic = tc1_topic or ""
            probe = topic[: -len(_tail(topic))].rstrip("/") if topic else ""
            if not probe:
                raise DataError(f"{where}: topic {topic!r} has no namespace for --probe topic")
            return probe
        if self.kind == "frame":
            if not frame_id:
                raise DataError(f"{where}: no frame_id to name the probe (--probe frame)")
            return frame_id
        text = str(recording.path)
        for pattern, probe in self.mapping:
            if fnmatch.fnmatch(text, pattern) or fnmatch.fnmatch(recording.path.name, pattern):
                return probe
        raise DataError(f"{where}: no pattern of the --probe map file matches it")


def _read_mapping(path: Path) -> tuple[tuple[str, str], ...]:
    try:
        with path.open(newline="") as handle:
            rows = [row for row in csv.reader(handle) if row and not row[0].startswith("#")]
    except OSError as exc:
        raise DataError(f"{path}: cannot read the probe map: {exc.strerror}") from exc
    mapping = []
    for number, row in enumerate(rows, start=1):
        if len(row) != 2 or not row[0].strip() or not row[1].strip():
            raise DataError(f"{path}: row {number} is not 'pattern,probe': {row!r}")
        mapping.append((row[0].strip(), row[1].strip()))
    if not mapping:
        raise DataError(f"{path}: the probe map holds no 'pattern,probe' row")
    return tuple(mapping)


def _walk(directory: Path, exclude: Path | None) -> list[Path]:
    """Recordings under ``directory``: bag directories are not entered."""
    found: list[Path] = []
    exclude = exclude.resolve() if exclude is not None else None
    for root, dirs, files in os.walk(directory):
        here = Path(root)
        where = here.resolve()
        if exclude is not None and (where == exclude or exclude in where.parents):
            dirs[:] = []
            continue
        if is_bag_directory(here):
            found.append(here)
            dirs[:] = []
            continue
        dirs.sort()
        found += [here / f for f in sorted(files) if is_data_file(here / f)]
    return found


def _name(path: Path, root: Path) -> str:
    try:
        relative = path.resolve().relative_to(root.resolve())
    except ValueError:
        relative = Path(path.name)
    return "__".join(relative.parts) or path.name


def _glob_root(pattern: str) -> Path:
    """The directory part of ``pattern`` before its first glob character."""
    parts = Path(pattern).parts
    plain = []
    for part in parts:
        if GLOB_CHARACTERS & set(part):
            break
        plain.append(part)
    return Path(*plain) if plain else Path(".")


def find_recordings(
    inputs: Sequence[str | Path],
    *,
    rule: ProbeRule = ProbeRule(),
    tc_topics: tuple[str, str] | None = None,
    exclude: Path | None = None,
) -> list[Recording]:
    """Every recording of ``inputs`` (directories, globs or recordings), in a stable order.

    Parameters
    ----------
    inputs : sequence of str or Path
    rule : ProbeRule
        With ``topic``, a bag directory holding several probes becomes one recording each.
    tc_topics : (str, str), optional
        tc1 and tc2 topics whose last components name the sensors in each namespace (the
        default topics when None).
    exclude : Path, optional
        A directory not walked (the campaign's output when it lies among the inputs).

    Raises
    ------
    DataError
        An input that does not exist, a glob that matches nothing, nothing found at all, or
        two recordings that would get the same name.
    """
    from ..choices import DEFAULT_TOPICS

    tc1_topic, tc2_topic = tc_topics or (str(DEFAULT_TOPICS[0]), str(DEFAULT_TOPICS[1]))
    found: list[tuple[Path, Path]] = []
    for item in inputs:
        text = str(item)
        if GLOB_CHARACTERS & set(text):
            matches = [Path(m) for m in sorted(glob.glob(text, recursive=True))]
            matches = [m for m in matches if is_data_file(m)]
            if not matches:
                raise DataError(f"{text}: the pattern matches no bag, .mcap or .csv file")
            found += [(m, _glob_root(text)) for m in matches]
            continue
        path = Path(item)
        if not path.exists():
            raise DataError(f"{path}: no such file or directory")
        if path.is_dir() and not is_bag_directory(path):
            found += [(p, path) for p in _walk(path, exclude)]
        elif is_data_file(path):
            found.append((path, path.parent))
        else:
            raise DataError(f"{path}: not a bag directory, .mcap or .csv file")
    if not found:
        raise DataError(
            f"{', '.join(map(str, inputs))}: holds no bag directory, .mcap or .csv file"
        )
    # One recording reached from two inputs (a directory and a file in it) is one recording,
    # named from the first input that reached it.
    unique: dict[Path, tuple[Path, Path]] = {}
    for path, root in found:
        unique.setdefault(path.resolve(), (path, root))
    recordings: list[Recording] = []
    for path, root in unique.values():
        name = _name(path, root)
        if rule.kind == "topic" and is_bag_directory(path):
            recordings += _per_namespace(path, name, tc1_topic, tc2_topic)
        else:
            recordings.append(Recording(path, name))
    names = [r.name for r in recordings]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise DataError(f"two recordings would be kept under one name: {', '.join(twice)}")
    return recordings


def _per_namespace(path: Path, name: str, tc1_topic: str, tc2_topic: str) -> list[Recording]:
    """One recording per namespace of a bag holding tc1 and tc2 topics under several."""
    from ..io.paths import bag_topic_names

    topics = set(bag_topic_names(path))
    tails = [_tail(tc1_topic), _tail(tc2_topic)]
    namespaces = sorted(
        topic[: -len(tails[0])].rstrip("/")
        for topic in topics
        if topic.endswith(tails[0]) and topic[: -len(tails[0])] + tails[1] in topics
    )
    namespaces = [ns for ns in namespaces if ns]
    if not namespaces:
        return [Recording(path, name)]
    if len(namespaces) == 1:
        return [_one(path, name, namespaces[0], tails)]
    return [_one(path, f"{name}{ns.replace('/', '__')}", ns, tails) for ns in namespaces]


def _tail(topic: str) -> str:
    """The sensor's own part of a topic: ``/tc1/temperature`` of ``/probe1/tc1/temperature``."""
    parts = PurePosixPath(topic).parts
    return "/" + "/".join(parts[-2:]) if len(parts) > 2 else topic


def _one(path: Path, name: str, namespace: str, tails: list[str]) -> Recording:
    return Recording(
        path,
        name,
        topics=(namespace + tails[0], namespace + tails[1], None),
        probe=namespace,
    )
