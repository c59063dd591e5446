"""A progress bar on stderr for long runs, shown only when stderr is a terminal.

``tqdm`` draws it when installed; otherwise a one-line bar of our own, redrawn at most five
times a second.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["ProgressBar", "progress_bar"]


class ProgressBar:
    """Percentage of the input read and pairs matched, on one line.

    Parameters
    ----------
    label : str
        Shown before the bar (the input's name).
    stream : text file
        Where to draw (stderr).
    """

    WIDTH = 30
    INTERVAL_S = 0.2

    def __init__(self, label: str, stream: TextIO) -> None:
        self._label = label
        self._stream = stream
        self._started = time.perf_counter()
        self._drawn = 0.0
        self._visible = False

    def update(self, fraction: float, pairs: int) -> None:
        """Redraw if due: ``fraction`` of the input read (0..1), ``pairs`` matched so far."""
        now = time.perf_counter()
        if now - self._drawn < self.INTERVAL_S and fraction < 1.0:
            return
        self._drawn = now
        filled = round(self.WIDTH * min(max(fraction, 0.0), 1.0))
        rate = pairs / max(now - self._started, 1e-9)
        self._stream.write(
            f"\r{self._label} [{'#' * filled}{'.' * (self.WIDTH - filled)}] "
            f"{100 * fraction:5.1f} % {pairs} pairs {rate / 1e6:.2f} M pairs/s"
        )
        self._stream.flush()
        self._visible = True

    def close(self) -> None:
        """End the line."""
        if self._visible:
            self._stream.write("\n")
            self._stream.flush()
            self._visible = False


class _Tqdm:
    """The same interface over ``tqdm`` (percent of the input)."""

    def __init__(self, label: str, stream: TextIO) -> None:
        from tqdm import tqdm

        self._bar = tqdm(total=1000, desc=label, file=stream, unit="‰", leave=True)

    def update(self, fraction: float, pairs: int) -> None:
        self._bar.set_postfix_str(f"{pairs} pairs", refresh=False)
        self._bar.update(round(1000 * fraction) - self._bar.n)

    def close(self) -> None:
        self._bar.close()


def progress_bar(label: str, stream: TextIO | None = None) -> ProgressBar | _Tqdm | None:
    """A bar on ``stream`` (stderr) if it is a terminal, else None (no output at all)."""
    stream = sys.stderr if stream is None else stream
    if not (hasattr(stream, "isatty") and stream.isatty()):
        return None
    try:
        return _Tqdm(label, stream)
    except ImportError:
        return ProgressBar(label, stream)
