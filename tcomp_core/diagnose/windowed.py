"""``diagnose`` of a long record, window by window, and the whole record's verdict from them.

Each window the reader hands over (:class:`~tcomp_core.io.windows.WindowReader`, streamed from
the file) is diagnosed on its own by :func:`~tcomp_core.diagnose.diagnose`; only a row of
figures is kept (:class:`WindowResult`), so memory holds one window's diagnosis at a time
whatever the record's length. A window that cannot be read (a gap, too many invalid samples, a
change of rate: the rules of :mod:`tcomp_core.io.screening` and the readers) or diagnosed says
why in its row; the others carry on.

The whole record's verdict (:func:`whole_verdict`) is the verdict most windows give, counting
the windows diagnosed except a last one shorter than half a window (too little of the record
to outvote a full one; it is listed all the same). On a tie a found effect goes before
``none`` and ``unexplained``, then the one met first. τ1 and τ2 are the medians of the final
models' τ over the windows that give that verdict (the model the verdict names), with their
range over those windows; the windows that disagree are listed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..effects import EFFECT_NAMES
from ..errors import DataError, TcompError
from ..io.windows import Window
from .pipeline import diagnose
from .ranking import MAX_EFFECTS

__all__ = [
    "WholeVerdict",
    "WindowResult",
    "WindowedDiagnosis",
    "diagnose_window",
    "diagnose_windows",
    "whole_verdict",
    "windowed_to_dict",
]

#: Verdicts that name no effect: on a tie between windows, a found effect goes first.
NO_FINDING = ("none", "unexplained")
#: A last window shorter than this share of the window length does not vote.
MIN_VOTING_SHARE = 0.5


def _finite(value: float | None) -> float | None:
    """A float for JSON, None for inf, NaN or None."""
    return float(value) if value is not None and np.isfinite(value) else None


@dataclass(frozen=True, kw_only=True)
class WindowResult:
    """The diagnosis of one window, as a row of figures.

    Attributes
    ----------
    index : int
        0, 1, ... in time order.
    start_s, length_s : float
        Start (seconds from the record's first sample) and length of the window, s.
    samples : int
        Samples read in the window.
    verdict : str or None
        An effect, ``none`` or ``unexplained``; None when the window was not diagnosed.
    effects : tuple of str
        The final model's effects (findings and ordinary physics).
    params : dict of str to float
        The final model's parameters besides τ1 and τ2 (the effects' parameters).
    tau1, tau2 : float
        The final model's time constants, s (NaN when not diagnosed).
    tau1_95, tau2_95 : (float, float) or None
        Their 95 % intervals, s.
    error_pct, base_error_pct : float
        Held-out error of the final and of the base model, %.
    problem : str
        Why the window was not diagnosed ('' when it was).
    notes : tuple of str
        Readings left out and bridged in the window, and the like.
    votes : bool
        Whether the window counts in the whole record's verdict.
    """

    index: int
    start_s: float
    length_s: float
    samples: int
    verdict: str | None = None
    effects: tuple[str, ...] = ()
    params: dict[str, float] = field(default_factory=dict)
    tau1: float = float("nan")
    tau2: float = float("nan")
    tau1_95: tuple[float, float] | None = None
    tau2_95: tuple[float, float] | None = None
    error_pct: float = float("nan")
    base_error_pct: float = float("nan")
    problem: str = ""
    notes: tuple[str, ...] = ()
    votes: bool = False

    @classmethod
    def undiagnosed(cls, window: Window, problem: str = "") -> WindowResult:
        """The row of ``window`` before (or instead of) its diagnosis: why, if ``problem``."""
        return cls(
            index=window.index,
            start_s=window.start_s,
            length_s=window.length_s,
            samples=window.samples,
            problem=problem,
            notes=window.notes,
        )

    def summary(self) -> dict[str, Any]:
        """JSON-ready row."""

        def interval(value: tuple[float, float] | None) -> list[float | None] | None:
            return None if value is None else [_finite(value[0]), _finite(value[1])]

        return {
            "index": self.index,
            "start_s": self.start_s,
            "length_s": _finite(self.length_s),
            "samples": self.samples,
            "verdict": self.verdict,
            "effects": list(self.effects),
            "params": {name: _finite(value) for name, value in self.params.items()},
            "tau1": _finite(self.tau1),
            "tau2": _finite(self.tau2),
            "tau1_95": interval(self.tau1_95),
            "tau2_95": interval(self.tau2_95),
            "error_pct": _finite(self.error_pct),
            "base_error_pct": _finite(self.base_error_pct),
            "problem": self.problem,
            "notes": list(self.notes),
            "votes": self.votes,
        }


@dataclass(frozen=True, kw_only=True)
class WholeVerdict:
    """The whole record's verdict drawn from its windows (see the module).

    Attributes
    ----------
    verdict : str
        The verdict most voting windows give.
    agree, voting : int
        How many voting windows give it, of how many.
    tau1, tau2 : float
        Medians of τ over the windows that give the verdict, s.
    tau1_range, tau2_range : (float, float)
        Their smallest and largest τ, s.
    disagreeing : list of int
        The voting windows that give another verdict.
    """

    verdict: str
    agree: int
    voting: int
    tau1: float
    tau2: float
    tau1_range: tuple[float, float]
    tau2_range: tuple[float, float]
    disagreeing: list[int] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class WindowedDiagnosis:
    """Everything ``tcomp diagnose`` found on a record diagnosed in windows.

    Attributes
    ----------
    source : str
        The file read.
    window_s : float
        Window length, s.
    automatic : bool
        The length was chosen because the record is too long to diagnose whole.
    windows : list of WindowResult
        One row per window, in time order.
    whole : WholeVerdict
        The whole record's verdict and τ.
    """

    source: str
    window_s: float
    automatic: bool
    windows: list[WindowResult]
    whole: WholeVerdict


def diagnose_window(
    window: Window, candidates: Sequence[str] = EFFECT_NAMES, max_effects: int = MAX_EFFECTS
) -> WindowResult:
    """Diagnose one window; a window that cannot be diagnosed says why in its row."""
    if window.record is None:
        return WindowResult.undiagnosed(window, window.problem)
    row = WindowResult.undiagnosed(window)
    try:
        found = diagnose(window.record, candidates=candidates, max_effects=max_effects)
    except (TcompError, ValueError) as exc:
        return replace(row, problem=" ".join(str(exc).split()))
    final = found.final
    return replace(
        row,
        verdict=found.verdict,
        effects=tuple(final.effects),
        params={
            name: float(value)
            for name, value in final.params.items()
            if name not in ("tau1", "tau2")
        },
        tau1=float(final.tau1),
        tau2=float(final.tau2),
        tau1_95=final.intervals.get("tau1"),
        tau2_95=final.intervals.get("tau2"),
        error_pct=float(final.error_pct),
        base_error_pct=float(found.base.error_pct),
    )


def whole_verdict(rows: Sequence[WindowResult]) -> WholeVerdict:
    """The whole record's verdict and τ from its windows' rows (see the module).

    Raises
    ------
    DataError
        If no window voted (none could be diagnosed), naming the first window's problem.
    """
    voting = [row for row in rows if row.votes and row.verdict is not None]
    if not voting:
        problems = [row for row in rows if row.problem]
        first = f"; window {problems[0].index + 1}: {problems[0].problem}" if problems else ""
        raise DataError(f"no window could be diagnosed{first}")
    counts = Counter(row.verdict for row in voting)
    most = max(counts.values())
    tied = [verdict for verdict, count in counts.items() if count == most]
    verdict = str(next((v for v in tied if v not in NO_FINDING), tied[0]))
    agreeing = [row for row in voting if row.verdict == verdict]
    tau1 = np.array([row.tau1 for row in agreeing])
    tau2 = np.array([row.tau2 for row in agreeing])
    return WholeVerdict(
        verdict=verdict,
        agree=len(agreeing),
        voting=len(voting),
        tau1=float(np.median(tau1)),
        tau2=float(np.median(tau2)),
        tau1_range=(float(tau1.min()), float(tau1.max())),
        tau2_range=(float(tau2.min()), float(tau2.max())),
        disagreeing=[row.index for row in voting if row.verdict != verdict],
    )


def diagnose_windows(
    windows: Iterable[Window],
    *,
    source: str,
    window_s: float | Callable[[], float],
    automatic: bool = False,
    candidates: Sequence[str] = EFFECT_NAMES,
    max_effects: int = MAX_EFFECTS,
    progress: Callable[[WindowResult], None] | None = None,
    diagnose_all: Callable[[Iterable[Window]], Iterable[WindowResult]] | None = None,
) -> WindowedDiagnosis:
    """Diagnose each window of a record and draw the whole record's verdict from them.

    Parameters
    ----------
    windows : iterable of Window
        From :class:`~tcomp_core.io.windows.WindowReader` (read as they are diagnosed).
    source : str
        The file, for the result.
    window_s : float or callable
        The window length, s (a callable is asked once the windows are read: the reader's
        automatic choice).
    automatic : bool
        The length was chosen automatically.
    candidates, max_effects
        As :func:`~tcomp_core.diagnose.diagnose`.
    progress : callable, optional
        Called with each window's row once it is diagnosed.
    diagnose_all : callable, optional
        Maps the windows to their rows, in order (default: :func:`diagnose_window` on each in
        turn, here; ``tcomp campaign`` hands them to its cluster's workers). ``candidates``
        and ``max_effects`` are then its business.

    Returns
    -------
    WindowedDiagnosis

    Raises
    ------
    DataError
        As the reader raises it on the file as a whole; if no window could be diagnosed.
    """
    rows: list[WindowResult] = []
    found = (
        diagnose_all(windows)
        if diagnose_all is not None
        else (diagnose_window(window, candidates, max_effects) for window in windows)
    )
    for row in found:
        rows.append(row)
        if progress is not None:
            progress(row)
    length = window_s() if callable(window_s) else window_s
    # A last window shorter than half the others has too little of the record to vote.
    last = rows[-1] if rows else None
    rows = [
        _with_vote(row, row is not last or row.length_s >= MIN_VOTING_SHARE * length)
        for row in rows
    ]
    return WindowedDiagnosis(
        source=source,
        window_s=length,
        automatic=automatic,
        windows=rows,
        whole=whole_verdict(rows),
    )


def _with_vote(row: WindowResult, full: bool) -> WindowResult:
    return replace(row, votes=full and row.verdict is not None)


def windowed_to_dict(result: WindowedDiagnosis) -> dict[str, Any]:
    """The JSON document of ``tcomp diagnose`` on a record diagnosed in windows.

    Keys: ``source``, ``window_s``, ``automatic``, ``verdict`` (the whole record's),
    ``rule`` (how it is drawn), ``agree``/``voting`` (windows giving it, windows voting),
    ``tau1``/``tau2`` {median, min, max} over the agreeing windows, ``disagreeing`` (window
    indices), ``windows`` (one row each: index, start_s, length_s, samples, verdict, effects,
    params, tau1, tau2, tau1_95, tau2_95, error_pct, base_error_pct, problem, notes, votes).
    """
    whole = result.whole
    return {
        "source": result.source,
        "window_s": _finite(result.window_s),
        "automatic": result.automatic,
        "verdict": whole.verdict,
        "rule": (
            "the verdict most windows give (a last window shorter than half a window does not "
            "vote; on a tie a found effect first); tau: median over the windows giving it"
        ),
        "agree": whole.agree,
        "voting": whole.voting,
        "tau1": {"median": whole.tau1, "min": whole.tau1_range[0], "max": whole.tau1_range[1]},
        "tau2": {"median": whole.tau2, "min": whole.tau2_range[0], "max": whole.tau2_range[1]},
        "disagreeing": list(whole.disagreeing),
        "windows": [row.summary() for row in result.windows],
    }
