"""A compensator node plus a peer node that feeds it and records what it publishes (tests)."""

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from sensor_msgs.msg import Temperature

from tcomp_ros.compensator import CompensatorNode

LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


class Harness:
    """A compensator plus a test node that feeds it and records what it publishes."""

    def __init__(self, context, executor_factory, spin_until, **parameters):
        self.context = context
        self.spin_until = spin_until
        # Feeding pauses between steps of a test; only the silence test wants a short timeout.
        parameters.setdefault("silence_timeout_s", 60.0)
        # The background diagnosis (a worker process) only where a test asks for it.
        parameters.setdefault("diagnosis_period_s", 0.0)
        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        self.node = CompensatorNode(context=context, parameter_overrides=overrides)
        self.peer = context_node(context)
        self.pub = [
            self.peer.create_publisher(Temperature, "tc1/temperature", 1000),
            self.peer.create_publisher(Temperature, "tc2/temperature", 1000),
        ]
        self.gas = []
        self.gas_variance = []
        self.sent = [0, 0]
        self.diagnostics = []
        self.peer.create_subscription(
            Temperature,
            "gas_temperature",
            self._record_gas,
            10000,
        )
        self.peer.create_subscription(
            DiagnosticArray, "/diagnostics", lambda m: self.diagnostics.append(m.status[0]), 100
        )
        self.executor = executor_factory(context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.peer)
        self.spin_until(self.executor, lambda: self.pub[0].get_subscription_count() > 0, 30.0)

    def _record_gas(self, message):
        stamp = message.header.stamp
        self.gas.append((stamp.sec * 10**9 + stamp.nanosec, message.temperature))
        self.gas_variance.append(message.variance)

    def send(self, index, stamp_ns, value):
        message = Temperature()
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(int(stamp_ns), 10**9)
        message.header.frame_id = "probe"
        message.temperature = float(value)
        self.pub[index].publish(message)
        self.sent[index] += 1

    def feed(self, stamps, tc1, tc2, batch=200):
        for start in range(0, len(stamps), batch):
            for k in range(start, min(start + batch, len(stamps))):
                self.send(0, stamps[k], tc1[k])
                self.send(1, stamps[k], tc2[k])
            self.catch_up()

    def catch_up(self, timeout=30.0):
        """Spin until the node has received everything sent so far (keeps queues short)."""
        sent = list(self.sent)
        node = self.node
        assert self.spin_until(
            self.executor,
            lambda: all(node.received[i] >= sent[i] for i in (0, 1)),
            timeout,
        ), f"node received {node.received} of {sent}"

    def settle(self, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def next_diagnostics(self, predicate=lambda status: True, timeout=30.0, since=None):
        """The first status matching ``predicate`` published after ``since`` (default: now).

        The timeout only bounds a failing wait: a suite on both cores of a loaded CI machine
        took more than 5 s to the first estimate's report.
        """
        seen = len(self.diagnostics) if since is None else since

        def arrived():
            return any(predicate(status) for status in self.diagnostics[seen:])

        assert self.spin_until(self.executor, arrived, timeout), (
            f"no matching diagnostics; last: {self.last_summary()}"
        )
        return next(status for status in self.diagnostics[seen:] if predicate(status))

    def last_summary(self):
        if not self.diagnostics:
            return "none"
        status = self.diagnostics[-1]
        return f"{LEVELS[status.level[0]]}: {status.message} {values(status)}"


def context_node(context):
    from rclpy.node import Node

    return Node("test_peer", context=context)


def values(status):
    return {item.key: item.value for item in status.values}


def level(status):
    return LEVELS[status.level[0]]


def stamps_for(count, dt, start_s=100.0):
    return (round(start_s * 1e9) + np.arange(count) * round(dt * 1e9)).astype(np.int64)
