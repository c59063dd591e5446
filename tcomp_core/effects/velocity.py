"""A changing flow velocity: both time constants vary in time with a constant ratio.

Convective heat transfer grows with velocity, τi(t) = τi0 (v(t)/v0)^(−m), and the same v(t)
reaches both sensors, so τ1(t)/τ2(t) stays constant. The factor s(t) = τi(t)/τi0 is fitted as
exp of a cubic spline with knots every ``knot_spacing_s``, normalised to a geometric mean of 1 over
the record (τi0 are then the record's geometric-mean time constants). A second-difference
penalty keeps s(t) smooth across the held-out blocks between knots.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import BSpline

from ..errors import TcompError
from ..tracking import track_tau
from .base import Effect, FitContext, ParamSpec

__all__ = ["Velocity"]

_DEGREE = 3
#: Weights of the smoothness penalty per unit second difference of log s, relative to the
#: square root of the number of fitted rows, chosen between on held-out data: the stiffer one
#: interpolates the held-out blocks better when s(t) changes slowly, the softer one lets a
#: fast, strong change (a period of a few knot spacings) through.
SMOOTHNESS_CHOICES = (0.05, 0.01)
#: Least share of a spline coefficient's basis weight on the scored samples for a free-run
#: refinement to search it (:meth:`Velocity.unseen_parameters`).
UNSEEN_SHARE = 0.5
#: The simulator's flow: τ ∝ v^-m, the speed's relative swing and its period, s.
SIMULATED_EXPONENT = 0.6
SIMULATED_DEPTH = 0.4
SIMULATED_PERIOD_S = 6.0


def _basis(context: FitContext) -> NDArray[np.float64]:
    """The spline's design matrix at the context's sample times, shape (N, n + 1), read-only.

    Every model with the effect has its own :class:`Velocity`, and a diagnosis fits dozens of
    them on the same samples: the matrix (a millisecond each) is shared by the times' content.
    Two are kept (each is N × n floats; a diagnosis works on one record or window at a time).
    """
    time = np.ascontiguousarray(context.time, dtype=np.float64)
    return _design_matrix(time.tobytes(), float(context.knot_spacing_s))


@functools.lru_cache(maxsize=2)
def _design_matrix(time_bytes: bytes, knot_spacing_s: float) -> NDArray[np.float64]:
    time = np.frombuffer(time_bytes, dtype=np.float64)
    start, stop = float(time[0]), float(time[-1])
    n_intervals = max(1, round((stop - start) / knot_spacing_s))
    inner = np.linspace(start, stop, n_intervals + 1)
    knots = np.concatenate(([start] * _DEGREE, inner, [stop] * _DEGREE))
    design = BSpline.design_matrix(time, knots, _DEGREE).toarray()
    design.flags.writeable = False
    return design


@functools.lru_cache(maxsize=16)
def _coefficient_names(keys: tuple[str, ...]) -> tuple[str, ...]:
    """The spline coefficients among parameter names, ``velocity_1`` first (cached by names)."""
    return tuple(
        sorted(
            (key for key in keys if key.startswith("velocity_") and key[9:].isdigit()),
            key=lambda key: int(key.split("_")[1]),
        )
    )


class Velocity(Effect):
    """Spline coefficients ``velocity_1 .. velocity_n`` of log s(t) (``velocity_0`` = 0)."""

    name = "velocity"
    uses_sample_times = True
    local_parameters = True
    summary = "a changing flow velocity scales both time constants together (spline of log s(t))"
    setting_choices = tuple(
        {"velocity_smoothness": value, "velocity_free_run": 0.0} for value in SMOOTHNESS_CHOICES
    )
    free_run_setting = "velocity_free_run"
    simulation_forms = ("sine", "steps")

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """m, depth, period_s: v/v0 = 1 + depth sin(2π t/period_s), or steps between 1 ± depth.

        Steps (a valve or a throttle moved) hold each speed half a period; a smooth spline of
        log s(t), the fit's form, can only round them.
        """
        return {"m": SIMULATED_EXPONENT, "depth": SIMULATED_DEPTH, "period_s": SIMULATED_PERIOD_S}

    def __init__(self) -> None:
        self._cache: tuple[int, float, NDArray[np.float64]] | None = None
        self._factor: tuple[tuple[float, ...], NDArray[np.float64]] | None = None

    def _design(self, context: FitContext) -> NDArray[np.float64]:
        # The shared matrix is keyed by the times' bytes (40 µs of hashing at 20 000 samples):
        # each fit's speed steps ask for it again, so the model keeps its own reference.
        key = (context.time.size, context.knot_spacing_s)
        if self._cache is None or self._cache[:2] != key:
            self._cache = (*key, _basis(context))
        return self._cache[2]

    def n_coefficients(self, context: FitContext) -> int:
        """Number of fitted spline coefficients (one fewer than basis functions)."""
        return self._design(context).shape[1] - 1

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        return tuple(
            ParamSpec(
                name=f"velocity_{j}",
                unit="1",
                lower=-1.5,
                upper=1.5,
                description=f"spline coefficient {j} of log tau factor",
            )
            for j in range(1, self.n_coefficients(context) + 1)
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        starts = [{spec.name: 0.0 for spec in self.specs(context)}]
        tracked = self._tracked_start(context, tc1, tc2)
        return starts if tracked is None else [*starts, tracked]

    def _tracked_start(
        self, context: FitContext, tc1: NDArray[np.float64], tc2: NDArray[np.float64]
    ) -> dict[str, float] | None:
        """A start from τ tracked through the record (forgetting β-GTLS, ratio held).

        A strong, fast velocity change leaves the constant-τ start far from the optimum; the
        tracked common scale, projected on the spline, starts the search near it.
        """
        try:
            track = track_tau(
                tc1,
                tc2,
                context.dt,
                memory_s=context.knot_spacing_s / 2.0,
                step_s=context.knot_spacing_s / 4.0,
                phi=context.phi_hat,
            )
        except (TcompError, ValueError, np.linalg.LinAlgError):
            return None
        scale = np.log(np.sqrt(track.tau1 * track.tau2))
        finite = np.isfinite(scale)
        design = self._design(context)
        if finite.sum() < design.shape[1]:
            return None
        log_s = np.interp(context.time, track.time[finite], scale[finite])
        coefficients, *_ = np.linalg.lstsq(design, log_s - log_s.mean(), rcond=None)
        # The basis sums to one: shifting every coefficient by c0 leaves the normalised s(t).
        relative = np.clip(coefficients[1:] - coefficients[0], -1.5, 1.5)
        start = {f"velocity_{j}": float(c) for j, c in enumerate(relative, start=1)}
        start["tau1"] = float(np.exp(np.nanmean(np.log(track.tau1))))
        start["tau2"] = float(np.exp(np.nanmean(np.log(track.tau2))))
        return start

    def _coefficients(self, params: Mapping[str, float]) -> NDArray[np.float64]:
        return np.array([0.0, *(params[name] for name in _coefficient_names(tuple(params)))])

    def tau_factor(self, context: FitContext, params: Mapping[str, float]) -> NDArray[np.float64]:
        # The same array for the same coefficients: a fit's chain memo matches chains by it.
        coefficients = self._coefficients(params)
        key = (context.time.size, context.knot_spacing_s, *coefficients.tolist())
        if self._factor is None or self._factor[0] != key:
            log_s = self._design(context) @ coefficients
            factor = np.exp(log_s - log_s.mean())
            factor.flags.writeable = False
            self._factor = (key, factor)
        return self._factor[1]

    def identifiability(self, params: Mapping[str, float]) -> str:
        return (
            "velocity: the level of s(t) trades with tau1 and tau2, so s(t) is normalised to a "
            "geometric mean of 1 and the time constants are the record's geometric means"
        )

    def unseen_parameters(self, context: FitContext, samples: NDArray[np.bool_]) -> frozenset[str]:
        """Coefficients whose basis function has less than half its weight on ``samples``.

        Outside them (the free run's start-up transient) a coefficient moves s(t) where
        nothing is scored, and through the normalisation of s(t) it trades with τ.
        """
        design = self._design(context)[:, 1:]
        share = design[samples].sum(axis=0) / np.maximum(design.sum(axis=0), 1e-300)
        return frozenset(
            f"velocity_{j}" for j, value in enumerate(share, start=1) if value < UNSEEN_SHARE
        )

    def log_factor_jacobian(self, context: FitContext) -> dict[str, NDArray[np.float64]]:
        # log s = B c − mean(B c), c0 = 0: linear in the coefficients.
        design = self._design(context)
        centred = design[:, 1:] - design[:, 1:].mean(axis=0)
        return {f"velocity_{j}": centred[:, j - 1] for j in range(1, design.shape[1])}

    def penalty(self, params: Mapping[str, float], n_rows: int) -> NDArray[np.float64]:
        coefficients = self._coefficients(params)
        if coefficients.size < 3:
            return np.empty(0)
        weight = params.get("velocity_smoothness", SMOOTHNESS_CHOICES[0])
        first = coefficients[1:] - coefficients[:-1]  # np.diff(coefficients, 2), in its steps
        return weight * np.sqrt(n_rows) * (first[1:] - first[:-1])
