"""All two-thermocouple time-constant estimators of Hung et al. (2005), behind one function.

=============  ==========================================================================
``tdr-kee``    time-derivative reconstruction, α = τ1/τ2 known a priori (Kee et al. 1999)
``gamma-ls``   least squares on the three-parameter ARX model (Eq. 11)
``gamma-tls``  total least squares on Eq. (11)
``beta-ls``    least squares on the two-parameter β model (Eqs. 13–17)
``beta-tls``   total least squares on the β model
``beta-gtls``  generalized total least squares with noise covariance C0(φ) (Eqs. 18–21)
``ml-eiv``     cross-relation residual weighted by its own banded noise covariance (beyond
               the paper; about a third of β-GTLS's spread for τ1 at K = 4 %)
=============  ==========================================================================

The first six are the paper's (:data:`PAPER_METHODS`). ``ml-eiv`` is the default
(:data:`DEFAULT_METHOD`): it weights the residual by the noise it carries at the sample rate it
is given, so it needs no pre-filter; β-GTLS without one is biased and scattered at the rates
test cells record (``bench/bench_accuracy.py``, rate block).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..choices import DEFAULT_METHOD, METHODS, PAPER_METHODS, Method
from ..errors import DataError, TcompError
from ..filters import prefilter_pair
from ..lines import ForeignLine, foreign_lines, remove_lines, subtract_tones
from ..validation import (
    check_excitation,
    check_pair,
    check_sample_interval,
    check_shared_signal,
)
from .beta import beta_gtls, beta_ls, beta_noise_covariance, beta_tls, estimate_beta_from_scatter
from .gamma import gamma_ls, gamma_tls
from .mleiv import ml_eiv, phi_from_data
from .result import Estimate
from .tdr import tdr_kee

__all__ = [
    "DEFAULT_METHOD",
    "DIFFERENCE_EQUATION_METHODS",
    "METHODS",
    "PAPER_METHODS",
    "PHI_METHODS",
    "PHI_REFIT_TOLERANCE",
    "Estimate",
    "Method",
    "beta_gtls",
    "beta_ls",
    "beta_noise_covariance",
    "beta_tls",
    "estimate",
    "estimate_beta_from_scatter",
    "gamma_ls",
    "gamma_tls",
    "ml_eiv",
    "phi_from_data",
    "tdr_kee",
    "warm_start",
]

#: The paper's five difference-equation estimators (all but TDR-Kee).
DIFFERENCE_EQUATION_METHODS: tuple[str, ...] = PAPER_METHODS[1:]
#: Estimators that take the noise variance ratio φ.
PHI_METHODS: tuple[str, ...] = ("beta-gtls", "ml-eiv")
#: Largest |ln| of the ratio between the noise ratio measured with the first fit's τ and the
#: one that fit used, below which the fit is kept rather than repeated. τ moves by at most
#: 1e-4 of itself per 1 % of φ (ml-eiv on multisine, pulses and ramps at 0.5-5 kHz, K 1-4 %,
#: φ 0.3-4), so a 2 % difference moves it by 0.02 % at most, far inside its standard error
#: (0.1-0.7 % on those records); the refit cost a second search on every window of a stream.
PHI_REFIT_TOLERANCE = 0.05


def estimate(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    method: Method = DEFAULT_METHOD,
    *,
    phi: float | None = 1.0,
    alpha: float | None = None,
    prefilter_hz: float | None = None,
    names: tuple[str, str] = ("tc1", "tc2"),
    start: tuple[float, ...] | None = None,
    phi_start: float | None = None,
    reject_lines: bool | None = None,
) -> Estimate:
    """Estimate the time constants of two thermocouples from their signals alone.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Temperatures of thermocouples 1 and 2 in degrees C, sampled simultaneously and uniformly.
    dt : float
        Sample interval τ_s in seconds.
    method : str
        One of :data:`METHODS`; ``ml-eiv`` by default (:data:`DEFAULT_METHOD`): unbiased at any
        sample rate without a pre-filter, where the paper's estimators need one (``README``).
    phi : float or None
        Noise variance ratio σ1²/σ2² assumed by ``beta-gtls`` and ``ml-eiv`` (1 when the noise
        is equal); ``None`` measures it: from the raw signals' spectra (before any
        pre-filter) for a first estimate, then from the model with that estimate's τ
        (:func:`tcomp_core.noise.model_noise`, which removes the gas signal the spectra share)
        for the final one (refitted only when that ratio differs from the first by more
        than :data:`PHI_REFIT_TOLERANCE`); ``params["phi_estimated"] = 1.0``. Refused for
        the other methods, which assume equal noise.
    alpha : float, optional
        Time constant ratio τ1/τ2 for ``tdr-kee`` (estimated at signal crossovers if omitted);
        refused for the other methods, which need no prior.
    prefilter_hz : float, optional
        Bandwidth of a zero-phase Butterworth pre-filter applied to both signals first, Hz.
    names : pair of str
        What to call the signals in error messages (columns, topics).
    start : (float, float) or (float, float, float), optional
        τ1, τ2 (s) to start ``ml-eiv``'s search from (a warm start, e.g. the previous
        window's), and the gain between the sensors (``params["gain"]``, 1 when left out);
        ignored by the other methods, which are not iterative. The refits after lines are
        notched and after φ is measured start from the first fit's τ and gain.
    phi_start : float, optional
        With ``phi=None``: the noise ratio the first fit uses instead of the raw spectra's
        (a warm start, e.g. the ratio the previous window measured); φ is then measured with
        that fit's τ as without it. Ignored when ``phi`` is given.
    reject_lines : bool, optional
        Look for spectral lines one sensor carries and the other does not (mains pick-up,
        :func:`tcomp_core.lines.foreign_lines`) and, where there are any, estimate again with
        them notched from both signals: a common filter leaves the sensors' relation intact,
        while the line would bend τ to explain it. The lines found are in ``.lines``. By
        default ``ml-eiv`` looks and the paper's methods do not (they reproduce the paper,
        and their τ, biased without a pre-filter at high rates, would call the gas's own
        lines foreign).

    Returns
    -------
    Estimate
        ``.tau1`` and ``.tau2`` in seconds, the raw parameters and a conditioning figure.

    Raises
    ------
    DataError
        Non-finite samples, unequal lengths, too few samples.
    NoExcitationError
        The data carry no information on the time constants (constant or identical signals).
    PhysicalRangeError
        A discrete pole came out outside (0, 1).
    EstimationError
        ``ml-eiv`` found its best fit at the edge of its search range.
    """
    first, second = check_pair(tc1, tc2, names)
    dt = check_sample_interval(dt)
    check_excitation(first, second, names)
    check_shared_signal(first, second, dt, names)
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if alpha is not None and method != "tdr-kee":
        raise ValueError(f"alpha applies to tdr-kee only; {method} estimates both time constants")
    if (phi is None or phi != 1.0) and method not in PHI_METHODS:
        raise ValueError(
            f"phi applies to {' and '.join(PHI_METHODS)} only; "
            f"{method} assumes equal noise variances"
        )
    raw = (first, second)
    measured = phi is None
    if phi is None and phi_start is not None:
        if not (math.isfinite(phi_start) and phi_start > 0.0):
            raise ValueError(f"phi_start={phi_start!r} must be a finite positive number")
        phi = phi_start
    elif phi is None:
        # Before the pre-filter, which would remove the band the noise is measured in.
        try:
            phi = phi_from_data(first, second, dt)
        except DataError:
            # One channel shows no noise at all (synthetic or heavily quantised data): no
            # ratio to measure, and equal weights are what the data allow.
            phi, measured = 1.0, False
    if prefilter_hz is not None:
        first, second = prefilter_pair(first, second, dt, prefilter_hz)
    if reject_lines is None:
        reject_lines = method == "ml-eiv"
    ratio = phi  # the closure below needs it bound as a float

    def fit(a: NDArray[np.float64], b: NDArray[np.float64], warm: tuple[float, ...] | None):
        return _dispatch(a, b, dt, method, ratio, alpha, warm, prefilter_hz)

    def refit(a: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[float, float]:
        found = fit(a, b, start)
        return found.tau1, found.tau2

    try:
        result: Estimate | None = fit(first, second, start)
    except TcompError as exc:
        if not reject_lines:
            raise
        # A line can throw the fit to the edge of its range: look for one before refusing.
        result, refused = None, exc
    lines: tuple[ForeignLine, ...] = ()
    if reject_lines:
        taus = None if result is None else (result.tau1, result.tau2)
        lines = tuple(foreign_lines(first, second, dt, taus, refit))
    if lines:
        frequencies = [line.frequency_hz for line in lines]
        notched = remove_lines(first, dt, frequencies), remove_lines(second, dt, frequencies)
        warm = start if result is None else warm_start(result)
        try:
            result = replace(fit(*notched, warm), lines=lines)
        except TcompError:
            if result is None:
                raise
            lines = ()  # the notches took what the fit needed: keep the estimate as it was
        else:
            first, second = notched
            # φ from the readings with the lines' tones off: a notch's hole reads as quiet.
            raw = subtract_tones(raw[0], dt, frequencies), subtract_tones(raw[1], dt, frequencies)
    if result is None:
        raise refused
    if measured:
        try:
            refined = phi_from_data(*raw, dt, taus=(result.tau1, result.tau2))
        except DataError:  # the model leaves no noise on one channel: keep the first φ
            measured = False
        else:
            if abs(math.log(refined / phi)) > PHI_REFIT_TOLERANCE:
                result = _dispatch(
                    first, second, dt, method, refined, alpha, warm_start(result), prefilter_hz
                )
    if measured:
        result = replace(result, params={**result.params, "phi_estimated": 1.0}, lines=lines)
    if prefilter_hz is None:
        return result
    return replace(result, prefilter_hz=float(prefilter_hz))


def warm_start(result: Estimate) -> tuple[float, ...]:
    """τ1, τ2 (s) of an estimate, and its gain when it has one: a start for ``ml-eiv``."""
    gain = result.params.get("gain")
    if gain is None:
        return (result.tau1, result.tau2)
    return (result.tau1, result.tau2, gain)


def _dispatch(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    dt: float,
    method: str,
    phi: float,
    alpha: float | None,
    start: tuple[float, ...] | None,
    prefilter_hz: float | None = None,
) -> Estimate:
    """Run ``method`` on validated signals (pre-filtered at ``prefilter_hz`` when given)."""
    if method == "tdr-kee":
        return tdr_kee(first, second, dt, alpha)
    if method == "gamma-ls":
        return gamma_ls(first, second, dt)
    if method == "gamma-tls":
        return gamma_tls(first, second, dt)
    if method == "beta-ls":
        return beta_ls(first, second, dt)
    if method == "beta-tls":
        return beta_tls(first, second, dt)
    if method == "ml-eiv":
        return ml_eiv(first, second, dt, phi, start=start, prefilter_hz=prefilter_hz)
    return beta_gtls(first, second, dt, phi)
