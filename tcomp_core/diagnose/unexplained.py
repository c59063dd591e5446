"""What the final model still fails to explain, in words.

When the last model of the staircase stays well above the noise floor (:func:`is_unexplained`)
no effect in the library accounts for the rest, and the diagnosis says so. The residual of the
slow sensor simulated from the fast one (``measured − predicted`` at the working rate, not
low-passed) is then described by the marks it carries:

* a spectral line on one channel that the other reading and the sensors' first-order relation
  do not explain (:func:`tcomp_core.effects.interference.find_line`: the gas signal's own
  harmonics are in both readings, a mains line on tc2 is not in tc1), when the
  ``interference`` effect could not take it (it was not a candidate, or not significant);
* error growing with the level: the residual's rms in the top fifth of the level against the
  bottom fifth;
* energy near Nyquist: the residual's power above :data:`NYQUIST_SHARE` of the Nyquist
  frequency;
* error confined to a time window: a stretch of the record whose rms is
  :data:`WINDOW_FACTOR` times the median window's.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

from ..effects import Model
from ..effects.interference import find_line
from .heldout import Evaluator
from .result import ModelFit

__all__ = ["describe_unexplained", "is_unexplained"]

#: The final model's error (noise taken out) is unexplained from this many noise floors...
UNEXPLAINED_PER_FLOOR = 2.0
#: ...and this many percent of the slow sensor's spread.
UNEXPLAINED_MIN_PCT = 1.0
#: "Near Nyquist" starts at this share of the Nyquist frequency; named above this share of power.
NYQUIST_SHARE = 0.8
NYQUIST_MIN_POWER = 0.25
#: Level and time: the ratio of rms errors that counts as growing or confined.
LEVEL_FACTOR = 2.0
WINDOW_FACTOR = 3.0
WINDOWS = 10


def is_unexplained(fit: ModelFit) -> bool:
    """Whether ``fit`` stays well above the noise floor (see the module constants)."""
    return bool(
        math.isfinite(fit.error_pct)
        and fit.error_pct >= UNEXPLAINED_MIN_PCT
        and fit.error_pct >= UNEXPLAINED_PER_FLOOR * fit.noise_floor_pct
    )


def _line(evaluator: Evaluator, fit: ModelFit) -> str | None:
    """The strongest line one channel carries beyond what the other explains, in words."""
    readings = evaluator.readings
    line = find_line(*readings, evaluator.data.dt, fit.tau1, fit.tau2)
    if line is None:
        return None
    f0, channel, amplitude = line
    return (
        f"a spectral line at {f0:.4g} Hz on tc{channel} (about {amplitude:.3g} degC) that "
        f"tc{3 - channel} does not share: interference such as mains pick-up"
    )


def _level(level: NDArray[np.float64], residual: NDArray[np.float64]) -> str | None:
    low, high = np.percentile(level, (20.0, 80.0))
    bottom = residual[level <= low]
    top = residual[level >= high]
    if bottom.size < 10 or top.size < 10:
        return None
    rms_bottom, rms_top = float(np.sqrt(np.mean(bottom**2))), float(np.sqrt(np.mean(top**2)))
    if rms_top >= LEVEL_FACTOR * rms_bottom:
        return (
            f"the error grows with the level: rms {rms_bottom:.3g} degC below {low:.4g} degC, "
            f"{rms_top:.3g} degC above {high:.4g} degC"
        )
    if rms_bottom >= LEVEL_FACTOR * rms_top:
        return (
            f"the error grows as the level falls: rms {rms_top:.3g} degC above {high:.4g} "
            f"degC, {rms_bottom:.3g} degC below {low:.4g} degC"
        )
    return None


def _nyquist(dt: float, residual: NDArray[np.float64]) -> str | None:
    spectrum = np.abs(np.fft.rfft(residual - residual.mean())) ** 2
    freq = np.fft.rfftfreq(residual.size, dt)
    edge = NYQUIST_SHARE * 0.5 / dt
    share = float(spectrum[freq >= edge].sum() / max(spectrum.sum(), 1e-300))
    if share >= NYQUIST_MIN_POWER:
        return f"{100 * share:.0f} % of the residual's energy lies near Nyquist (> {edge:.4g} Hz)"
    return None


def _window(time: NDArray[np.float64], residual: NDArray[np.float64]) -> str | None:
    edges = np.linspace(time[0], time[-1], WINDOWS + 1)
    rms = []
    for start, stop in itertools.pairwise(edges):
        part = residual[(time >= start) & (time < stop)]
        rms.append(float(np.sqrt(np.mean(part**2))) if part.size else math.nan)
    values = np.asarray(rms)
    median = float(np.nanmedian(values))
    worst = int(np.nanargmax(values))
    if median > 0.0 and values[worst] >= WINDOW_FACTOR * median:
        return (
            f"the error is confined to {edges[worst]:.3g}–{edges[worst + 1]:.3g} s (rms "
            f"{values[worst]:.3g} degC against a median {median:.3g} degC)"
        )
    return None


def describe_unexplained(evaluator: Evaluator, fit: ModelFit) -> str:
    """The residual's signature in words when ``fit`` is unexplained, else ``""``."""
    if not is_unexplained(fit):
        return ""
    data = evaluator.data
    measured = evaluator.readings[evaluator.slow - 1]
    keep = evaluator.scored_mask(Model(fit.effects, fit.params))
    residual = (measured - fit.predicted)[keep]
    marks = [
        _line(evaluator, fit),
        _level(measured[keep], residual),
        _nyquist(data.dt, residual),
        _window(data.time[keep], residual),
    ]
    found = [mark for mark in marks if mark]
    head = (
        f"the final model ({' + '.join(fit.effects) or 'first order'}) leaves "
        f"{fit.error_pct:.3g} % against a noise floor of {fit.noise_floor_pct:.3g} %"
    )
    return f"{head}: {'; '.join(found) if found else 'no simple signature (broadband, steady)'}"
