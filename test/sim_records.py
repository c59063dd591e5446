"""Seeded simulated two-thermocouple records, cached per parameter set, shared by the tests."""

from __future__ import annotations

import functools

from tcomp_core.simulate import simulate_pair


@functools.lru_cache(maxsize=256)
def _cached_pair(kind, tau1, tau2, dt, duration, noise_percent, phi, seed, freq_hz):
    pair = simulate_pair(
        kind,
        tau1=tau1,
        tau2=tau2,
        dt=dt,
        duration=duration,
        noise_percent=noise_percent,
        phi=phi,
        seed=seed,
        signal_params=None if freq_hz is None else {"freq_hz": freq_hz},
    )
    for array in (pair.time, pair.gas, pair.tc1, pair.tc2, pair.clean1, pair.clean2):
        array.flags.writeable = False  # shared between tests: nobody may modify it
    return pair


def make_pair(
    kind="sinusoid",
    *,
    tau1=0.0238,
    tau2=0.1168,
    dt=0.002,
    duration=4.0,
    noise_percent=0.0,
    phi=1.0,
    seed=0,
    freq_hz=None,
):
    """A seeded simulate_pair record (read-only arrays), cached across tests.

    ``freq_hz``: the signal's frequency (its generator's default when None).
    """
    return _cached_pair(
        kind,
        float(tau1),
        float(tau2),
        float(dt),
        float(duration),
        float(noise_percent),
        float(phi),
        int(seed),
        None if freq_hz is None else float(freq_hz),
    )


def record_of(sim, source="sim"):
    """A simulated record (lumped or detailed physics: time, tc1, tc2, gas, dt) as a Record."""
    from tcomp_core.io import Record

    return Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=sim.gas, source=source, dt=sim.dt)
