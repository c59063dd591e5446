"""A transport delay: the second junction sees the gas δ seconds later than the first.

Junctions a few millimetres apart in a flow of a few metres per second, or different wire
lengths in the flow, see the same gas at different times. A delay looks like extra lag at low
frequencies, so the base model absorbs it into τ2 − τ1 and then fails at high frequencies.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from ..errors import TcompError
from ..estimators.beta import beta_gtls
from .base import Effect, Evidence, FitContext, OutputEvidence, ParamSpec
from .chain import fractional_shift

__all__ = ["MIN_SAMPLES", "Delay"]

#: Least delay that counts, in samples of the record (not of the diagnosis's working rate).
MIN_SAMPLES = 0.5

#: Trial delays of the closed-form scan, how many of its lowest local minima are refined, and
#: how many of those start the search. The GTLS criterion is sharp around the true delay: a
#: 9 ms delay on 40 Hz engine pulses stood out 5× against its aliases one pulse period away
#: when a trial came within a millisecond, and the search ended on an alias with τ 50 % long
#: when none did.
_TRIALS = 81
_REFINED = 6
_STARTS = 3
#: The criterion the refinement sees where β-GTLS finds no positive τ (finite, for Brent).
_FAILED = 1e30


class Delay(Effect):
    """δ (s), positive when tc2 sees the gas later.

    τ may rise any distance from the first-order estimate (:attr:`max_tau_factor` infinite):
    the base model absorbs a delay into τ2 − τ1, so a delay of a few samples collapses its τ1
    to a tenth of the truth, one longer than τ1 to its bound (9 ms on engine pulses put it at
    a 25th), and the delay brings it back. It falls by half at most (:attr:`max_tau_fall`):
    a delay gives back the lag the first order hid, it takes none away. Fits that put τ1 at
    1/20 and 1/50 of the default path's (campaign draws 2878 and 2892, steps with a mains
    line and no delay, the default path within 2 % of the truth) traded the line for a shift
    of one channel; applied, the second made the gas 1.9 → 21.9 % off. Real delays' fits
    stood at 0.98–1.93 times the default path's τ (campaign draws 2829 and 2799).

    Material (:meth:`material`) from :data:`MIN_SAMPLES` of a sample of the record: the
    diagnosis decimates a 5 kHz record to a few hundred Hz, and a delay of 2.5 raw samples,
    fitted by a fractional shift, is then a fraction of a working sample, yet it is real and it
    moves τ and the gas (a delay fitted at zero is no delay: its fall came from the restarts of
    τ that the delay's search makes). Output (:meth:`output_handling`): ``prior``, only the
    delay between the sensors is seen, so the gas is put on tc1's clock.

    Its evidence is not the sensors' disagreement at the diagnosis's closed-form start
    (:attr:`evidence_at_start` False): that first-order start absorbs the delay by bending
    τ2 − τ1, and the readings then agree there because the delay is hidden, not because it is
    absent (engine pulses at 1 kHz with 2.13 ms between the junctions: the start put τ1 at
    5.6 ms against a true 53, the sensors' first-order gas 2.75 °C apart, against 21.8 at the
    default path's τ and 32.8 at the fit's own; the delay, 2.16 ± 0.03 ms, changed the gas by
    16.5 °C, half the disagreement at its own τ as a shift of one channel must, and was refused
    as a correction six times its evidence: the gas stayed 31.4 % off where the delay put it
    at 5.3). The default path's τ and the fit's own still count, and a delay traded for lag (τ1
    and τ2 swapped around a 265 ms shift on steps with a mains line) stays refused there.
    """

    name = "delay"
    summary = "tc2 sees the gas later than tc1 (delay_s)"
    keeps_first_order_scale = True
    evidence_at_start = False

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """delay_s (s) by which junction 2 sees the gas later: 8 ms, 4 samples at 500 Hz."""
        return {"delay_s": 0.008}

    max_tau_factor = math.inf
    max_tau_fall = 2.0

    def material(self, params: Mapping[str, float], evidence: Evidence) -> bool:
        return bool(abs(params["delay_s"]) >= MIN_SAMPLES * evidence.record_dt)

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        return "prior", "only the delay between the sensors is seen: the gas is put on tc1's clock"

    def _bound(self, context: FitContext) -> float:
        return float(min(max(context.tau_scale_s, 20.0 * context.dt), context.duration_s / 10.0))

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        bound = self._bound(context)
        return (
            ParamSpec(
                name="delay_s",
                unit="s",
                lower=-bound,
                upper=bound,
                description="how much later tc2 sees the gas than tc1",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        # A strong delay drives the base model's τ far off. β-GTLS on tc2 advanced by a trial
        # delay is closed-form, so a grid of trials finds the few delays (and τ) to start from:
        # the local minima of the GTLS criterion (smallest generalised eigenvalue), each refined
        # by a 1-D search (the minimum is narrower than a millisecond on sharp pulses), the
        # lowest first.
        bound = self._bound(context)
        delays = np.linspace(-0.9 * bound, 0.9 * bound, _TRIALS)
        criteria = np.array([self._criterion(d, context, tc1, tc2)[0] for d in delays])
        padded = np.concatenate(([np.inf], criteria, [np.inf]))
        minima = np.flatnonzero(
            np.isfinite(criteria) & (criteria <= padded[:-2]) & (criteria <= padded[2:])
        )
        spacing = delays[1] - delays[0]
        refined = []
        for i in minima[np.argsort(criteria[minima])][:_REFINED]:
            found = optimize.minimize_scalar(
                lambda d: min(self._criterion(d, context, tc1, tc2)[0], _FAILED),
                bounds=(delays[i] - spacing, delays[i] + spacing),
                method="bounded",
                options={"xatol": 0.05 * context.dt},
            )
            criterion, taus = self._criterion(float(found.x), context, tc1, tc2)
            if taus is not None:
                refined.append((criterion, {"delay_s": float(found.x), **taus}))
        refined.sort(key=lambda trial: trial[0])
        return [{"delay_s": 0.0}] + [start for _, start in refined[:_STARTS]]

    @staticmethod
    def _criterion(
        delay: float, context: FitContext, tc1: NDArray[np.float64], tc2: NDArray[np.float64]
    ) -> tuple[float, dict[str, float] | None]:
        """β-GTLS's criterion per sample with tc2 advanced by ``delay``, and its τ (inf, None)."""
        shifted, _ = fractional_shift(tc2, delay / context.dt)
        inside = np.isfinite(shifted)
        try:
            found = beta_gtls(tc1[inside], shifted[inside], context.dt, context.phi_hat)
        except TcompError:
            return math.inf, None
        criterion = found.params["noise_eigenvalue"] / inside.sum()
        return criterion, {"tau1": found.tau1, "tau2": found.tau2}

    def identifiability(self, params: Mapping[str, float]) -> str:
        return (
            "delay: only the relative delay is visible (tc2 sees the gas after tc1); the gas "
            "temperature is given at tc1's position"
        )

    def delay_s(self, params: Mapping[str, float]) -> float:
        return params["delay_s"]
