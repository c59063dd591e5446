"""Gas temperature signals, thermocouple responses and measurement noise (Sec. IV, Fig. 2–3).

The simulation follows the block diagram of Fig. 2: one gas temperature drives two first-order
sensors; white Gaussian noise is added to each output. The sensors are simulated with the exact
zero-order-hold difference equation (Eq. 4), so noise-free data satisfy the estimators' model to
rounding. Noise level K (Eq. 22) is taken relative to the noise-free response of thermocouple 1;
the noise variance ratio φ = σ1²/σ2² (the paper's nomenclature, Eq. 19) is 1 by default.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .choices import PAPER_DT, PAPER_DURATION, PAPER_TAU1, PAPER_TAU2, SIGNALS, SignalKind
from .models import FirstOrderLag
from .validation import check_sample_interval

__all__ = [
    "SIGNALS",
    "SignalKind",
    "SimulatedPair",
    "add_noise",
    "exhaust_pulses",
    "gas_signal",
    "multisine",
    "periodic_ramp",
    "simulate_pair",
    "sinusoid",
]


def sinusoid(
    t: NDArray[np.float64], freq_hz: float = 10.0, mean: float = 100.0, amplitude: float = 50.0
) -> NDArray[np.float64]:
    """Sinusoidal gas temperature of Fig. 3(a), in degrees C; 10 Hz as on the test rig."""
    return mean + amplitude * np.sin(2.0 * np.pi * freq_hz * t)


def periodic_ramp(
    t: NDArray[np.float64], freq_hz: float = 10.0, mean: float = 100.0, amplitude: float = 50.0
) -> NDArray[np.float64]:
    """Periodic ramp (sawtooth) gas temperature of Fig. 3(b), in degrees C.

    Rises linearly from ``mean - amplitude`` to ``mean + amplitude`` over each period, then drops.
    """
    # Cycles are counted with a tiny lead: where f·t is a whole number the rounding of f·t would
    # put the jump on either side of the sample at random, a spurious broadband jitter.
    cycles = freq_hz * np.asarray(t, dtype=np.float64) + 1e-9
    return mean + amplitude * (2.0 * np.mod(cycles, 1.0) - 1.0)


def multisine(
    t: NDArray[np.float64],
    f_min_hz: float = 1.0,
    f_max_hz: float = 100.0,
    n_tones: int = 40,
    mean: float = 100.0,
    amplitude: float = 50.0,
) -> NDArray[np.float64]:
    """Broadband multisine: ``n_tones`` log-spaced equal-amplitude tones with Schroeder phases.

    Schroeder phases keep the crest factor low, so the peak stays near ``mean ± amplitude``.
    Deterministic: no random phases.
    """
    freqs = np.geomspace(f_min_hz, f_max_hz, n_tones)
    k = np.arange(1, n_tones + 1)
    phases = -np.pi * k * (k - 1) / n_tones
    times = np.asarray(t, dtype=np.float64)
    tones = np.empty(times.shape)
    # In blocks of samples: the whole (tones, N) array of a long record is hundreds of MB
    # (a million samples took 8 s, most of it paging); each sample's sum is the same.
    for start in range(0, times.size, _MULTISINE_BLOCK):
        block = times[start : start + _MULTISINE_BLOCK]
        angles = 2.0 * np.pi * freqs[:, None] * block[None, :] + phases[:, None]
        tones[start : start + block.size] = np.sin(angles).sum(axis=0)
    return mean + amplitude * tones / np.max(np.abs(tones))


#: Samples per block of :func:`multisine`'s tone sum.
_MULTISINE_BLOCK = 16384


def exhaust_pulses(
    t: NDArray[np.float64],
    firing_hz: float = 25.0,
    mean: float = 450.0,
    amplitude: float = 150.0,
    decay_fraction: float = 0.25,
    jitter: float = 0.1,
    seed: int = 0,
) -> NDArray[np.float64]:
    """Engine-exhaust-like pulse train in degrees C.

    At each exhaust-valve opening the temperature jumps (blowdown) and then relaxes exponentially
    with a time constant of ``decay_fraction`` of the firing period; pulse heights vary from cycle
    to cycle by ``jitter`` (relative standard deviation, seeded) as combustion does.
    """
    period = 1.0 / firing_hz
    cycle = np.floor(t / period).astype(np.int64)
    phase = t - cycle * period
    rng = np.random.default_rng(seed)
    heights = 1.0 + jitter * rng.standard_normal(int(cycle.max() - cycle.min()) + 1)
    pulse = heights[cycle - cycle.min()] * np.exp(-phase / (decay_fraction * period))
    # Centre the pulse train: the exponential has mean (decay_fraction)(1 - e^{-1/decay_fraction}).
    pulse_mean = decay_fraction * (1.0 - np.exp(-1.0 / decay_fraction))
    return mean + amplitude * (pulse - pulse_mean) / (1.0 - pulse_mean)


_GENERATORS: dict[str, Callable[..., NDArray[np.float64]]] = {
    "sinusoid": sinusoid,
    "ramp": periodic_ramp,
    "multisine": multisine,
    "exhaust": exhaust_pulses,
}


def gas_signal(kind: SignalKind, t: NDArray[np.float64], **params: float) -> NDArray[np.float64]:
    """Evaluate the gas temperature signal ``kind`` at times ``t`` (seconds), in degrees C.

    Parameters
    ----------
    kind : {'sinusoid', 'ramp', 'multisine', 'exhaust'}
    t : ndarray, shape (N,)
    **params
        Keyword parameters of the generator (``freq_hz``, ``mean``, ``amplitude``...).
    """
    try:
        generator = _GENERATORS[kind]
    except KeyError:
        raise ValueError(f"unknown signal {kind!r}; choose one of {', '.join(SIGNALS)}") from None
    return generator(np.asarray(t, dtype=np.float64), **params)


def add_noise(
    clean1: NDArray[np.float64],
    clean2: NDArray[np.float64],
    noise_percent: float,
    phi: float = 1.0,
    rng: np.random.Generator | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """Add independent white Gaussian noise to two sensor outputs.

    Parameters
    ----------
    clean1, clean2 : ndarray, shape (N,)
        Noise-free sensor outputs, degrees C.
    noise_percent : float
        K of Eq. (22) in percent: σ1 = K/100 · std(clean1).
    phi : float
        Noise variance ratio φ = σ1²/σ2² (> 0), 1 for equal variances.
    rng : numpy.random.Generator
        Source of the noise; pass a seeded generator for reproducible data.

    Returns
    -------
    noisy1, noisy2 : ndarray, shape (N,)
    sigma1, sigma2 : float
        Noise standard deviations in degrees C.
    """
    if noise_percent < 0.0:
        raise ValueError(f"{noise_percent=} must be >= 0")
    if not phi > 0.0:
        raise ValueError(f"{phi=} must be > 0")
    rng = np.random.default_rng() if rng is None else rng
    sigma1 = noise_percent / 100.0 * float(np.std(clean1))
    sigma2 = sigma1 / np.sqrt(phi)
    noisy1 = clean1 + sigma1 * rng.standard_normal(clean1.size)
    noisy2 = clean2 + sigma2 * rng.standard_normal(clean2.size)
    return noisy1, noisy2, sigma1, sigma2


@dataclass(frozen=True, kw_only=True)
class SimulatedPair:
    """A simulated two-thermocouple record.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times in seconds, starting at 0.
    gas : ndarray, shape (N,)
        True gas temperature, degrees C (zero-order held).
    tc1, tc2 : ndarray, shape (N,)
        Noisy thermocouple outputs, degrees C.
    clean1, clean2 : ndarray, shape (N,)
        Noise-free thermocouple outputs, degrees C.
    tau1, tau2, dt : float
        True time constants and sample interval, seconds.
    sigma1, sigma2 : float
        Noise standard deviations, degrees C.
    """

    time: NDArray[np.float64]
    gas: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    clean1: NDArray[np.float64]
    clean2: NDArray[np.float64]
    tau1: float
    tau2: float
    dt: float
    sigma1: float
    sigma2: float
    meta: dict[str, object] = field(default_factory=dict)


def simulate_pair(
    kind: SignalKind = "sinusoid",
    *,
    tau1: float = PAPER_TAU1,
    tau2: float = PAPER_TAU2,
    dt: float = PAPER_DT,
    duration: float = PAPER_DURATION,
    noise_percent: float = 0.0,
    phi: float = 1.0,
    seed: int = 0,
    signal_params: dict[str, float] | None = None,
    warmup: float = 0.0,
) -> SimulatedPair:
    """Simulate the two-thermocouple system of Fig. 2.

    Parameters
    ----------
    kind : {'sinusoid', 'ramp', 'multisine', 'exhaust'}
        Gas temperature signal.
    tau1, tau2 : float
        Time constants of the two sensors in seconds.
    dt : float
        Sample interval τ_s in seconds.
    duration : float
        Record length in seconds.
    noise_percent : float
        Noise level K in percent (Eq. 22), relative to the noise-free output of sensor 1.
    phi : float
        Noise variance ratio σ1²/σ2².
    seed : int
        Seed of the noise generator.
    signal_params : dict, optional
        Extra parameters of the gas signal generator.
    warmup : float
        Seconds simulated before the record starts and dropped, s (>= 0): with several time
        constants of warm-up the sensors start settled in the running signal, as on a rig
        that was already running, rather than in equilibrium with its first value (whose
        start-up transient is a step response, a strong extra excitation).

    Returns
    -------
    SimulatedPair
    """
    dt = check_sample_interval(dt)
    if not duration > 0.0:
        raise ValueError(f"{duration=} must be > 0 s")
    if not (math.isfinite(warmup) and warmup >= 0.0):
        raise ValueError(f"{warmup=} must be >= 0 s")
    n = round(duration / dt)
    skip = round(warmup / dt)
    time = np.arange(-skip, n, dtype=np.float64) * dt
    gas = gas_signal(kind, time, **(signal_params or {}))
    clean1 = FirstOrderLag(tau=tau1).respond(gas, dt)[skip:]
    clean2 = FirstOrderLag(tau=tau2).respond(gas, dt)[skip:]
    time, gas = time[skip:], gas[skip:]
    rng = np.random.default_rng(seed)
    tc1, tc2, sigma1, sigma2 = add_noise(clean1, clean2, noise_percent, phi, rng)
    return SimulatedPair(
        time=time,
        gas=gas,
        tc1=tc1,
        tc2=tc2,
        clean1=clean1,
        clean2=clean2,
        tau1=float(tau1),
        tau2=float(tau2),
        dt=dt,
        sigma1=sigma1,
        sigma2=sigma2,
        meta={"signal": kind, "noise_percent": noise_percent, "phi": phi, "seed": seed},
    )
