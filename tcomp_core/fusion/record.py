"""Fusion of a whole record: the signal model fitted, then the smoother or the causal filter."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import EstimationError
from ..validation import check_pair
from .causal import CausalFuser
from .fitting import FIT_FAILURES, SignalModelFits, fit_signal_models
from .signal_model import FusionModel, ModelChoice
from .smoother import smoothed_gas

__all__ = ["FusionResult", "fuse", "run_model"]


@dataclass(frozen=True, kw_only=True)
class FusionResult:
    """Gas temperature fused from two thermocouples.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Start of the interval over which each gas sample holds, seconds.
    gas : ndarray, shape (N,)
        Estimated gas temperature, degrees C. Element N-1 is a one-step prediction.
    std : ndarray, shape (N,)
        Standard deviation of each estimate under the model, degrees C.
    model : FusionModel
        The model used, with its hyper-parameters.
    log_likelihood : float
        Log-likelihood of the innovations under ``model``, nats.
    candidates : dict of str to float
        Log-likelihood of each signal model fitted (empty when the model was given).
    causal : bool
        Whether ``gas`` comes from the forward (causal) filter rather than the smoother.
    note : str
        Signal models that could not be fitted or used, and which one was used instead ('' when
        the model asked for was used).
    misfit_warning : str
        How far the readings depart from the first-order model at the τ given, when that is
        material ('' otherwise, and when the model was given): ``std`` holds that departure
        (:attr:`FusionModel.misfit_c`), the gas does not correct it.
    """

    time: NDArray[np.float64]
    gas: NDArray[np.float64]
    std: NDArray[np.float64]
    model: FusionModel
    log_likelihood: float
    candidates: dict[str, float] = field(default_factory=dict)
    causal: bool = False
    note: str = ""
    misfit_warning: str = ""

    @property
    def kind(self) -> str:
        """Signal model used."""
        return self.model.kind

    @property
    def q(self) -> float:
        """Process noise intensity of the model (see :class:`FusionModel`)."""
        return self.model.q


def fuse(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    sigma1: float | None = None,
    sigma2: float | None = None,
    model: ModelChoice | FusionModel = "auto",
    causal: bool = False,
) -> FusionResult:
    """Fused gas temperature from both thermocouples: RTS smoother or causal Kalman filter.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C, sampled every ``dt``.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds.
    sigma1, sigma2 : float, optional
        Noise standard deviations, degrees C; measured from the model
        (:func:`tcomp_core.noise.model_noise`) when omitted.
    model : str or FusionModel
        'auto' or a signal model name, fitted by maximum likelihood
        (:func:`fit_signal_models`), or a :class:`FusionModel` used as it is (its dt, τ and σ
        then replace the arguments). A model that cannot be fitted, or whose reconstruction is
        not finite, gives way to the next likeliest (``note`` says so).
    causal : bool
        Run the forward Kalman filter only: element k then depends on samples 0..k+1 alone,
        once the model is fixed. With a model name the hyper-parameters are still fitted on
        the whole record; pass a :class:`FusionModel` for a strictly causal run.

    Returns
    -------
    FusionResult
        Gas estimate and its standard deviation, shape (N,); element k is the gas temperature
        over ``[t_k, t_{k+1})``.

    Raises
    ------
    EstimationError
        When no signal model can be fitted and used (Eq. 7 still can: the caller's fallback).
    """
    first, second = check_pair(tc1, tc2)
    if isinstance(model, FusionModel):
        gas, std, log_likelihood = run_model(model, first, second, causal)
        if gas is None:
            raise EstimationError(
                f"the Kalman reconstruction with the {model.kind} signal model is numerically "
                "unstable on this record (non-finite output); choose another signal model"
            )
        return FusionResult(
            time=np.arange(first.size, dtype=np.float64) * model.dt,
            gas=gas,
            std=std,
            model=model,
            log_likelihood=log_likelihood,
            causal=causal,
        )
    fits = fit_signal_models(
        first, second, dt, tau1, tau2, sigma1=sigma1, sigma2=sigma2, model=model
    )
    failures, unstable = dict(fits.failures), []
    for fitted, _ in fits.ranked:
        gas, std, log_likelihood = run_model(fitted, first, second, causal)
        if gas is None:
            failures[fitted.kind] = "numerically unstable on this record (non-finite output)"
            unstable.append(fitted.kind)
            continue
        note = SignalModelFits(fits.ranked, failures, fits.requested).note(fitted.kind)
        if unstable and fits.requested == "auto":  # the likelier ones were fitted but failed
            note = "; ".join(
                [
                    *filter(None, [note]),
                    f"{', '.join(unstable)} numerically unstable on this "
                    f"record (non-finite output): {fitted.kind} used instead",
                ]
            )
        return FusionResult(
            time=np.arange(first.size, dtype=np.float64) * fitted.dt,
            gas=gas,
            std=std,
            model=fitted,
            log_likelihood=log_likelihood,
            candidates=fits.candidates,
            causal=causal,
            note=note,
            misfit_warning=fits.misfit_warning,
        )
    reasons = SignalModelFits([], failures, fits.requested).note(None)
    raise EstimationError(f"no signal model of the gas could be used: {reasons}")


def run_model(
    model: FusionModel, first: NDArray[np.float64], second: NDArray[np.float64], causal: bool
) -> tuple[NDArray[np.float64] | None, NDArray[np.float64], float]:
    """Gas, std and log-likelihood of the smoother or causal filter (gas None: not finite)."""
    try:
        if causal:
            fuser = CausalFuser(model)
            gas, std = fuser.extend(first, second)
            ahead, ahead_std = fuser.predict()
            gas, std = np.append(gas, ahead), np.append(std, ahead_std)
            log_likelihood = fuser.log_likelihood
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                gas, std, log_likelihood = smoothed_gas(model, first, second)
    except FIT_FAILURES:
        return None, np.empty(0), -np.inf
    if not (np.all(np.isfinite(gas)) and np.all(np.isfinite(std))):
        return None, np.empty(0), -np.inf
    return gas, std, log_likelihood
