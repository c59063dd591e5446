"""Where a fitted model fails: statistics of its free-run residual.

The residual of a model that captures the physics is white noise, uncorrelated with the input
and with the temperature level, spread over the spectrum like the noise and steady over time.
Each departure points somewhere:

* autocorrelation outside the white-noise bound (Ljung–Box): the model misses some dynamics;
* correlation with the fast sensor's rate of change at a lag: a delay or a wrong time constant;
* a slope or curvature against the temperature level: calibration or radiation;
* time constants of both sensors drifting together over the record: a velocity change;
* residual power in a narrow frequency band: dynamics missing in that band (conduction when
  it is slow).

The series compared here are autocorrelated (the residual of a smooth model error, the rate of
a smooth signal), so the usual white-noise bound ±z/√N of a cross-correlation is far too
narrow. The bounds use Bartlett's formula instead (Box, Jenkins & Reinsel, *Time Series
Analysis*, §11.1.3): for two series uncorrelated with each other

    var r_xy(k) ≈ (1/N) Σ_j ρ_xx(j) ρ_yy(j),

summed over the lags where the autocorrelations are not negligible: the sum is cut where its
partial sum is largest (see :func:`.correlation._variance_factor`).

Modules: :mod:`.correlation` (autocorrelation, cross-correlation, candidate signals),
:mod:`.windows` (error and time constants per window), :mod:`.spectrum` (residual per band),
:mod:`.level` (residual against the temperature level), :mod:`.findings` (the sentences) and
:mod:`.analysis` (:func:`analyse_failure`, all of them together); :mod:`.common` holds the
helpers they share.
"""

from __future__ import annotations

from .analysis import FailureAnalysis, analyse_failure
from .correlation import (
    Autocorrelation,
    CandidateCorrelation,
    CrossCorrelation,
    autocorrelation,
    candidate_correlations,
    cross_correlation,
)
from .level import LevelErrors, level_errors
from .spectrum import BandErrors, band_errors
from .windows import WindowedError, WindowedTau, default_window_s, windowed_error, windowed_tau

__all__ = [
    "Autocorrelation",
    "BandErrors",
    "CandidateCorrelation",
    "CrossCorrelation",
    "FailureAnalysis",
    "LevelErrors",
    "WindowedError",
    "WindowedTau",
    "analyse_failure",
    "autocorrelation",
    "band_errors",
    "candidate_correlations",
    "cross_correlation",
    "default_window_s",
    "level_errors",
    "windowed_error",
    "windowed_tau",
]
