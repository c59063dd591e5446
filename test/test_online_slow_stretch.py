"""A stretch of gas too slow to excite the sensors does not move the published τ.

The windows' ml-eiv intervals were a fraction of their error (the noise's share of the Jacobian
counted as information, :mod:`tcomp_core.estimators.eiv_noise`), so the engine's ±20 % rule
took some of them: on 0.3 Hz after a multisine it published τ1 = 0.088 s for a true 0.020.
"""

import numpy as np
from scipy.signal import lfilter

from tcomp_core.online import OnlineCompensator, OnlineConfig
from tcomp_core.simulate import gas_signal

DT = 0.002
TAUS = (0.02, 0.1)
BROADBAND_S = 10.0
SLOW_S = 40.0


def _record(seed):
    """10 s of a 1–100 Hz multisine, then 40 s of a 0.3 Hz sine, read by both sensors."""
    time = np.arange(round((BROADBAND_S + SLOW_S) / DT)) * DT
    gas = gas_signal("multisine", time)
    slow = time >= BROADBAND_S
    # The sine starts at the multisine's last value: no step to excite the sensors.
    start = gas[~slow][-1]
    gas[slow] = start + 50.0 * np.sin(2.0 * np.pi * 0.3 * (time[slow] - BROADBAND_S))
    rng = np.random.default_rng(seed)
    readings = []
    for tau in TAUS:
        a = np.exp(-DT / tau)
        clean = lfilter([0.0, 1.0 - a], [1.0, -a], gas, zi=[a * gas[0]])[0]
        readings.append(clean + 0.02 * np.std(clean) * rng.standard_normal(time.size))
    return time, readings[0], readings[1]


def test_the_published_tau_holds_through_a_stretch_that_does_not_pin_it_down():
    time, tc1, tc2 = _record(seed=17)
    stamps = np.round(time * 1e9).astype(np.int64) + 10**18
    engine = OnlineCompensator(OnlineConfig(window_s=4.0, reconstruction="difference"))
    published = []
    for start in range(0, time.size, 250):
        part = slice(start, start + 250)
        engine.add_pairs(stamps[part], tc1[part], tc2[part])
        engine.update_estimate()  # a window every 0.5 s, as the node's timer
        if time[part][0] >= BROADBAND_S + 4.0 and engine.tau is not None:  # slow windows only
            published.append(engine.tau)
    taus = np.array(published)
    assert taus.shape[0] > 60
    np.testing.assert_allclose(taus, np.broadcast_to(TAUS, taus.shape), rtol=0.05)
    # The slow windows were estimated and refused for their intervals, not skipped.
    assert "interval" in engine.last_status.reason, engine.last_status
