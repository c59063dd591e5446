"""Replay node: publish the Temperature topics of a bag, or simulated data, in real time.

``source: bag`` publishes every ``sensor_msgs/Temperature`` topic of a rosbag2 MCAP bag (tc1,
tc2 and the reference when present) in log-time order, at real time or ``rate`` × real time, on
the bag's topic names made relative (``/tc1/temperature`` → ``tc1/temperature``) so that
namespaces and remapping apply. Header stamps are the bag's, to the nanosecond. With ``loop``
the bag restarts and its stamps are shifted by its length plus :data:`LOOP_GAP_STEPS` sample
steps, so they keep increasing and a consumer that watches for gaps (the compensator does) never
links the last sample of one pass to the first of the next: the sensors' states jump there.
``publish_clock`` publishes ``/clock`` with the bag time for ``use_sim_time`` consumers. The
replay runs on a steady wall-clock timer whatever ``use_sim_time`` says: under simulated time a
ROS timer would wait for the very clock this node is meant to publish.

``wait_for_subscribers: N`` holds the first message until the two sensor topics (tc1, tc2; not
the reference) each have at least N matched subscriptions, then starts the clock: DDS discovers
each topic on its own, so without it a consumer started beside the replay may receive the first
messages of one sensor and not the other's.

``source: simulate`` generates live two-thermocouple data (:mod:`tcomp_core.simulate`) stamped
from the node's clock instead.

A 200 Hz timer publishes every message whose time has come (a per-message timer cannot keep up
with 2 × 5 kHz in Python).
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Temperature

from tcomp_core.choices import SIGNALS
from tcomp_core.errors import DataError, TruncatedInputWarning
from tcomp_core.io import DEFAULT_TOPICS, read_bag

from .spin import shut_down, spin_until_shutdown

__all__ = ["ReplayNode", "main"]

TICK_S = 0.005
#: Sample steps left out between two passes of a looped bag (a visible gap in the stamps).
LOOP_GAP_STEPS = 10
QOS = QoSProfile(
    depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
)
#: Length of the record generated in simulate mode when ``duration_s`` is 0 (then looped), s.
SIMULATED_LOOP_S = 60.0


def _range(low: float, high: float) -> list[FloatingPointRange]:
    # float(): an int given to the float64 fields is advertised as garbage (5e-324).
    return [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]


PARAMETERS: dict[str, tuple[object, ParameterDescriptor]] = {
    "source": ("bag", ParameterDescriptor(description="'bag' or 'simulate'")),
    "bag": ("", ParameterDescriptor(description="rosbag2 MCAP bag to replay")),
    "rate": (
        1.0,
        ParameterDescriptor(description="speed factor", floating_point_range=_range(1e-3, 1e3)),
    ),
    "loop": (False, ParameterDescriptor(description="restart the bag at its end")),
    "publish_clock": (False, ParameterDescriptor(description="publish /clock (bag time)")),
    "wait_for_subscribers": (
        0,
        ParameterDescriptor(
            description="hold the start until tc1 and tc2 each have this many subscriptions",
            integer_range=[IntegerRange(from_value=0, to_value=1000, step=1)],
        ),
    ),
    "signal": ("sinusoid", ParameterDescriptor(description=f"one of {', '.join(SIGNALS)}")),
    "tau1": (0.0238, ParameterDescriptor(description="s", floating_point_range=_range(1e-6, 1e3))),
    "tau2": (0.1168, ParameterDescriptor(description="s", floating_point_range=_range(1e-6, 1e3))),
    "noise_percent": (
        1.0,
        ParameterDescriptor(description="noise level K, %", floating_point_range=_range(0, 100)),
    ),
    "sample_rate_hz": (
        500.0,
        ParameterDescriptor(description="Hz", floating_point_range=_range(1.0, 1e5)),
    ),
    "phi": (
        1.0,
        ParameterDescriptor(
            description="sigma1^2/sigma2^2", floating_point_range=_range(1e-6, 1e6)
        ),
    ),
    "seed": (
        0,
        ParameterDescriptor(
            description="noise seed",
            integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1, step=1)],
        ),
    ),
    "duration_s": (
        0.0,
        ParameterDescriptor(
            description="simulated length, s (0 = forever)", floating_point_range=_range(0, 1e6)
        ),
    ),
}


class ReplayNode(Node):
    """Publishes a bag's (or simulated) Temperature topics in real time; see the module notes.

    Raises
    ------
    DataError
        When the bag is missing, unreadable or lacks the topics (from :func:`read_bag`).
    """

    def __init__(self, node_name: str = "replay", **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)
        value = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.rate = float(value["rate"])
        self.loop = bool(value["loop"])
        self.wait_for_subscribers = int(value["wait_for_subscribers"])
        if value["signal"] not in SIGNALS:
            raise DataError(f"signal={value['signal']!r} is not one of {', '.join(SIGNALS)}")
        self._live = value["source"] == "simulate"
        if value["source"] == "bag":
            self._load_bag(Path(str(value["bag"])))
        elif value["source"] == "simulate":
            self._simulate(value)
        else:
            raise DataError(f"source={value['source']!r} must be 'bag' or 'simulate'")
        self._topic_publishers = [
            self.create_publisher(Temperature, topic, QOS) for topic in self.topics
        ]
        self._clock_publisher = (
            self.create_publisher(Clock, "/clock", 10) if value["publish_clock"] else None
        )
        self.done = False
        self.published = 0
        self._next = 0
        self._pass = 0
        self._started: float | None = None
        if self.wait_for_subscribers:
            self.get_logger().info(
                f"waiting for {self.wait_for_subscribers} subscription(s) on each of "
                f"{', '.join(self.topics[:2])}"
            )
        self.create_timer(TICK_S, self._tick, clock=RosClock(clock_type=ClockType.STEADY_TIME))

    def _load_bag(self, path: Path) -> None:
        if not str(path) or str(path) == ".":
            raise DataError("parameter 'bag' is empty: give the bag to replay")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", TruncatedInputWarning)
            record = read_bag(path)
        for warning in caught:  # a bag cut short replays up to its last complete record
            if issubclass(warning.category, TruncatedInputWarning):
                self.get_logger().warning(str(warning.message))
        self.topics = [DEFAULT_TOPICS[0].lstrip("/"), DEFAULT_TOPICS[1].lstrip("/")]
        columns = [record.tc1, record.tc2]
        if record.ref is not None:
            self.topics.append(str(DEFAULT_TOPICS[2]).lstrip("/"))
            columns.append(record.ref)
        assert record.stamps_ns is not None  # read_bag always sets them
        self.stamps = record.stamps_ns
        self.values = np.column_stack(columns)
        self.frame_id = record.frame_id
        self.get_logger().info(
            f"replaying {path}: {self.stamps.size} samples on {', '.join(self.topics)} at "
            f"{self.rate:g}x"
        )

    def _simulate(self, value: dict[str, Any]) -> None:
        # Imported here: scipy.signal, which the simulator needs, is most of a second of
        # start-up that a bag replay (or a refused parameter) does not need.
        from tcomp_core.simulate import simulate_pair

        duration = float(value["duration_s"]) or SIMULATED_LOOP_S
        if not float(value["duration_s"]):
            self.loop = True
        data = simulate_pair(
            str(value["signal"]),  # type: ignore[arg-type]
            tau1=float(value["tau1"]),
            tau2=float(value["tau2"]),
            dt=1.0 / float(value["sample_rate_hz"]),
            duration=duration,
            noise_percent=float(value["noise_percent"]),
            phi=float(value["phi"]),
            seed=int(value["seed"]),
        )
        self.topics = [topic.lstrip("/") for topic in DEFAULT_TOPICS if topic]
        start = self.get_clock().now().nanoseconds
        self.stamps = start + np.rint(data.time * 1e9).astype(np.int64)
        self.values = np.column_stack((data.tc1, data.tc2, data.gas))
        self.frame_id = "simulated"

    @property
    def period_ns(self) -> int:
        """Stamp shift from one pass to the next, nanoseconds (length plus the loop gap)."""
        step = int(self.stamps[1] - self.stamps[0]) if self.stamps.size > 1 else 0
        return int(self.stamps[-1] - self.stamps[0]) + (1 + LOOP_GAP_STEPS) * step

    def _tick(self) -> None:
        if self.done:
            return
        if self._started is None:
            sensors = self._topic_publishers[:2]  # the reference is for scoring, not required
            counts = [publisher.get_subscription_count() for publisher in sensors]
            if min(counts) < self.wait_for_subscribers:
                return
            self._started = time.monotonic()
            if self._live:  # live stamps start now, not at construction
                self.stamps = self.stamps - self.stamps[0] + self.get_clock().now().nanoseconds
        elapsed_ns = (time.monotonic() - self._started) * self.rate * 1e9
        due_offset = self.stamps[0] + elapsed_ns - self._pass * self.period_ns
        end = int(np.searchsorted(self.stamps, due_offset, side="right"))
        shift = self._pass * self.period_ns
        for index in range(self._next, end):
            stamp = int(self.stamps[index]) + shift
            sec, nanosec = divmod(stamp, 1_000_000_000)
            for column, publisher in enumerate(self._topic_publishers):
                message = Temperature()
                message.header.stamp.sec = sec
                message.header.stamp.nanosec = nanosec
                message.header.frame_id = self.frame_id
                message.temperature = float(self.values[index, column])
                publisher.publish(message)
            self.published += 1
        if self._clock_publisher is not None and end > self._next:
            clock = Clock()
            clock.clock.sec, clock.clock.nanosec = divmod(int(self.stamps[end - 1]) + shift, 10**9)
            self._clock_publisher.publish(clock)
        self._next = end
        if self._next >= self.stamps.size:
            if self.loop:
                self._pass += 1
                self._next = 0
            else:
                self.done = True
                self.get_logger().info(f"replay finished: {self.published} samples per topic")


def main(args: Sequence[str] | None = None) -> int:
    """Entry point of ``replay_node`` (accepts ``--ros-args``); 1 when the bag cannot be read."""
    rclpy.init(args=None if args is None else list(args))
    try:
        node = ReplayNode()
    except (DataError, ParameterException, ValueError, TypeError) as exc:  # a bad parameter
        print(f"replay_node: error: {' '.join(str(exc).split())}", file=sys.stderr)
        shut_down()
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):  # stopped while loading
        shut_down()
        return 0
    try:
        spin_until_shutdown(node, done=lambda: node.done)
    finally:
        node.destroy_node()
        shut_down()
    return 0


if __name__ == "__main__":
    sys.exit(main())
