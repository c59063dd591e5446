"""A whole record's gas temperature compensated with an extended model.

Each sensor's readings are turned into the readings a first-order sensor of the model's τ
would give of the same gas (:func:`~tcomp_core.effects.chain.first_order_reading`: the
effects' stages undone, a non-first-order lag re-lagged); the first-order reconstructions then
apply unchanged, the Kalman smoother or causal filter (:func:`tcomp_core.fusion.fuse`) with its
signal model and standard deviation, or Eq. (7). Where the data do not fix the level (a
``dynamics`` piece: a calibration, an unestablished radiation level) it is moved last to first
order's: the Kalman gas to the mean of the default path's gas (:func:`default_level_shift_c`,
what ``tcomp reconstruct`` publishes without options), else to the one the same
reconstruction gives with that effect left first order (:func:`level_shift_c`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..effects.chain import first_order_reading
from ..errors import TcompError
from ..fusion import FusionModel, FusionResult, fuse
from ..fusion.signal_model import ModelChoice
from ..lines import ForeignLine, line_free_pair
from .plan import OutputModel

__all__ = [
    "Compensated",
    "compensate",
    "default_level_shift_c",
    "default_path_gas",
    "equivalent_readings",
    "level_shift_c",
]


def equivalent_readings(
    model: OutputModel,
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Both sensors' readings as first-order sensors of τ1, τ2 would give them.

    Parameters
    ----------
    model : OutputModel
    time : ndarray, shape (N,)
        Sample times on the model's time base (``model.origin_s`` is the fitted record's
        start), s.
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C, sampled every ``dt`` seconds.
    dt : float

    Returns
    -------
    tuple of ndarray, shape (N,) each
        Degrees C, tc2 on tc1's scale when a calibration is applied, without the lines one
        sensor carried alone (``model.lines``) unless an applied interference took its own.
    """
    first, second = model.chains(time, dt)
    readings = first_order_reading(first, tc1, dt), first_order_reading(second, tc2, dt)
    if not model.lines or "interference" in model.applied():
        return readings
    return line_free_pair(*readings, dt, model.lines, (model.tau1, model.tau2))


@dataclass(frozen=True, kw_only=True)
class Compensated:
    """A gas temperature reconstructed with an output model.

    Attributes
    ----------
    gas, std : ndarray, shape (N,)
        Gas temperature and its standard deviation, degrees C; element k holds over
        ``[t_k, t_k+1)``, the last a one-step prediction.
    fusion : FusionResult
        The Kalman reconstruction of the equivalent readings (before the level rule).
    model : OutputModel
    readings : (ndarray, ndarray)
        The equivalent first-order readings, shape (N,) each.
    level_shift_c : float
        Degrees C added to keep the first-order level (a ``dynamics`` piece; else 0).
    """

    gas: NDArray[np.float64]
    std: NDArray[np.float64]
    fusion: FusionResult
    model: OutputModel
    readings: tuple[NDArray[np.float64], NDArray[np.float64]]
    level_shift_c: float = 0.0


def level_shift_c(
    model: OutputModel,
    gas: NDArray[np.float64],
    reconstruct: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]],
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
) -> float:
    """Degrees C that move ``gas`` to the first-order level (a ``dynamics`` piece applied).

    Which sensor's calibration is right the two signals cannot tell, nor a radiation level
    whose ratios are within their intervals of 0, so the level stays first order's:
    ``reconstruct`` (the same reconstruction that made ``gas``, from
    two equivalent readings) is run on the readings of the model with those effects left
    first order (:meth:`OutputModel.level_reference`) and the mean difference returned.

    Returns
    -------
    float
        0 without a ``dynamics`` piece.
    """
    if not model.keeps_first_order_level:
        return 0.0
    reference = reconstruct(*equivalent_readings(model.level_reference(), time, tc1, tc2, dt))
    return _mean_offset(reference, gas)


def _mean_offset(reference: NDArray[np.float64], gas: NDArray[np.float64]) -> float:
    """Mean of ``reference - gas`` over their common start where both are finite, degrees C.

    NaN where no sample is finite in both.
    """
    count = min(gas.size, reference.size)
    difference = reference[:count] - gas[:count]
    finite = difference[np.isfinite(difference)]
    return float(np.mean(finite)) if finite.size else math.nan


def default_path_gas(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    taus: tuple[float, float],
    lines: Sequence[ForeignLine] = (),
    signal_model: ModelChoice = "auto",
    causal: bool = False,
) -> NDArray[np.float64]:
    """The gas ``tcomp reconstruct`` publishes without options, shape (N,), degrees C.

    The default path's first order: ``lines`` (found by its ml-eiv estimate) taken off the
    sensor that carries them, then the Kalman smoother (or with ``causal`` the filter) at its
    τ (``taus``, s), its signal model fitted to the readings.

    Raises
    ------
    TcompError
        As :func:`tcomp_core.fusion.fuse` raises it.
    """
    readings = line_free_pair(tc1, tc2, dt, lines, taus)
    return fuse(*readings, dt, taus[0], taus[1], model=signal_model, causal=causal).gas


def default_level_shift_c(
    model: OutputModel,
    gas: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    causal: bool = False,
    signal_model: ModelChoice | FusionModel = "auto",
) -> float | None:
    """Degrees C that move a Kalman ``gas`` to the mean of the default path's gas, or None.

    Which sensor's calibration is right the two signals cannot tell, so a ``dynamics`` piece
    leaves the level to first order; the first order a user has is the default path's: its
    τ (:attr:`OutputModel.first_order_taus`), its lines off the sensor that carries them and
    the same Kalman reconstruction (the smoother, or with ``causal`` the filter), each with
    its own signal model (``signal_model`` when it is a choice, as ``--signal-model`` gives
    it to both; a fitted model belongs to the equivalent readings, so the default path fits
    its own). Two first-order reconstructions at other τ, or fused with another
    signal model, weigh the sensors otherwise at low frequency, and where the sensors
    disagree by tens of degrees in level that moved the gas by degrees (campaign draw 10176:
    3.6 °C below ``tcomp reconstruct``'s, its error 20.2 -> 27.5 %).

    Returns
    -------
    float or None
        The shift; None without a ``dynamics`` piece, without the default path's τ, or where
        its reconstruction fails (the caller then keeps :func:`level_shift_c`'s rule).
    """
    taus = model.first_order_taus
    if not model.keeps_first_order_level or taus is None:
        return None
    choice = signal_model if isinstance(signal_model, str) else "auto"
    try:
        default = default_path_gas(tc1, tc2, dt, taus, model.lines, choice, causal)
    except (TcompError, ValueError, np.linalg.LinAlgError):
        return None
    shift = _mean_offset(default, gas)
    return None if math.isnan(shift) else shift


def compensate(
    model: OutputModel,
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    *,
    signal_model: ModelChoice | FusionModel = "auto",
    causal: bool = False,
) -> Compensated:
    """The Kalman-fused gas temperature of a record under ``model``.

    Parameters
    ----------
    model : OutputModel
    time, tc1, tc2, dt
        As :func:`equivalent_readings`.
    signal_model : str or FusionModel
        Passed to :func:`tcomp_core.fusion.fuse` (fitted to the equivalent readings).
    causal : bool
        The forward Kalman filter alone instead of the smoother (the equivalent readings of
        a delay still look a delay ahead on tc2).

    Returns
    -------
    Compensated
    """
    readings = equivalent_readings(model, time, tc1, tc2, dt)
    fusion = fuse(
        readings[0], readings[1], dt, model.tau1, model.tau2, model=signal_model, causal=causal
    )
    shift = default_level_shift_c(model, fusion.gas, tc1, tc2, dt, causal, signal_model)
    if shift is None:
        shift = level_shift_c(
            model,
            fusion.gas,
            lambda first, second: (
                fuse(
                    first, second, dt, model.tau1, model.tau2, model=fusion.model, causal=causal
                ).gas
            ),
            time,
            tc1,
            tc2,
            dt,
        )
    return Compensated(
        gas=fusion.gas + shift,
        std=fusion.std,
        fusion=fusion,
        model=model,
        readings=readings,
        level_shift_c=shift,
    )
