"""Interference: a line and its odd harmonics added to one channel (mains pick-up).

A thermocouple's millivolts pick up the mains (50 or 60 Hz) and its odd harmonics through the
extension cable and the amplifier's input: the channel reads T + Σ_h (a_h cos 2πhft +
b_h sin 2πhft), h = 1, 3, 5, on one channel, which the gas does not share. The fit takes the
line off that channel's readings before the inverse; the frequency starts where the readings
carry a spectral line that the other channel and the sensors' first-order relation do not
explain (:func:`find_line`), and both channels are tried (a setting, chosen on held-out data).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import TcompError
from ..lines import ForeignLine, foreign_lines, segment_length
from .base import Effect, Evidence, FitContext, ParamSpec

if TYPE_CHECKING:
    from ..estimators import Estimate

__all__ = ["HARMONICS", "Interference", "find_line", "interference_line"]

#: Harmonics fitted (odd: a rectifier's and a transformer's pick-up).
HARMONICS = (1, 3, 5)


def interference_line(
    params: Mapping[str, float], time: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The fitted line and its odd harmonics at ``time`` (s from the fitted record's start).

    Returns
    -------
    ndarray, shape like ``time``
        Degrees C on the channel ``params["interference_channel"]`` carries it on.
    """
    return _line(params, _harmonics(params["interference_hz"], time))


def _harmonics(frequency_hz: float, time: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """cos(2πhft) and sin(2πhft) of every harmonic h, in :data:`HARMONICS` order."""
    phase = 2.0 * np.pi * frequency_hz * np.asarray(time, dtype=np.float64)
    return [wave for h in HARMONICS for wave in (np.cos(h * phase), np.sin(h * phase))]


def _line(params: Mapping[str, float], waves: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Σ_h a_h cos(2πhft) + b_h sin(2πhft) from the waves of :func:`_harmonics`."""
    line = np.zeros(waves[0].shape)
    for name, wave in zip(_AMPLITUDES, waves, strict=True):
        line += params[name] * wave
    return line


#: The amplitudes, in the order of :func:`_harmonics`'s waves.
_AMPLITUDES = tuple(f"interference_{part}{h}" for h in HARMONICS for part in ("a", "b"))


def find_line(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
    channel: int | None = None,
) -> tuple[float, int, float] | None:
    """The strongest spectral line one channel carries that the other does not explain.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C.
    dt : float
        Sample interval, s.
    tau1, tau2 : float
        Time constants, s: the gas's own lines appear in tc2 as in tc1 times |G2/G1|.
    channel : int, optional
        Look on this channel only (1 or 2).

    Returns
    -------
    (frequency_hz, channel, amplitude_c) or None
        From :func:`tcomp_core.lines.foreign_lines`.
    """
    lines = foreign_lines(tc1, tc2, dt, (tau1, tau2), channel=channel)
    if not lines:
        return None
    return lines[0].frequency_hz, lines[0].channel, lines[0].amplitude_c


def _refine(reading: NDArray[np.float64], context: FitContext, f0: float) -> float:
    """The frequency within ±1 Welch bin of ``f0`` where the record's DFT peaks.

    The phase of a line drifts by 2π Δf T over the record, so the fit needs a start within a
    fraction of 1/T: the periodogram of the whole record on a grid 20 times finer than 1/T.
    """
    centred = reading - reading.mean()
    width = 1.0 / (segment_length(reading.size, context.dt) * context.dt)  # a Welch bin, Hz
    step = max(1.0, 2.0 / context.duration_s) / 20.0
    count = math.ceil(max(width, 20.0 * step) / step)
    grid = f0 + step * np.arange(-count, count + 1)
    grid = grid[grid > 0.0]
    power = [abs(np.exp(-2j * np.pi * f * context.time) @ centred) for f in grid]
    return float(grid[int(np.argmax(power))])


#: A line-free τ this far (ratio) from the base model's is a start of its own.
FAR_TAU_RATIO = 1.2


def _line_free_estimate(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float
) -> Estimate | None:
    """ml-eiv with the lines one channel carries notched (:mod:`tcomp_core.lines`), or None."""
    from ..estimators import estimate

    try:
        return estimate(tc1, tc2, dt)
    except TcompError:
        return None


def _far(found: Estimate, params: Mapping[str, float]) -> bool:
    return any(
        abs(math.log(getattr(found, name) / params[name])) > math.log(FAR_TAU_RATIO)
        for name in ("tau1", "tau2")
    )


class Interference(Effect):
    """``interference_hz`` and the amplitudes ``interference_a{h}``, ``interference_b{h}``.

    τ may move any distance from the first-order estimate (:attr:`max_tau_factor` infinite):
    the line is a signal only one sensor carries, and the first-order fit bends τ to explain
    it without limit (a 1 °C mains line on a multisine put τ1 at 6.8× the truth).

    Material (:meth:`material`) when the line is there: one channel carries it, at the fitted
    frequency or one of its :data:`HARMONICS`, beyond what the other explains with the
    first-order τ (the candidate's own τ could make a gas harmonic look foreign).
    """

    name = "interference"
    uses_sample_times = True
    max_tau_factor = math.inf
    summary = (
        "a line and its odd harmonics on one channel, e.g. mains pick-up (interference_hz, "
        "amplitudes)"
    )
    keeps_first_order_scale = True
    setting_choices = ({"interference_channel": 2.0}, {"interference_channel": 1.0})

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """interference_hz (Hz) and interference_c, the fundamental's amplitude (degrees C)."""
        return {"interference_hz": 50.0, "interference_c": 1.0}

    def found_by_default_path(self, lines: Sequence[ForeignLine], phi_hat: float) -> str:
        """Lines one channel carries alone: mains pick-up, which the default path takes off.

        It notches or subtracts them before it estimates τ (campaign draws 3276, 3292, 3361,
        3366: 50 or 60 Hz with harmonics on tc2, read ``none`` before). On the 151 stored
        campaign draws it found them on every draw with interference (20) and on none without
        it (131).
        """
        if not lines:
            return ""
        return (
            "one channel carries lines the other does not share (mains pick-up, named in the "
            "notes); the default path takes them off before it estimates tau, so the model "
            "needs no piece for them"
        )

    def material(self, params: Mapping[str, float], evidence: Evidence) -> bool:
        channel = int(params["interference_channel"])
        line = find_line(*evidence.readings, evidence.dt, *evidence.base_taus, channel)
        return line is not None and any(
            abs(line[0] - h * params["interference_hz"]) <= max(1.0, 0.02 * line[0])
            for h in HARMONICS
        )

    def __init__(self) -> None:
        self._cache: tuple[tuple[float, ...], NDArray[np.float64]] | None = None
        self._waves: list[tuple[tuple[float, ...], list[NDArray[np.float64]]]] = []

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        span = 10.0 * context.level_std_c + 10.0
        amplitudes = tuple(
            ParamSpec(
                name=f"interference_{part}{h}",
                unit="degC",
                lower=-span,
                upper=span,
                description=f"{'cosine' if part == 'a' else 'sine'} amplitude of harmonic {h}",
            )
            for h in HARMONICS
            for part in ("a", "b")
        )
        frequency = ParamSpec(
            name="interference_hz",
            unit="Hz",
            lower=2.0 / context.duration_s,
            upper=0.45 / context.dt,
            description="fundamental frequency of the line",
        )
        return (frequency, *amplitudes)

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        channel = int(params.get("interference_channel", 2))
        robust = _line_free_estimate(tc1, tc2, context.dt)
        lines = [line for line in robust.lines if line.channel == channel] if robust else []
        if lines:
            strongest = lines[0].frequency_hz
        else:
            line = find_line(tc1, tc2, context.dt, params["tau1"], params["tau2"], channel)
            if line is None:
                return []  # no line on this channel that the other does not explain
            strongest = line[0]
        zeros = {f"interference_{part}{h}": 0.0 for h in HARMONICS for part in ("a", "b")}
        reading = (tc1, tc2)[channel - 1]
        # The strongest line may be a harmonic of the fundamental: try f, f/3 and f/5.
        low = 2.0 / context.duration_s
        candidates = [_refine(reading, context, strongest / h) for h in HARMONICS]
        starts = [{"interference_hz": f, **zeros} for f in candidates if f > low]
        if lines and robust is not None and starts and _far(robust, params):
            # The base model bent τ to explain the line: start also from τ without it.
            starts.append({**starts[0], "tau1": robust.tau1, "tau2": robust.tau2})
        return starts

    def additive(
        self, sensor: int, params: Mapping[str, float], context: FitContext
    ) -> NDArray[np.float64] | None:
        if sensor != int(params.get("interference_channel", 2)):
            return None
        key = (
            context.time.size,
            context.dt,
            params["interference_hz"],
            *(params[name] for name in _AMPLITUDES),
        )
        if self._cache is None or self._cache[0] != key:
            # A fit moves the amplitudes more often than the frequency: the waves are kept.
            # Two frequencies are kept: a Jacobian moves it for one column and back for the rest.
            waves_key = key[:3]
            found = next((w for k, w in self._waves if k == waves_key), None)
            if found is None:
                found = _harmonics(params["interference_hz"], context.time)
                self._waves = [(waves_key, found), *self._waves[:1]]
            line = _line(params, found)
            line.flags.writeable = False
            self._cache = (key, line)  # one array per parameter set: the fit's memo keys on it
        return self._cache[1]

    def identifiability(self, params: Mapping[str, float]) -> str:
        channel = int(params.get("interference_channel", 2))
        return (
            f"interference: the line is put on tc{channel}, the channel whose readings carry "
            "it beyond what the other explains; a line on both channels alike would look like gas"
        )
