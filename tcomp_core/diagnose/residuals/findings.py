"""Plain sentences saying where a model fails, from the statistics of its residual."""

from __future__ import annotations

import math

import numpy as np

from .common import normal_quantile
from .correlation import Autocorrelation, CandidateCorrelation, CrossCorrelation
from .level import LevelErrors
from .spectrum import BandErrors
from .windows import WindowedError, WindowedTau

__all__ = ["MIN_CORRELATION", "describe_failure"]

#: Smallest correlation worth a finding (the signal explains 1 % of the residual's variance);
#: an offset is worth one from a tenth of the residual's standard deviation.
MIN_CORRELATION = 0.1


def _p_text(p: float) -> str:
    return "p < 1e-6" if p < 1e-6 else f"p = {p:.2g}"


def _whiteness_finding(acf: Autocorrelation, confidence: float) -> str:
    outside = f"{100 * acf.fraction_outside:.0f} % of autocorrelation lags outside the " + (
        f"{100 * confidence:.0f} % bound (Ljung-Box {_p_text(acf.p_value)})"
    )
    if acf.p_value < 1.0 - confidence:
        return f"residual not white: {outside}"
    return f"residual consistent with white noise: {outside}"


def _band_finding(bands: BandErrors) -> str:
    low, high = bands.peak_band_hz
    share = bands.residual_share[bands.peak_band]
    ratio = bands.residual_to_signal[bands.peak_band]
    return (
        f"largest share of the residual power in {low:.3g}–{high:.3g} Hz: {100 * share:.0f} %, "
        f"where the residual holds {100 * ratio:.3g} % of the signal's power"
    )


def _level_findings(levels: LevelErrors, z: float) -> list[str]:
    found = []
    if abs(levels.offset_t) > z and abs(levels.offset) >= MIN_CORRELATION * levels.residual_std:
        found.append(f"residual offset {levels.offset:.3g} degC (t = {levels.offset_t:.3g})")
    if levels.r_squared < MIN_CORRELATION**2:
        return found
    if abs(levels.slope_t) > z:
        found.append(
            f"error changes with temperature level: slope {levels.slope:.3g} degC/degC "
            f"(t = {levels.slope_t:.3g})"
        )
    if abs(levels.curvature_t) > z:
        found.append(
            f"error curves with temperature level: curvature {levels.curvature:.3g} /degC "
            f"(t = {levels.curvature_t:.3g})"
        )
    return found


def _tau_finding(taus: WindowedTau) -> str | None:
    spreads = (taus.tau1_spread_pct, taus.tau2_spread_pct, taus.ratio_spread_pct)
    if not all(math.isfinite(s) for s in spreads):
        return None
    if taus.vary_together:
        return (
            f"tau1 and tau2 vary together across windows (corr {taus.log_correlation:.2f}, "
            f"spread {spreads[0]:.2g} % and {spreads[1]:.2g} %) at a constant ratio "
            f"(spread {spreads[2]:.2g} %)"
        )
    return (
        f"tau1 and tau2 across windows: spread {spreads[0]:.2g} % and {spreads[1]:.2g} %, "
        f"ratio spread {spreads[2]:.2g} % (corr of logs {taus.log_correlation:.2f})"
    )


def _input_finding(ccf: CrossCorrelation) -> str:
    at = f"correlation {ccf.peak:.2f} at {1e3 * ccf.peak_lag_s:.3g} ms, bound {ccf.bound:.2f}"
    if not ccf.significant:
        return f"residual not significantly correlated with the input rate ({at})"
    if abs(ccf.peak) < MIN_CORRELATION:
        return f"the residual follows the input rate only weakly ({at}: under 1 % of its variance)"
    if ccf.peak_lag_s == 0.0:
        return f"the residual moves with the input rate ({at})"
    way = "lags" if ccf.peak_lag_s > 0.0 else "leads"
    return (
        f"the residual {way} the input rate by {1e3 * abs(ccf.peak_lag_s):.3g} ms "
        f"(correlation {ccf.peak:.2f}, bound {ccf.bound:.2f})"
    )


def _window_finding(errors: WindowedError) -> str | None:
    e = errors.error_pct
    finite = np.isfinite(e)
    if finite.sum() < 2:
        return None
    median = float(np.median(e[finite]))
    worst = int(np.nanargmax(e))
    if e[worst] < 1.5 * median:
        return (
            f"error spread evenly over time: {np.min(e[finite]):.3g}–{e[worst]:.3g} % "
            "across windows"
        )
    first = last = worst
    while first > 0 and e[first - 1] >= 1.5 * median:
        first -= 1
    while last < e.size - 1 and e[last + 1] >= 1.5 * median:
        last += 1
    c = errors.centres_s
    half = 0.5 * (c[1] - c[0])
    which = (
        f"window {first + 1} holds" if first == last else f"windows {first + 1}–{last + 1} hold"
    )
    return (
        f"{which} the largest error ({max(c[first] - half, 0.0):.3g}–{c[last] + half:.3g} s): up "
        f"to {e[worst]:.3g} % against a median of {median:.3g} %"
    )


def _candidate_finding(candidates: list[CandidateCorrelation], z: float) -> str | None:
    if not candidates or not abs(candidates[0].z) > z:
        return None
    if abs(candidates[0].correlation) < MIN_CORRELATION:
        return None
    best = candidates[0]
    return (
        f"of the candidate signals the residual follows {best.name!r} most "
        f"(r = {best.correlation:.2f}, z = {best.z:.3g})"
    )


def describe_failure(
    *,
    acf: Autocorrelation,
    ccf_input: CrossCorrelation,
    candidates: list[CandidateCorrelation],
    windowed_error: WindowedError,
    windowed_tau: WindowedTau,
    bands: BandErrors,
    levels: LevelErrors,
    confidence: float,
) -> list[str]:
    """Plain sentences saying where the model fails, in a fixed order.

    Parameters
    ----------
    acf, ccf_input, candidates, windowed_error, windowed_tau, bands, levels
        The statistics of :class:`~tcomp_core.diagnose.residuals.analysis.FailureAnalysis`.
    confidence : float
        Confidence level of every bound and test, in (0, 1).

    Returns
    -------
    list of str
        Whiteness, frequency band, level, time constants, input rate, windows and candidate
        signals; a statistic that shows nothing worth saying adds no sentence.
    """
    z = normal_quantile(confidence)
    found = [
        _whiteness_finding(acf, confidence),
        _band_finding(bands),
        *_level_findings(levels, z),
        _tau_finding(windowed_tau),
        _input_finding(ccf_input),
        _window_finding(windowed_error),
        _candidate_finding(candidates, z),
    ]
    return [sentence for sentence in found if sentence]
