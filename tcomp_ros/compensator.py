"""Compensator node: two Temperature topics in, reconstructed gas temperature and diagnostics out.

Subscribes ``tc1/temperature`` and ``tc2/temperature`` (relative names, remappable) and hands
their samples to the core's online engine (:class:`~tcomp_core.online.Engine`: pair matching by
``header.stamp``, window, reconstruction, health), re-estimates τ1 and τ2 on a timer and
publishes ``gas_temperature`` (one message per reconstructed pair, stamped with that pair's
sample time) and ``/diagnostics`` once a second. The node is an adapter: messages in,
parameters to config (validated in the on-set callback, applied in the post-set callback),
timers; every time the engine sees is the node's clock (``now``), so ``use_sim_time`` works and
``tcomp process`` (which passes stamp time) reads the same.

The published gas is the causal Kalman filter of both sensors by default
(``reconstruction: kalman``): its signal model is fitted in a worker process
(:class:`~tcomp_core.workers.ProcessRunner`) and handed over warm, so the stream never waits for
a fit; τ is re-estimated on a thread (:class:`~tcomp_core.workers.ThreadRunner`: the window's
copy, milliseconds of numpy and scipy that the executor interrupts every few milliseconds to
drain the inputs) and taken at the next drain after it lands. The background diagnosis (every
``diagnosis_period_s`` while the first-order fit is poor
or ``effects`` is set) and the output models it yields with ``compensate_effects`` follow the
engine's rules (:mod:`tcomp_core.online.diagnosis`), as ``tcomp process`` does; the node only
ticks them on its timers.

Subscriptions take serialized messages (``raw=True``) decoded by a fixed-layout codec
(:func:`tcomp_core.io.decode_message`, the one Temperature codec, with its rosbags fallback), and
the callbacks only append to an inbox; a 5 ms timer drains it in batches and publishes serialized
outputs, so the Python cost per message stays a few microseconds.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.timer import Timer
from sensor_msgs.msg import Temperature

from tcomp_core.choices import names_a_saved_diagnosis
from tcomp_core.compensation import OutputModel
from tcomp_core.errors import DataError
from tcomp_core.io import Encoder, decode_message
from tcomp_core.memory import pin_mmap_threshold
from tcomp_core.online import DIAGNOSTICS_PERIOD_S, Engine, GasBatch, Health, OnlineConfig
from tcomp_core.online.health import format_value as _fmt
from tcomp_core.parameters import PARAMETERS, ParameterSpec
from tcomp_core.workers import InlineRunner, ProcessRunner, ThreadRunner

from .spin import LONG_RUN_SLICE_S, shut_down, spin_until_shutdown

__all__ = ["CompensatorNode", "descriptor", "main"]

#: Period of the timer that drains the inbox, match pairs and publishes, seconds.
PROCESS_PERIOD_S = 0.005
#: Longest time a thread of the node holds the interpreter while another waits for it, s.
SWITCH_INTERVAL_S = 0.0005
#: The node waits this long at start for its fitting worker process to be ready, seconds.
WORKER_START_S = 30.0
#: Reliability of the input subscriptions by ``input_reliability``. Best effort (the default)
#: receives from best-effort publishers (sensor drivers, REP 2003's SensorDataQoS) and reliable
#: ones alike; reliable receives from reliable publishers only.
INPUT_RELIABILITY = {
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
    "reliable": ReliabilityPolicy.RELIABLE,
}
#: Deep enough for the pairs held until the first τ, published in one go (up to a window).
OUTPUT_QOS = QoSProfile(
    depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
)
#: Gas messages of held pairs published per drain beside the drain's own: the pairs held until
#: the first τ and filter (up to a window) go out over several drains at 15 000 a second more
#: than the stream's rate, so a subscriber that keeps up with the stream keeps up with them.
BACKLOG_PER_DRAIN = 75


def _float_range(low: float, high: float) -> list[FloatingPointRange]:
    # float(): an int given to the float64 fields is advertised as garbage (5e-324).
    return [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """The ROS descriptor of a declared parameter: description, range, choices, read-only."""
    extra: dict[str, Any] = {}
    if spec.kind is float and spec.low is not None and spec.high is not None:
        extra["floating_point_range"] = _float_range(spec.low, spec.high)
    if spec.kind is int and spec.low is not None and spec.high is not None:
        extra["integer_range"] = [
            IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
        ]
    if spec.choices:
        extra["additional_constraints"] = f"one of {', '.join(spec.choices)}"
    return ParameterDescriptor(description=spec.description, read_only=spec.read_only, **extra)


class CompensatorNode(Node):
    """Two-thermocouple compensator; see the module notes.

    Parameters
    ----------
    node_name : str
        Node name ('compensator').
    background : bool
        Fit the Kalman filter's signal model and run the diagnoses in worker processes and the
        τ re-estimation on a thread (the default, so the stream never waits); False runs them
        inline, at the stamp where they are asked for, as ``tcomp process`` does (a replay
        that must match it sample for sample).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``).
    """

    def __init__(self, node_name: str = "compensator", background: bool = True, **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        for spec in PARAMETERS:
            self.declare_parameter(spec.name, spec.default, descriptor(spec))
        self._values = {spec.name: self.get_parameter(spec.name).value for spec in PARAMETERS}
        fits = ProcessRunner() if background else None
        diagnoses = ProcessRunner() if background else InlineRunner()
        estimates = ThreadRunner("tcomp-estimate") if background else None
        if background:
            # The executor's thread gives the interpreter up at every rclpy call (take,
            # publish, wait) and then waits for the estimating thread to hand it back: at
            # most this long (Python's default, 5 ms, stretched a drain of 100 messages).
            sys.setswitchinterval(SWITCH_INTERVAL_S)
        self._engine = Engine(
            OnlineConfig.from_parameters(self._values),
            runner=fits,
            diagnosis_runner=diagnoses,
            estimate_runner=estimates,
        )
        # The worker's imports take seconds: wait for them here, before any sample is taken,
        # so the first pairs are reconstructed with a fitted model instead of an interim one.
        kalman = self._values["reconstruction"] == "kalman"
        if fits is not None and kalman and not fits.start(wait_s=WORKER_START_S):
            self.get_logger().warning(
                f"the fitting worker is not ready after {WORKER_START_S:g} s; the first "
                "pairs may be published with an interim model"
            )
        # Per input: stamps (ns) and values of the messages not yet handed to the engine.
        self._inbox: list[tuple[list[int], list[float]]] = [([], []), ([], [])]
        self._received = [0, 0]
        self._frame_id = ""
        self._callback_errors = 0
        self._last_callback_error = ""
        self._latency = LatencyHistogram()
        self._outbox: deque[GasBatch] = deque()  # gas waiting for the publisher

        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._gas_pub = self.create_publisher(Temperature, "gas_temperature", OUTPUT_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        reliability = str(self._values["input_reliability"])
        if reliability not in INPUT_RELIABILITY:
            raise ValueError(
                f"input_reliability={reliability!r} is not one of {', '.join(INPUT_RELIABILITY)}"
            )
        input_qos = QoSProfile(
            depth=1000,
            history=HistoryPolicy.KEEP_LAST,
            reliability=INPUT_RELIABILITY[reliability],
        )
        for index, topic in enumerate(("tc1/temperature", "tc2/temperature")):
            self.create_subscription(
                Temperature, topic, partial(self._on_sample, index), input_qos, raw=True
            )
        self._encoder = Encoder("")
        self.create_timer(PROCESS_PERIOD_S, self._process)
        self._estimate_timer = self.create_timer(
            self._values["update_period_s"], self.update_estimate
        )
        self.create_timer(
            DIAGNOSTICS_PERIOD_S, lambda: self._guarded("diagnostics", self.publish_diagnostics)
        )
        self._diagnosis_timer: Timer | None = None
        self._start_diagnosis_timer()

    def destroy_node(self) -> None:
        """Stop the worker processes (abandoning running jobs), then destroy the node."""
        self._engine.close()
        super().destroy_node()

    # -- state -------------------------------------------------------------------------------
    @property
    def engine(self) -> Engine:
        """The online engine (read it, do not feed it: the node's callbacks do)."""
        return self._engine

    @property
    def received(self) -> tuple[int, int]:
        """Messages received per input, ``(tc1, tc2)``, whether handed to the engine yet or not."""
        return self._received[0], self._received[1]

    @property
    def matched_pairs(self) -> int:
        """Sample pairs matched so far."""
        return self._engine.counters.matched

    def _now(self) -> float:
        """The node's clock, seconds (ROS time: simulated time under ``use_sim_time``)."""
        return self.get_clock().now().nanoseconds * 1e-9

    # -- parameters --------------------------------------------------------------------------
    def _start_diagnosis_timer(self) -> None:
        """(Re)create the timer of the periodic diagnosis; none when the period is 0."""
        if self._diagnosis_timer is not None:
            self._diagnosis_timer.cancel()
            self.destroy_timer(self._diagnosis_timer)
            self._diagnosis_timer = None
        period = float(self._values["diagnosis_period_s"])
        if period > 0.0:
            self._diagnosis_timer = self.create_timer(
                period,
                lambda: self._guarded(
                    "diagnosis", lambda: self._engine.periodic_diagnosis(self._now())
                ),
            )

    def _validate_parameters(self, parameters: Sequence[Parameter]) -> SetParametersResult:
        """On-set callback: accept a change only when every value is sound, as a whole."""
        values = dict(self._values)
        values.update({parameter.name: parameter.value for parameter in parameters})
        try:
            OnlineConfig.from_parameters(values)
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: Sequence[Parameter]) -> None:
        """Post-set callback: apply a change the on-set callback has accepted."""
        values = dict(self._values)
        values.update({parameter.name: parameter.value for parameter in parameters})
        changed = {name for name in values if values[name] != self._values[name]}
        # A saved diagnosis is read again whenever it is set, its path the same or not.
        changed |= {
            parameter.name
            for parameter in parameters
            if parameter.name == "effects"
            and isinstance(parameter.value, str)
            and names_a_saved_diagnosis(parameter.value)
        }
        if not changed:
            self._values = values
            return
        try:
            config = OnlineConfig.from_parameters(values)
        except (ValueError, TypeError) as exc:  # a saved diagnosis gone since it was checked
            self.get_logger().error(f"parameters not applied, the engine keeps its own: {exc}")
            return
        self._values = values
        self._engine.reconfigure(config)
        if "update_period_s" in changed:
            self._estimate_timer.cancel()
            self.destroy_timer(self._estimate_timer)
            self._estimate_timer = self.create_timer(
                float(values["update_period_s"]), self.update_estimate
            )
        if "diagnosis_period_s" in changed:
            self._start_diagnosis_timer()
        if self._engine.diagnosis.wanted:
            self._engine.diagnosis.start(self._now(), self._engine.compensator)
        self._flush_log()
        self.get_logger().info(
            "parameters changed: " + ", ".join(f"{n}={values[n]!r}" for n in sorted(changed))
        )

    # -- data path ---------------------------------------------------------------------------
    def _on_sample(self, index: int, data: bytes) -> None:
        """Subscription callback: decode the stamp and value and put them in the inbox.

        A message that cannot be decoded is counted (``malformed_tc1/2``), reported in the
        diagnostics and skipped: the callback never raises into the executor.
        """
        try:
            stamp, frame_id, value = self._decode(data)
        except Exception as exc:  # any bytes may arrive on a topic; none may stop the node
            reason = f"{len(data)} bytes: {type(exc).__name__}: {exc}"[:200]
            self._engine.malformed(index, reason)
            self.get_logger().warning(
                f"{('tc1', 'tc2')[index]}: malformed message skipped ({reason})",
                throttle_duration_sec=5.0,
            )
            return
        self._received[index] += 1
        if index == 0 and not self._frame_id:
            self._frame_id = frame_id
        stamps, values = self._inbox[index]
        stamps.append(stamp)
        values.append(value)

    @staticmethod
    def _decode(data: bytes) -> tuple[int, str, float]:
        """Stamp (ns), frame_id and value of a serialized Temperature."""
        try:
            stamp, frame_id, value, _ = decode_message(data)
        except ValueError:  # another CDR layout: let rclpy decode it
            message = deserialize_message(data, Temperature)
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            frame_id, value = message.header.frame_id, message.temperature
        return int(stamp), str(frame_id), float(value)

    def _guarded(self, what: str, callback: Callable[[], object]) -> None:
        """Run a timer's work; an exception is counted, logged and reported, never raised."""
        try:
            callback()
        except Exception as exc:  # the node must outlive any input
            self._callback_errors += 1
            self._last_callback_error = f"{what}: {type(exc).__name__}: {exc}"[:200]
            self.get_logger().error(self._last_callback_error, throttle_duration_sec=5.0)

    def _process(self) -> None:
        """Timer: hand the inbox to the engine and publish the gas samples it reconstructs."""
        self._guarded("process", self._process_inbox)

    def _process_inbox(self) -> None:
        now = self._now()
        engine = self._engine
        drained = max(len(self._inbox[0][0]), len(self._inbox[1][0]))  # pairs at most
        for index in (0, 1):
            stamps, values = self._inbox[index]
            if stamps:
                self._inbox[index] = ([], [])
                engine.add_samples(index, stamps, values, now)
        try:
            out = engine.reconstruct()
        except DataError as exc:  # never die on data: count, report, carry on
            self._callback_errors += 1
            self._last_callback_error = f"pairs refused: {exc}"[:200]
            self.get_logger().warning(self._last_callback_error, throttle_duration_sec=5.0)
            out = GasBatch.empty()
        if out.stamps_ns.size:
            self._outbox.append(out)
        self._publish_outbox(drained)

    def _publish_outbox(self, drained: int) -> None:
        """Publish what waits, oldest first: the drain's share, :data:`BACKLOG_PER_DRAIN` more."""
        budget = drained + BACKLOG_PER_DRAIN
        while self._outbox and budget > 0:
            batch = self._outbox.popleft()
            if batch.stamps_ns.size > budget:
                batch, rest = batch.split(budget)
                self._outbox.appendleft(rest)
            budget -= batch.stamps_ns.size
            self._publish(batch)

    def _publish(self, out: GasBatch) -> None:
        """Hand gas samples to the publisher and record their latency."""
        if not out.stamps_ns.size:
            return
        engine = self._engine
        frame_id = self._values["frame_id"] or self._frame_id
        if frame_id != self._encoder.frame_id:
            self._encoder = Encoder(frame_id)
        encode, publish = self._encoder.encode, self._gas_pub.publish
        outputs = zip(out.stamps_ns.tolist(), out.gas.tolist(), out.variance.tolist(), strict=True)
        for stamp, value, variance in outputs:
            publish(encode(stamp, value, variance))
        period = engine.compensator.period_s
        if period:
            # From the stamp of the input pair that completed each output to its publication.
            inputs = out.stamps_ns + round(period * 1e9)
            self._latency.add((time.time_ns() - inputs) * 1e-6)

    def update_estimate(self) -> None:
        """Re-estimate τ1, τ2 now (the timer calls this every ``update_period_s``)."""
        self._guarded("estimate", lambda: self._engine.update_estimate(self._now()))

    # -- the published model ------------------------------------------------------------------
    def use_output_model(
        self,
        model: OutputModel | None,
        origin_ns: int = 0,
        record: tuple | None = None,
        note: str = "",
    ) -> None:
        """Publish the gas of ``model`` once it is built (None: first order), saying why.

        A caller may hand a model fitted elsewhere (e.g. the one ``tcomp process --effects``
        fitted), with the stamps of its record's first sample; it is not judged (see
        :meth:`tcomp_core.online.diagnosis.DiagnosisPolicy.adopt` for that).
        """
        compensator = self._engine.compensator
        compensator.use_output_model(model, origin_ns, record)
        compensator.output_note = note

    def _flush_log(self) -> None:
        """Log what the engine's diagnosis did since the last call."""
        log, self._engine.diagnosis.log = self._engine.diagnosis.log, []
        for level, message in log:
            if level == "warning":
                self.get_logger().warning(message, throttle_duration_sec=60.0)
            else:
                self.get_logger().info(message)

    # -- diagnostics -------------------------------------------------------------------------
    def health_status(self, new_period: bool = False) -> DiagnosticStatus:
        """The current diagnostic status (also published once a second).

        Parameters
        ----------
        new_period : bool
            Start a new report period (the diagnostics timer does).
        """
        extra = {
            **self._latency.summary(),
            "callback_errors": str(self._callback_errors),
            "last_callback_error": self._last_callback_error,
        }
        health: Health = self._engine.report(self._now(), extra, new_period=new_period)
        return DiagnosticStatus(
            level=bytes([int(health.level)]),
            name=f"tcomp: {self.get_name()}",
            message=health.message,
            hardware_id=str(self._values["hardware_id"]),
            values=[KeyValue(key=key, value=value) for key, value in health.values.items()],
        )

    def publish_diagnostics(self) -> None:
        """Publish the status on /diagnostics and start a new report period.

        Also ticks the engine's diagnosis: collects a finished job, starts one that was asked
        for while the worker was busy or the window too short.
        """
        self._engine.poll_diagnosis(self._now())
        self._flush_log()
        status = self.health_status(new_period=True)
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [status]
        self._diag_pub.publish(array)
        self._latency.new_period()


class LatencyHistogram:
    """Publish latencies in 0.1 ms bins (0–2 s), for this report period and since the start.

    Latency is measured against the node's wall clock, so it is meaningful when the input stamps
    come from a synchronised clock (live sensors); replayed bags carry old stamps.
    """

    BIN_MS = 0.1
    BINS = 20_000

    def __init__(self) -> None:
        self._total = np.zeros(self.BINS, dtype=np.int64)
        self._period = np.zeros(self.BINS, dtype=np.int64)

    def add(self, latencies_ms: np.ndarray) -> None:
        """Count a batch of latencies, milliseconds (clipped to the histogram's range)."""
        bins = np.clip((latencies_ms / self.BIN_MS).astype(np.int64), 0, self.BINS - 1)
        counts = np.bincount(bins, minlength=self.BINS)
        self._total += counts
        self._period += counts

    def new_period(self) -> None:
        """Start a new report period."""
        self._period[:] = 0

    def summary(self) -> dict[str, str]:
        """p50 / p99 / max of the period and p99 since the start, milliseconds."""
        return {
            "latency_p50_ms": _fmt(self._quantile(self._period, 0.50)),
            "latency_p99_ms": _fmt(self._quantile(self._period, 0.99)),
            "latency_max_ms": _fmt(self._quantile(self._period, 1.0)),
            "latency_p99_total_ms": _fmt(self._quantile(self._total, 0.99)),
        }

    def _quantile(self, counts: np.ndarray, q: float) -> float:
        total = int(counts.sum())
        if total == 0:
            return math.nan
        index = int(np.searchsorted(np.cumsum(counts), math.ceil(q * total)))
        return (index + 1) * self.BIN_MS


def main(args: Sequence[str] | None = None) -> int:
    """Entry point of ``compensator_node`` (accepts ``--ros-args``)."""
    pin_mmap_threshold()  # weeks of window-sized numpy arrays must not fragment the heap
    rclpy.init(args=None if args is None else list(args))
    try:
        node = CompensatorNode()
    except (ParameterException, ValueError, TypeError) as exc:  # a bad value given at start
        print(f"compensator_node: error: {' '.join(str(exc).split())}", file=sys.stderr)
        shut_down()
        return 1
    try:
        spin_until_shutdown(node, timeout_sec=LONG_RUN_SLICE_S)  # weeks: few slices
    finally:
        node.destroy_node()
        shut_down()
    return 0


if __name__ == "__main__":
    sys.exit(main())
