"""What a campaign has done: a content key per recording and options, and each one's result.

A recording's key is a hash of its bytes (every file of a bag), the topics it is read with and
the campaign's options, so a rerun with the same data and options finds its result and does no
work, while a changed file or option is processed again. Hashing a file's bytes costs about a
second per GB; the digest is kept with the file's size and modification time
(``ledger/digests.json``) and reused while they are unchanged.

A result is one JSON document per key (``ledger/KEY.json``), written by the worker that
produced it, atomically, once the recording's output is complete: a campaign cut at any point
keeps everything finished and redoes only the rest.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..io.outputs import atomic_output
from ..io.paths import bag_files, is_bag_directory
from .inputs import Recording

__all__ = ["Ledger", "write_entry"]

#: Bumped when a result's content changes meaning: older results are then not reused.
LEDGER_VERSION = 1
#: Bytes read at a time while hashing.
HASH_BLOCK = 8 * 2**20


def _files(path: Path) -> list[Path]:
    if is_bag_directory(path):
        return [path / "metadata.yaml", *bag_files(path)]
    return [path]


def write_entry(path: Path, entry: Mapping[str, Any]) -> None:
    """Write a result atomically (:func:`~tcomp_core.io.atomic_output`), replacing any."""
    with atomic_output(path, overwrite=True) as temporary:
        temporary.write_text(json.dumps(entry, allow_nan=True))


class Ledger:
    """The results of a campaign's output directory (see the module).

    Parameters
    ----------
    out_dir : Path
        The campaign's output directory; results live in ``out_dir/ledger``.
    """

    def __init__(self, out_dir: Path) -> None:
        self.directory = Path(out_dir) / "ledger"
        self.directory.mkdir(parents=True, exist_ok=True)
        self._digests_path = self.directory / "digests.json"
        try:
            self._digests: dict[str, list] = json.loads(self._digests_path.read_text())
        except (OSError, ValueError):
            self._digests = {}

    def data_digest(self, recording: Recording) -> str:
        """sha256 of the recording's bytes (file names and contents, in order)."""
        digest = hashlib.sha256()
        for file in _files(recording.path):
            stat = file.stat()
            where = str(file.resolve())
            cached = self._digests.get(where)
            if cached and cached[:2] == [stat.st_size, stat.st_mtime_ns]:
                part = cached[2]
            else:
                part = _file_digest(file)
                self._digests[where] = [stat.st_size, stat.st_mtime_ns, part]
            digest.update(file.name.encode() + b"\0" + part.encode())
        return digest.hexdigest()

    def key(self, recording: Recording, options: Mapping[str, Any]) -> str:
        """The key of ``recording`` processed with ``options`` (JSON-ready values)."""
        described = {
            "version": LEDGER_VERSION,
            "options": options,
            "topics": recording.topics,
            "data": self.data_digest(recording),
        }
        text = json.dumps(described, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def entry_path(self, key: str) -> Path:
        """Where the result of ``key`` is (or will be) written."""
        return self.directory / f"{key}.json"

    def finished(self, key: str) -> dict[str, Any] | None:
        """The result of ``key`` when it is complete and its output exists, else None."""
        try:
            entry = json.loads(self.entry_path(key).read_text())
        except (OSError, ValueError):
            return None
        output = entry.get("output")
        return entry if output and Path(output).exists() else None

    def save_digests(self) -> None:
        """Keep the file digests for the next run."""
        write_entry(self._digests_path, self._digests)


def _file_digest(file: Path) -> str:
    digest = hashlib.sha256()
    with file.open("rb") as handle:
        while block := handle.read(HASH_BLOCK):
            digest.update(block)
    return digest.hexdigest()
