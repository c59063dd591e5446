"""Choice of the signal model and its hyper-parameters by maximum likelihood.

Hyper-parameters are chosen by maximising the likelihood of the Kalman innovations
(:mod:`scipy.optimize` on their logarithms), and the model by that likelihood less its number
of hyper-parameters (Akaike). The noise levels σ_i come from the model
(:func:`tcomp_core.noise.model_noise`) unless given.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg
import scipy.optimize
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from ..errors import EstimationError
from ..models import lag_frequency_response, tau_to_pole
from ..noise import model_noise
from ..reconstruct import Reconstruction, reconstruct
from ..validation import check_pair, check_sample_interval
from .adequacy import Misfit, first_order_misfit
from .kalman import innovation_log_likelihood
from .signal_model import MODELS, FusionModel, ModelChoice, ModelKind, butterworth_unit_variance

__all__ = [
    "FIT_FAILURES",
    "QUICK_MODELS",
    "SignalModelFits",
    "first_order_adequacy",
    "fit_fusion_model",
    "fit_signal_models",
]

#: Smallest noise standard deviation used, as a fraction of the signal's standard deviation:
#: keeps the Riccati equation well posed on noise-free data.
MIN_RELATIVE_SIGMA = 1e-6
#: Search range of log10(q / q_ref) (q_ref = gas variance / dt^order, order 1 or 3), and of
#: the level's intensity likewise.
LOG10_Q_RANGE = (-14.0, 6.0)
#: Search range of log10 of a stationary signal variance relative to the data's.
VARIANCE_RANGE = (-8.0, 4.0)
#: Starting value of log10(q dt / gas variance) of the periodic model's resonator.
PERIODIC_START = -6.0
#: Starting value of log10(level_q dt / gas variance).
LEVEL_START = -10.0
#: Initial simplex edge of the Nelder–Mead searches, in log10 units.
SIMPLEX_STEP = 0.3
#: Cost reported to the optimisers where the likelihood cannot be evaluated.
FAILED_COST = 1e15
#: Half-width of the maximum-likelihood frequency search around the spectral line, in
#: periodogram bins (the least-squares line frequency is much closer than that).
FREQUENCY_SPAN = 0.02
#: Butterworth orders of the band-limited model tried by the maximum-likelihood fit.
BAND_LIMITED_ORDERS = (2, 4, 8)
#: Search range of the band-limited model's cut-off as a fraction of the Nyquist frequency.
CUTOFF_RANGE = (1e-3, 0.9)
#: Models ``auto`` compares: all of them.
AUTO_MODELS: tuple[ModelKind, ...] = MODELS
#: The models whose fits take a fraction of a second: all but the band-limited one (its cut-off
#: scan and three orders take seconds). A stream's first fit compares these, the next all.
QUICK_MODELS: tuple[ModelKind, ...] = tuple(kind for kind in MODELS if kind != "band-limited")
#: Orders of the autoregressive model of the gas's changes tried (Akaike chooses).
AR_ORDERS = (8, 16, 24, 32)
#: Search range of log10(q / q_YW), q_YW the Yule–Walker innovation variance.
AR_SCALE_RANGE = (-3.0, 3.0)
#: Floor of the gas-change spectrum the autoregression is fitted to, relative to its peak.
AR_SPECTRUM_FLOOR = 1e-6
#: Largest modulus of an autoregression's roots accepted (an order with a root closer to the
#: unit circle is skipped: its smoother is numerically unstable).
AR_MAX_ROOT = 1.0 - 1e-4
#: Samples per Welch segment of the gas spectrum the autoregressive model is fitted to.
AR_SEGMENT = 1024


def _dominant_frequency(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> float:
    """Frequency of the strongest spectral line relative to the noise floor, Hz.

    The Hann-windowed periodograms' signal-to-noise ratios of the two sensors are summed; the
    peak bin is refined to the frequency of the least-squares sinusoid fitted to the Eq. (7)
    reconstruction (which, unlike the readings, carries no start-up transient of the sensors),
    as a narrow resonator needs it to a small fraction of a bin.
    """
    count = first.size
    freqs = np.fft.rfftfreq(count, base.dt)
    window = np.hanning(count)
    excess = np.zeros(freqs.size)
    for values, sigma in ((first, base.sigma1), (second, base.sigma2)):
        power = np.abs(np.fft.rfft((values - values.mean()) * window)) ** 2
        excess += power / (sigma**2 * np.sum(window**2))
    excess[0] = 0.0
    peak = max(int(np.argmax(excess[: freqs.size - 1])), 1)
    gas = _reconstruction(first, second, base).gas
    time = np.arange(gas.size) * base.dt
    best = scipy.optimize.minimize_scalar(
        lambda frequency: _sinusoid_residual(gas, time, frequency),
        bounds=(freqs[peak - 1], freqs[peak + 1]),
        method="bounded",
        options={"xatol": 1e-7 * freqs[1]},
    )
    return float(best.x)


def _sinusoid_residual(values: NDArray[np.float64], time: NDArray, frequency: float) -> float:
    """Residual sum of squares of ``values`` about a least-squares sinusoid at ``frequency``."""
    phase = 2.0 * np.pi * frequency * time
    basis = np.stack((np.ones_like(time), np.cos(phase), np.sin(phase)))
    normal = np.einsum("ik,jk->ij", basis, basis)
    projection = np.einsum("ik,k->i", basis, values)
    coefficients = np.linalg.solve(normal, projection)
    return float(values @ values - coefficients @ projection)


#: Logarithms (base 10) of a model's hyper-parameters, as the optimisers vary them.
Theta = Sequence[float] | NDArray[np.float64]


@dataclass(frozen=True)
class _Fitting:
    """Data and scales shared by the maximum-likelihood fits of one record.

    Attributes
    ----------
    base : FusionModel
        Carries dt, τ and σ.
    y : ndarray, shape (2, N)
        Readings less their mean level, degrees C.
    scale : float
        Gas temperature variance estimated from the Eq. (7) reconstruction less its noise, °C².
    freq_hz : float
        Strongest spectral line, Hz.
    misfit : Misfit
        How far the readings depart from the first-order model at these τ (its excess is
        ``base.misfit_c``).
    """

    base: FusionModel
    y: NDArray[np.float64]
    scale: float
    freq_hz: float
    misfit: Misfit
    _costs: dict[FusionModel, float] = field(default_factory=dict, compare=False, repr=False)

    def cost(self, model: FusionModel) -> float:
        """Negative log-likelihood, nats (finite, for the optimisers).

        Remembered per model: a search starts where a scan already evaluated, and the fitted
        models are compared again at their optima (about one evaluation in thirty).
        """
        known = self._costs.get(model)
        if known is None:
            known = self._costs[model] = min(
                -innovation_log_likelihood(model, self.y), FAILED_COST
            )
        return known


def _random_walk_model(fit: _Fitting, kind: ModelKind, theta: Theta) -> FusionModel:
    """θ = log10(q dt^order / scale)."""
    order = 3 if kind == "integrated-random-walk" else 1
    return replace(fit.base, kind=kind, q=float(fit.scale / fit.base.dt**order * 10.0 ** theta[0]))


def _band_limited_model(fit: _Fitting, theta: Theta, order: int = 2) -> FusionModel:
    """θ = log10 of (variance / scale, cut-off / Nyquist frequency, level_q dt / scale)."""
    cutoff = 0.5 / fit.base.dt * 10.0 ** theta[1]
    unit = butterworth_unit_variance(order, 2.0 * math.pi * cutoff)
    return replace(
        fit.base,
        kind="band-limited",
        q=float(fit.scale * 10.0 ** theta[0] / unit),
        freq_hz=float(cutoff),
        level_q=float(fit.scale / fit.base.dt * 10.0 ** theta[2]),
        order=order,
    )


def _periodic_model(fit: _Fitting, theta: Theta) -> FusionModel:
    """θ = log10 of (q dt / scale, level_q dt / scale)."""
    return replace(
        fit.base,
        kind="periodic",
        q=float(fit.scale / fit.base.dt * 10.0 ** theta[0]),
        freq_hz=fit.freq_hz,
        level_q=float(fit.scale / fit.base.dt * 10.0 ** theta[1]),
    )


def _fit_random_walk(fit: _Fitting, kind: ModelKind) -> FusionModel:
    """Brent's method on log10 q."""
    best = scipy.optimize.minimize_scalar(
        lambda t: fit.cost(_random_walk_model(fit, kind, [t])),
        bounds=LOG10_Q_RANGE,
        method="bounded",
        options={"xatol": 1e-3},
    )
    return _random_walk_model(fit, kind, [best.x])


def _polish(
    fit: _Fitting,
    build: Callable[[_Fitting, Theta], FusionModel],
    start: NDArray[np.float64],
    bounds: list[tuple[float, float]],
) -> FusionModel:
    """Nelder–Mead on the log10 hyper-parameters from ``start``.

    The tolerances (0.1 in log10, 0.05 nats) are far below what changes the estimate.
    """

    def cost(theta: NDArray[np.float64]) -> float:
        return fit.cost(build(fit, theta))

    simplex = np.vstack((start, start + SIMPLEX_STEP * np.eye(start.size)))
    best = scipy.optimize.minimize(
        cost,
        start,
        method="Nelder-Mead",
        bounds=bounds,
        options={"xatol": 0.1, "fatol": 0.05, "initial_simplex": simplex, "maxfev": 150},
    )
    return build(fit, best.x)


def _fit_band_limited(fit: _Fitting) -> FusionModel:
    """Each order of :data:`BAND_LIMITED_ORDERS` fitted; the likelier kept."""
    return min((_fit_butterworth(fit, order) for order in BAND_LIMITED_ORDERS), key=fit.cost)


def _fit_butterworth(fit: _Fitting, order: int) -> FusionModel:
    """Scan of the cut-off at the data's variance, then all three settings polished."""

    def build(fitting: _Fitting, theta: Theta) -> FusionModel:
        return _band_limited_model(fitting, theta, order)

    low, high = (math.log10(limit) for limit in CUTOFF_RANGE)
    cutoffs = np.linspace(low, high, 10)
    costs = [fit.cost(build(fit, [0.0, c, LEVEL_START])) for c in cutoffs]
    start = np.array([0.0, cutoffs[int(np.argmin(costs))], LEVEL_START])
    bounds = [VARIANCE_RANGE, (low, high), LOG10_Q_RANGE]
    return _polish(fit, build, start, bounds)


def _fit_periodic(fit: _Fitting) -> FusionModel:
    """Maximum-likelihood settings of the periodic model.

    Drive and level intensities by Nelder–Mead, then the frequency refined by Brent's method
    within a few hundredths of a periodogram bin.
    """
    start = np.array([PERIODIC_START, LEVEL_START])
    bounds = [LOG10_Q_RANGE, LOG10_Q_RANGE]
    model = _polish(fit, _periodic_model, start, bounds)
    span = FREQUENCY_SPAN / (fit.y.shape[1] * fit.base.dt)
    best = scipy.optimize.minimize_scalar(
        lambda frequency: fit.cost(replace(model, freq_hz=frequency)),
        # A line within a bin of 0 Hz: the search stays above half its frequency.
        bounds=(max(model.freq_hz - span, 0.5 * model.freq_hz), model.freq_hz + span),
        method="bounded",
        options={"xatol": 1e-4 * span},
    )
    return replace(model, freq_hz=float(best.x))


def _gas_change_autocovariance(fit: _Fitting) -> NDArray[np.float64]:
    """Autocovariance of the gas's sample-to-sample change d_k, °C², lags 0..``AR_SEGMENT``/2.

    The gas spectrum comes from the cross-spectrum of the two readings, which their
    independent noises do not bias: E[conj(Y1) Y2] = conj(G1) G2 S_g, so S_g is its
    component along the phase of conj(G1) G2 divided by |G1 G2| (negative estimates set
    to zero, as are bins where it does not stand two standard errors above the noise, so the
    stop band of a band-limited gas stays empty). The change's spectrum is S_g |1 - e^(-iω)|².
    """
    count = fit.y.shape[1]
    nperseg = int(min(AR_SEGMENT, max(32, count // 4), count))
    freqs, cross = signal.csd(fit.y[0], fit.y[1], fs=1.0 / fit.base.dt, nperseg=nperseg)
    omega = 2.0 * math.pi * freqs * fit.base.dt
    poles = tau_to_pole([fit.base.tau1, fit.base.tau2], fit.base.dt)
    g1, g2 = (lag_frequency_response(float(a), omega) for a in poles)
    shared = np.conj(g1) * g2
    along = np.real(cross * np.conj(shared)) / np.abs(shared)  # |G1 G2| S_g plus noise
    # Noise of that component per bin: sqrt(S11 S22 / (2 K)), K Welch segments (about
    # count / (nperseg / 2) with half overlap); bins within two of it hold no gas signal.
    _, auto1 = signal.welch(fit.y[0], fs=1.0 / fit.base.dt, nperseg=nperseg)
    _, auto2 = signal.welch(fit.y[1], fs=1.0 / fit.base.dt, nperseg=nperseg)
    segments = max(1.0, count / (0.5 * nperseg) - 1.0)
    threshold = 2.0 * np.sqrt(auto1 * auto2 / (2.0 * segments))
    gas = np.where(along > threshold, along, 0.0) / np.abs(shared)
    change = gas * 4.0 * np.sin(0.5 * omega) ** 2
    # A floor far below the peak keeps the Toeplitz system of Yule–Walker well conditioned and
    # the autoregression's roots off the unit circle, where the smoother would blow up.
    change = change + AR_SPECTRUM_FLOOR * float(np.max(change))
    # One-sided density (°C²/Hz) to autocovariance: r_k = ∫ S(f) cos(2π f k dt) df.
    return np.fft.irfft(change) / (2.0 * fit.base.dt)


def _autoregressive_model(
    fit: _Fitting, coefficients: NDArray[np.float64], reference: float, theta: Theta
) -> FusionModel:
    """θ = log10(q / reference)."""
    return replace(
        fit.base,
        kind="autoregressive",
        ar=tuple(float(c) for c in coefficients),
        q=float(reference * 10.0 ** theta[0]),
    )


def _fit_autoregressive(fit: _Fitting) -> FusionModel:
    """Yule–Walker coefficients per order of :data:`AR_ORDERS`, innovation variance by ML.

    The orders are compared by likelihood less their number of settings (Akaike).
    """
    autocovariance = _gas_change_autocovariance(fit)
    if not autocovariance[0] > 0.0:
        raise ValueError("the readings share no gas signal to fit an autoregressive model to")
    best: tuple[float, FusionModel] | None = None
    for order in AR_ORDERS:
        if order >= autocovariance.size - 1:
            break
        coefficients = scipy.linalg.solve_toeplitz(
            autocovariance[:order], autocovariance[1 : order + 1]
        )
        roots = np.roots(np.concatenate(([1.0], -coefficients)))
        if not np.max(np.abs(roots)) <= AR_MAX_ROOT:
            continue
        reference = max(
            float(autocovariance[0] - coefficients @ autocovariance[1 : order + 1]),
            1e-12 * float(autocovariance[0]),
        )
        try:
            result = scipy.optimize.minimize_scalar(
                lambda t, c=coefficients, r=reference: fit.cost(
                    _autoregressive_model(fit, c, r, [t])
                ),
                bounds=AR_SCALE_RANGE,
                method="bounded",
                options={"xatol": 1e-2},
            )
            model = _autoregressive_model(fit, coefficients, reference, [result.x])
        except ValueError:  # a numerically non-stationary Yule–Walker solution
            continue
        score = float(result.fun) + model.n_hyperparameters  # the cost at result.x
        if best is None or score < best[0]:
            best = (score, model)
    if best is None:
        raise ValueError("no stationary autoregressive model of the gas could be fitted")
    return best[1]


def _fit_kind(fit: _Fitting, kind: ModelKind) -> FusionModel:
    if kind == "band-limited":
        return _fit_band_limited(fit)
    if kind == "periodic":
        return _fit_periodic(fit)
    if kind == "autoregressive":
        return _fit_autoregressive(fit)
    return _fit_random_walk(fit, kind)


def _reconstruction(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> Reconstruction:
    """The paper's inverse-variance weighted Eq. (7) reconstruction (no post-filter)."""
    phi = (base.sigma1 / base.sigma2) ** 2
    return reconstruct(first, second, base.dt, base.tau1, base.tau2, phi=phi)


def _gas_variance(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> float:
    """Variance of the gas temperature: the Eq. (7) reconstruction's less its noise, °C²."""
    reconstruction = _reconstruction(first, second, base)
    poles = tau_to_pole([base.tau1, base.tau2], base.dt)
    noise = np.array([base.sigma1, base.sigma2]) ** 2 * (1.0 + poles**2) / (1.0 - poles) ** 2
    weights = np.array([reconstruction.weight1, 1.0 - reconstruction.weight1])
    total = float(np.var(reconstruction.gas))
    return max(total - float(weights**2 @ noise), 1e-6 * total, 1e-12)


def _noise_sigmas(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    base: tuple[float, float, float],
    sigma1: float | None,
    sigma2: float | None,
) -> tuple[float, float]:
    """Noise standard deviations, from the model unless given, with a floor.

    ``base`` is (dt, τ1, τ2): the levels come from :func:`tcomp_core.noise.model_noise`,
    which removes the gas signal the two spectra share (a spectral floor alone reads the
    leakage of sharp edges as noise on the fast sensor).
    """
    measured: tuple[float | None, float | None] = (None, None)
    if sigma1 is None or sigma2 is None:
        noise1, noise2 = model_noise(first, second, *base)
        measured = (noise1.sigma, noise2.sigma)
    sigmas = []
    for values, given, found in ((first, sigma1, measured[0]), (second, sigma2, measured[1])):
        sigma = float(given) if given is not None else float(found)  # type: ignore[arg-type]
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"noise standard deviation {sigma!r} must be finite and >= 0")
        floor = MIN_RELATIVE_SIGMA * max(float(np.std(values)), 1e-9)
        sigmas.append(max(sigma, floor))
    return sigmas[0], sigmas[1]


@dataclass(frozen=True)
class SignalModelFits:
    """Signal models fitted to one record by maximum likelihood, best first.

    Attributes
    ----------
    ranked : list of (FusionModel, float)
        The models that could be fitted and their log-likelihoods (nats), by log-likelihood less
        their number of hyper-parameters (Akaike), best first.
    failures : dict of str to str
        Why each model that could not be fitted failed.
    requested : str
        The model asked for ('auto' or a name).
    misfit : Misfit or None
        How far the readings depart from the first-order model at the τ given (None when the
        record could not be prepared).
    gas_std_c : float
        Standard deviation of the gas estimated from the readings, degrees C (NaN when
        unknown).
    """

    ranked: list[tuple[FusionModel, float]]
    failures: dict[str, str]
    requested: str
    misfit: Misfit | None = None
    gas_std_c: float = math.nan

    @property
    def misfit_warning(self) -> str:
        """The first-order model's misfit in a sentence, when material ('' otherwise)."""
        if self.misfit is None or not self.misfit.material(self.gas_std_c):
            return ""
        return self.misfit.describe(self.gas_std_c)

    @property
    def candidates(self) -> dict[str, float]:
        """Log-likelihood of every model fitted, nats."""
        return {model.kind: value for model, value in self.ranked}

    def note(self, used: str | None) -> str:
        """What the fit could not do and what was used instead ('' when nothing to say).

        Parameters
        ----------
        used : str or None
            The kind of the model used (None: none could be).
        """
        # 'auto' compares what can be fitted; a candidate that cannot is news only when it was
        # asked for by name, or when nothing could be used.
        failures = self.failures if self.requested != "auto" or used is None else {}
        parts = [f"{kind} not fitted ({reason})" for kind, reason in failures.items()]
        if used is not None and self.requested not in ("auto", used):
            parts.append(f"{used} used instead of {self.requested}")
        return "; ".join(parts)


#: Failures of one signal model's fit that leave the others to try.
FIT_FAILURES = (ValueError, ArithmeticError, np.linalg.LinAlgError)


def fit_signal_models(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    sigma1: float | None = None,
    sigma2: float | None = None,
    model: ModelChoice = "auto",
    fallback: bool = True,
    auto_models: tuple[ModelKind, ...] = AUTO_MODELS,
) -> SignalModelFits:
    """Fit the signal model asked for (or every one, 'auto') and rank what could be fitted.

    A model whose fit fails (a non-stationary autoregression, a Riccati equation without a
    stabilising solution, ...) is left out and its reason kept; with ``fallback`` a named
    model that fails is replaced by the others, ranked as 'auto' ranks them.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds.
    sigma1, sigma2 : float, optional
        Noise standard deviations, degrees C; measured from the model
        (:func:`tcomp_core.noise.model_noise`) when omitted.
    model : {'auto', 'random-walk', 'integrated-random-walk', 'band-limited', 'periodic', \
'autoregressive'}
        Signal model; 'auto' fits those of :data:`AUTO_MODELS`.
    fallback : bool
        Fit the others when a named model fails.
    auto_models : tuple of str
        The models 'auto' (and a fallback) fits: all by default; :data:`QUICK_MODELS` for a
        first fit in a fraction of the time.

    Returns
    -------
    SignalModelFits
        ``ranked`` may be empty: then no model could be fitted (``failures`` says why).

    Raises
    ------
    ValueError
        On an unknown model name or data that do not form a record.
    """
    first, second = check_pair(tc1, tc2)
    dt = check_sample_interval(dt)
    if model != "auto" and model not in MODELS:
        raise ValueError(f"model={model!r} is not 'auto' or one of {', '.join(MODELS)}")
    for name, tau in (("tau1", tau1), ("tau2", tau2)):
        if not (math.isfinite(tau) and tau > 0.0):
            raise ValueError(f"{name}={tau!r} s must be finite and > 0")
    for name, given in (("sigma1", sigma1), ("sigma2", sigma2)):
        if given is not None and not (math.isfinite(given) and given >= 0.0):
            raise ValueError(f"{name}={given!r}: a noise standard deviation must be >= 0")
    failures: dict[str, str] = {}
    try:
        fit = _prepare(first, second, dt, tau1, tau2, sigma1, sigma2)
    except FIT_FAILURES as exc:
        return SignalModelFits([], {model: f"no noise levels or gas variance: {exc}"}, model)
    fitted: list[tuple[FusionModel, float]] = []
    kinds: tuple[ModelKind, ...] = auto_models if model == "auto" else (model,)
    for attempt in (kinds, tuple(k for k in auto_models if k != model)):
        for kind in attempt:
            try:
                candidate = _fit_kind(fit, kind)
            except FIT_FAILURES as exc:
                failures[kind] = str(exc) or type(exc).__name__
                continue
            log_likelihood = -fit.cost(candidate)
            if log_likelihood <= -FAILED_COST:
                failures[kind] = "its Kalman filter has no steady state on this record"
                continue
            fitted.append((candidate, log_likelihood))
        if fitted or model == "auto" or not fallback:
            break
    fitted.sort(key=lambda item: item[1] - item[0].n_hyperparameters, reverse=True)
    return SignalModelFits(
        fitted, failures, model, misfit=fit.misfit, gas_std_c=math.sqrt(fit.scale)
    )


#: Most samples the likelihood of a signal model is evaluated on. Its few hyper-parameters
#: are fixed long before (the likelihood's curvature grows with N), while each evaluation
#: refilters the stretch: the smoother of a 160 000-sample record took 34 s, 16 s with it.
MAX_LIKELIHOOD_SAMPLES = 2**16


def _likelihood_stretch(n: int) -> slice:
    """The middle :data:`MAX_LIKELIHOOD_SAMPLES` of ``n`` samples (all of a shorter record)."""
    start = max(0, (n - MAX_LIKELIHOOD_SAMPLES) // 2)
    return slice(start, start + MAX_LIKELIHOOD_SAMPLES)


def first_order_adequacy(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
) -> tuple[Misfit, float]:
    """Whether the first-order model at τ1, τ2 describes a pair of readings.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C, every ``dt`` seconds.
    dt : float
        Sample interval, s.
    tau1, tau2 : float
        The first-order model's time constants, s.

    Returns
    -------
    misfit : Misfit
        The sensors' first-order disagreement beyond their noise
        (:func:`~.adequacy.first_order_misfit`, noise levels from the model).
    gas_std_c : float
        The gas's fluctuation (Eq. (7)'s reconstruction less its noise), degrees C:
        ``misfit.material(gas_std_c)`` says whether the model fails the record.
    """
    first = np.asarray(tc1, dtype=np.float64)
    second = np.asarray(tc2, dtype=np.float64)
    base, misfit = _first_order_base(first, second, dt, tau1, tau2, None, None)
    return misfit, math.sqrt(_gas_variance(first, second, base))


def _first_order_base(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
    sigma1: float | None,
    sigma2: float | None,
) -> tuple[FusionModel, Misfit]:
    """The first-order base model (noise levels, its misfit) and that misfit."""
    s1, s2 = _noise_sigmas(first, second, (dt, tau1, tau2), sigma1, sigma2)
    misfit = first_order_misfit(first, second, dt, tau1, tau2, s1, s2)
    base = FusionModel(
        kind="random-walk",
        dt=dt,
        tau1=tau1,
        tau2=tau2,
        sigma1=s1,
        sigma2=s2,
        q=1,
        misfit_c=misfit.excess_c,
    )
    return base, misfit


def _prepare(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
    sigma1: float | None,
    sigma2: float | None,
) -> _Fitting:
    """Noise levels, gas variance and spectral line shared by the fits of one record."""
    base, misfit = _first_order_base(first, second, dt, tau1, tau2, sigma1, sigma2)
    level = float(np.mean(first))
    likelihood = _likelihood_stretch(first.size)
    return _Fitting(
        base=base,
        y=np.vstack((first[likelihood] - level, second[likelihood] - level)),
        scale=_gas_variance(first, second, base),
        freq_hz=_dominant_frequency(first, second, base),
        misfit=misfit,
    )


def fit_fusion_model(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    sigma1: float | None = None,
    sigma2: float | None = None,
    model: ModelChoice = "auto",
) -> tuple[FusionModel, float, dict[str, float]]:
    """Choose the signal model and its hyper-parameters by maximum likelihood.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds.
    sigma1, sigma2 : float, optional
        Noise standard deviations, degrees C; measured from the model
        (:func:`tcomp_core.noise.model_noise`) when omitted.
    model : {'auto', 'random-walk', 'integrated-random-walk', 'band-limited', 'periodic', \
'autoregressive'}
        Signal model; 'auto' fits those of :data:`AUTO_MODELS` and keeps the one with the
        highest log-likelihood less its number of hyper-parameters (Akaike); a model that
        cannot be fitted is left out (:func:`fit_signal_models` says why).

    Returns
    -------
    model : FusionModel
    log_likelihood : float
        Of the chosen model, nats.
    candidates : dict of str to float
        Log-likelihood of every model fitted, nats.

    Raises
    ------
    EstimationError
        When the model named (or, for 'auto', every model) cannot be fitted.
    """
    fits = fit_signal_models(
        tc1, tc2, dt, tau1, tau2, sigma1=sigma1, sigma2=sigma2, model=model, fallback=False
    )
    if not fits.ranked:
        raise EstimationError(f"no signal model could be fitted: {fits.note(None)}")
    best, log_likelihood = fits.ranked[0]
    return best, log_likelihood, fits.candidates
