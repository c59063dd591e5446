"""The compensator as its own process, fed the hostile phases of issue 26 over DDS.

A test node publishes, at the pace of the stamps, one phase after another: a good 500 Hz sine,
the same sensors at 2 kHz (a driver restarted at another rate), 500 °C steps, readings of
3e8 °C on tc1, and identical sensors. The node runs its defaults with the Kalman filter's
signal model chosen automatically (its fit used to run on the executor: /diagnostics fell
silent for seconds and pairs were lost). It must stay up, report at least every few seconds
while data flow, count the change of rate and the invalid readings, never publish a gas
outside the physical range, and stop cleanly.
"""

import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from node_harness import values
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Temperature

from tcomp_core.io.screening import VALID_RANGE_C

pytestmark = pytest.mark.slow

#: (name, sample rate Hz, seconds) of each phase.
PHASES = (
    ("sine_500hz", 500.0, 8.0),
    ("sine_2khz", 2000.0, 6.0),
    ("steps_500c", 2000.0, 3.0),
    ("absurd_tc1", 2000.0, 1.0),
    ("identical", 2000.0, 3.0),
)
TAUS = (0.02, 0.1)
#: Longest silence of /diagnostics while data flow, s (the node reports once a second).
MAX_SILENCE_S = 3.0


def phase_samples(name, rate, seconds, start_s, state, rng):
    """Stamps (s) and readings of one phase; ``state`` carries the sensors' temperatures."""
    time_s = start_s + np.arange(int(rate * seconds)) / rate
    if name == "steps_500c":
        gas = np.where((time_s % 1.0) < 0.5, 300.0, 800.0)
    else:
        gas = 300 + 50 * np.sin(2 * np.pi * 3 * time_s) + 20 * np.sin(2 * np.pi * 11 * time_s)
    readings = []
    for index, tau in enumerate(TAUS):
        pole = math.exp(-1.0 / (rate * tau))
        out = np.empty_like(gas)
        value = state[index]
        for k, g in enumerate(gas):
            value = pole * value + (1 - pole) * g
            out[k] = value
        state[index] = value
        readings.append(out + rng.normal(0, 0.3, gas.size))
    tc1, tc2 = readings
    if name == "absurd_tc1":
        tc1 = np.full(gas.size, 3e8)
    if name == "identical":
        tc2 = tc1.copy()
    return time_s, tc1, tc2


def test_the_node_survives_hostile_phases_as_its_own_process(ros_context, ros_domain_id):
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain_id))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    compensator = subprocess.Popen(
        [
            *(sys.executable, "-m", "tcomp_ros.compensator", "--ros-args"),
            *("-p", "reconstruction:=kalman", "-p", "signal_model:=auto"),
            *("-p", "window_s:=3.0", "-p", "input_reliability:=reliable"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    node = Node("hostile_feeder", context=ros_context)
    reliable = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    publishers = [
        node.create_publisher(Temperature, "tc1/temperature", reliable),
        node.create_publisher(Temperature, "tc2/temperature", reliable),
    ]
    statuses, gas = [], []
    node.create_subscription(
        DiagnosticArray,
        "/diagnostics",
        # When the node stamped the report (its clock, not when this busy feeder took it).
        lambda m: statuses.extend(
            (m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, s) for s in m.status
        ),
        100,
    )
    node.create_subscription(
        Temperature, "gas_temperature", lambda m: gas.append(m.temperature), 10000
    )
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    rng = np.random.default_rng(26)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and publishers[0].get_subscription_count() == 0:
            executor.spin_once(timeout_sec=0.05)
        assert publishers[0].get_subscription_count() > 0, "the node never subscribed"
        state, start_s, epoch = [300.0, 300.0], 0.0, 1_700_000_000
        feeding_started = time.time()
        for name, rate, seconds in PHASES:
            stamps, tc1, tc2 = phase_samples(name, rate, seconds, start_s, state, rng)
            start_s = stamps[-1] + 1.0 / rate
            batch = max(1, int(rate * 0.01))  # 10 ms of samples per turn
            phase_started = time.monotonic()
            for first in range(0, stamps.size, batch):
                for k in range(first, min(first + batch, stamps.size)):
                    sec, nanosec = divmod(round((epoch + stamps[k]) * 1e9), 10**9)
                    for index, value in enumerate((tc1[k], tc2[k])):
                        message = Temperature()
                        message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
                        message.header.frame_id = "probe"
                        message.temperature = float(value)
                        publishers[index].publish(message)
                # Keep to the stamps' pace (the node's silence checks use wall time): spin until
                # the stamps' time, not once (a spin returns at the first gas message, and the
                # phases went out 4x faster than their stamps, the node then behind them).
                due = phase_started + (stamps[first] - stamps[0])
                while (lag := due - time.monotonic()) > 0.0:
                    executor.spin_once(timeout_sec=lag)
        feeding_ended = time.time()
        # The last reports: until the node has counted every reading sent (a fixed number of
        # spins returned early on the gas messages, before the absurd phase was reported).
        sent = sum(int(rate * seconds) for _, rate, seconds in PHASES)
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not (
            statuses and int(values(statuses[-1][1]).get("received_tc1", 0)) >= sent
        ):
            executor.spin_once(timeout_sec=0.05)
        assert compensator.poll() is None, compensator.stderr.read()[-3000:]
    finally:
        executor.shutdown()
        node.destroy_node()
        if compensator.poll() is None:
            compensator.send_signal(signal.SIGINT)
        try:
            _, stderr = compensator.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            compensator.kill()
            _, stderr = compensator.communicate()
    assert compensator.returncode == 0, stderr[-3000:]
    assert "Traceback" not in stderr
    # Reports kept coming while data flowed: no silence while a fit ran.
    times = [t for t, _ in statuses if feeding_started <= t <= feeding_ended]
    gaps = np.diff([feeding_started, *times, feeding_ended])
    assert gaps.max() < MAX_SILENCE_S, gaps.max()
    reports = [values(s) for _, s in statuses]
    last = reports[-1]
    # The rate change was seen, counted and reported; the invalid readings counted.
    assert int(last["rate_changes"]) >= 1
    # At the new rate τ is right again (it came out 10x too long when the period stayed learnt).
    fast = [
        v for v in reports if v["sample_period_s"] != "nan" and float(v["sample_period_s"]) < 1e-3
    ]
    assert fast, "no report at 2 kHz"
    assert float(fast[0]["sample_period_s"]) == pytest.approx(5e-4, rel=0.01)
    # (τ of the published gas: nan while the filter for the new rate is being fitted.)
    sine = [v for v in fast if v["estimate_accepted"] == "true" and v["tau1_s"] != "nan"][:3]
    assert sine and all(float(v["tau1_s"]) == pytest.approx(TAUS[0], rel=0.1) for v in sine)
    assert int(last["invalid_tc1"]) >= int(0.9 * 2000 * 1.0)
    # Never a gas outside the physical range, and gas came out of every phase but the absurd.
    assert gas and np.all(np.isfinite(gas))
    low, high = VALID_RANGE_C
    assert low <= min(gas) and max(gas) <= high
    # (This busy feeder takes one message per turn: the node's own count says what it sent.)
    expected = sum(rate * seconds for name, rate, seconds in PHASES[:3])
    assert int(last["published"]) > 0.5 * expected, last["published"]
