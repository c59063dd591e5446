"""Compensator node: two Temperature topics in, reconstructed gas temperature and diagnostics out.

Subscribes ``tc1/temperature`` and ``tc2/temperature`` (relative names, remappable) and hands
their samples to the core's online engine (:class:`~tcomp_core.online.Engine`: pair matching by
``header.stamp``, window, reconstruction, health), re-estimates τ1 and τ2 on a timer and
publishes ``gas_temperature`` (one message per reconstructed pair, stamped with that pair's
sample time) and ``/diagnostics`` once a second. The node is an adapter: messages in,
parameters to config (validated in the on-set callback, applied in the post-set callback),
timers; every time the engine sees is the node's clock (``now``), so ``use_sim_time`` works and
``tcomp process`` (which passes stamp time) reads the same.

Every ``diagnosis_period_s`` while the first-order fit is poor or effects are set (and at once
when the parameter ``effects`` changes) the longest gap-free stretch of the window is diagnosed
in a worker process
(:class:`~tcomp_core.diagnose.background.BackgroundDiagnoser`): the base model plus the requested
effects is fitted and, when the fit is poor or effects were requested, the effect the base model
misses most is looked for (``effects: auto``: the whole diagnosis, its final model). The
diagnostics carry the held-out errors with and without the effects and the top suspect. A model
that fits is not diagnosed: a job costs seconds of CPU, which a 2-core machine feels in the
latency.

With ``compensate_effects`` the newest gap-free pairs (with their stamps) are diagnosed instead,
and a fit that lands with an effect a stream can apply, no parameter on a bound and a held-out
error at least :data:`MIN_ERROR_FALL` below first order's becomes the published model
(:meth:`tcomp_core.online.OnlineCompensator.use_output_model`, primed on the newest pairs so
that no stamp is skipped or repeated); a later fit that fails, a fit older than
:data:`OUTPUT_STALE_PERIODS` diagnosis periods, or ``compensate_effects: false`` return to first
order. The ``output_model`` keys of the diagnostics say which model the gas uses, since when
and why.

Subscriptions take serialized messages (``raw=True``) decoded by a fixed-layout codec
(:func:`tcomp_core.io.decode_message`, the one Temperature codec, with its rosbags fallback), and
the callbacks only append to an inbox; a 5 ms timer drains it in batches and publishes serialized
outputs, so the Python cost per message stays a few microseconds.
"""

from __future__ import annotations

import math
import sys
import time
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

from tcomp_core.compensation import OutputModel
from tcomp_core.diagnose.background import BackgroundDiagnoser, parse_effects
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.errors import DataError
from tcomp_core.estimators import DEFAULT_METHOD, METHODS
from tcomp_core.io import Encoder, decode_message
from tcomp_core.online import (
    DIAGNOSTICS_PERIOD_S,
    RECONSTRUCT_FROM,
    RECONSTRUCTIONS,
    SIGNAL_MODELS,
    Engine,
    GasBatch,
    Health,
    Level,
    OnlineConfig,
)
from tcomp_core.online.health import format_value as _fmt

from .spin import spin_until_shutdown

__all__ = ["CompensatorNode", "main"]

#: Period of the timer that drains the inbox, match pairs and publishes, seconds.
PROCESS_PERIOD_S = 0.005
#: Reliability of the input subscriptions by ``input_reliability``. Best effort (the default)
#: receives from best-effort publishers (sensor drivers, REP 2003's SensorDataQoS) and reliable
#: ones alike; reliable receives from reliable publishers only.
INPUT_RELIABILITY = {
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
    "reliable": ReliabilityPolicy.RELIABLE,
}
OUTPUT_QOS = QoSProfile(
    depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
)
#: The background diagnosis needs a gap-free stretch of the window this long, seconds ...
MIN_DIAGNOSIS_S = 2.0
#: ... holding at least this many samples.
MIN_DIAGNOSIS_SAMPLES = 1000
#: A job diagnoses at most the newest this many seconds of it (its cost grows with the length).
MAX_DIAGNOSIS_S = 60.0
#: Shortest period of the background diagnosis, seconds (a job takes seconds anyway).
MIN_DIAGNOSIS_PERIOD_S = 1.0
#: A fit compensates the published gas when it lowers the held-out error by this share ...
MIN_ERROR_FALL = 0.2
#: ... and until it is this many diagnosis periods old without a newer accepted fit.
OUTPUT_STALE_PERIODS = 3.0
#: Pairs run through a new output model before it takes over (its filters warm up).
PRIME_PAIRS = 2000


def _float_range(low: float, high: float) -> list[FloatingPointRange]:
    # float(): an int given to the float64 fields is advertised as garbage (5e-324).
    return [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]


def _descriptor(description: str, **kwargs) -> ParameterDescriptor:
    return ParameterDescriptor(description=description, **kwargs)


PARAMETERS: dict[str, tuple[object, ParameterDescriptor]] = {
    "window_s": (
        2.0,
        _descriptor("estimation window length, s", floating_point_range=_float_range(0.05, 3600)),
    ),
    "update_period_s": (
        0.5,
        _descriptor("period of re-estimation, s", floating_point_range=_float_range(0.01, 60)),
    ),
    "method": (
        DEFAULT_METHOD,
        _descriptor("estimator", additional_constraints=f"one of {', '.join(METHODS)}"),
    ),
    "phi": (
        1.0,
        _descriptor(
            "noise variance ratio sigma1^2/sigma2^2", floating_point_range=_float_range(1e-6, 1e6)
        ),
    ),
    "prefilter_hz": (
        0.0,
        _descriptor(
            "zero-phase pre-filter on the window before estimation, Hz (0 = off)",
            floating_point_range=_float_range(0.0, 1e6),
        ),
    ),
    "postfilter_hz": (
        0.0,
        _descriptor(
            "causal Butterworth low-pass on gas_temperature, Hz (0 = off)",
            floating_point_range=_float_range(0.0, 1e6),
        ),
    ),
    "sync_slop_s": (
        0.0,
        _descriptor(
            "largest stamp difference of a tc1/tc2 pair, s (0 = exact stamps)",
            floating_point_range=_float_range(0.0, 1.0),
        ),
    ),
    "reconstruct_from": (
        "fused",
        _descriptor(
            "which reconstruction is published",
            additional_constraints=f"one of {', '.join(RECONSTRUCT_FROM)}",
        ),
    ),
    "reconstruction": (
        "difference",
        _descriptor(
            "'difference': Eq. (7) per sensor, combined by reconstruct_from; 'kalman': causal "
            "Kalman filter of both sensors, its signal model fitted on the window (the "
            "published variance is then its own)",
            additional_constraints=f"one of {', '.join(RECONSTRUCTIONS)}",
        ),
    ),
    "signal_model": (
        "random-walk",
        _descriptor(
            "gas temperature model of the Kalman filter; 'auto' fits all (~1.5 s per refit "
            "on the estimation timer, against ~0.1 s for one)",
            additional_constraints=f"one of {', '.join(SIGNAL_MODELS)}",
        ),
    ),
    "tracking_memory_s": (
        0.0,
        _descriptor(
            "forgetting time of a tau that changes with the flow, s: tau from an exponentially "
            "forgetting beta-GTLS with tau1/tau2 held to its long-term value (0 = the window)",
            floating_point_range=_float_range(0.0, 3600),
        ),
    ),
    "hardware_id": ("thermocouple-pair", _descriptor("hardware_id of the diagnostic status")),
    "sample_period_s": (
        0.0,
        _descriptor(
            "sample period of the pairs, s (0 = learn from the stamps)",
            floating_point_range=_float_range(0.0, 10.0),
        ),
    ),
    "silence_timeout_s": (
        1.0,
        _descriptor(
            "a sensor silent this long is an ERROR, s",
            floating_point_range=_float_range(0.01, 3600),
        ),
    ),
    "max_condition": (
        1e3,
        _descriptor(
            "estimates with a larger condition figure are refused",
            floating_point_range=_float_range(1.0, 1e12),
        ),
    ),
    "max_model_error_pct": (
        10.0,
        _descriptor(
            "model error above which the fit is poor (WARN), percent",
            floating_point_range=_float_range(0.01, 1000),
        ),
    ),
    "queue_size": (
        2000,
        _descriptor(
            "unmatched samples kept per input",
            integer_range=[IntegerRange(from_value=1, to_value=10**6, step=1)],
        ),
    ),
    "frame_id": ("", _descriptor("frame_id of gas_temperature ('' = that of tc1)")),
    "input_reliability": (
        "best_effort",
        _descriptor(
            "reliability of the tc1/tc2 subscriptions: best_effort receives from best-effort "
            "and reliable publishers alike, reliable from reliable ones only (read at start)",
            additional_constraints=f"one of {', '.join(INPUT_RELIABILITY)}",
            read_only=True,
        ),
    ),
    "min_temperature_c": (
        -273.15,
        _descriptor(
            "readings below are invalid (counted, reported, left out), degrees C",
            floating_point_range=_float_range(-273.15, 1e6),
        ),
    ),
    "max_temperature_c": (
        2000.0,
        _descriptor(
            "readings above are invalid (counted, reported, left out), degrees C",
            floating_point_range=_float_range(-273.15, 1e6),
        ),
    ),
    "max_window_samples": (
        500_000,
        _descriptor(
            "memory budget of the window in sample pairs (48 bytes each): a window_s that "
            "needs more at sample_period_s is refused, a learnt period clips the window",
            integer_range=[IntegerRange(from_value=100, to_value=10**8, step=1)],
        ),
    ),
    "discontinuity_s": (
        10.0,
        _descriptor(
            "stamps this far behind the last matched one, several in a row, restart the "
            "window (a clock reset or a bag starting over), s",
            floating_point_range=_float_range(0.001, 1e9),
        ),
    ),
    "effects": (
        "",
        _descriptor(
            "effects the background diagnosis adds to the first-order model, comma-separated "
            "('' = none), or 'auto' (the diagnosis's final model); they change the diagnosis "
            "and the error it reports, and with compensate_effects the published gas",
            additional_constraints=f"'auto' or names from {', '.join(EFFECT_NAMES)}, each at "
            "most once",
        ),
    ),
    "compensate_effects": (
        False,
        _descriptor(
            "publish gas_temperature compensated with the background fit of effects once it "
            "lands, lowers the held-out error by 20 % with no parameter on a bound, and while "
            "it is fresh (3 diagnosis periods); first order otherwise (see output_model in "
            "/diagnostics)"
        ),
    ),
    "diagnosis_period_s": (
        10.0,
        _descriptor(
            "period of the background diagnosis of the window while the fit is poor or "
            "effects is set, s (0 = only when effects changes); one job at a time, each "
            "taking seconds in a worker process",
            floating_point_range=_float_range(0.0, 3600),
            additional_constraints=f"0 or >= {MIN_DIAGNOSIS_PERIOD_S:g}",
        ),
    ),
}

#: Parameters that configure the numerical engine (tcomp_core.online.OnlineConfig).
ENGINE_PARAMETERS = (
    "window_s",
    "method",
    "phi",
    "prefilter_hz",
    "postfilter_hz",
    "reconstruct_from",
    "reconstruction",
    "signal_model",
    "tracking_memory_s",
    "sample_period_s",
    "max_condition",
    "max_model_error_pct",
    "min_temperature_c",
    "max_temperature_c",
    "max_window_samples",
    "discontinuity_s",
)


class CompensatorNode(Node):
    """Two-thermocouple compensator; see the module notes.

    Parameters
    ----------
    node_name : str
        Node name ('compensator').
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``).
    """

    def __init__(self, node_name: str = "compensator", **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)
        self._values = {name: self.get_parameter(name).value for name in PARAMETERS}
        self._engine = Engine(
            self._engine_config(self._values),
            slop_ns=round(float(self._values["sync_slop_s"]) * 1e9),
            queue_size=int(self._values["queue_size"]),
            update_period_s=float(self._values["update_period_s"]),
            silence_timeout_s=float(self._values["silence_timeout_s"]),
        )
        self._effects = self._diagnosis_effects(self._values)
        # Per input: stamps (ns) and values of the messages not yet handed to the engine.
        self._inbox: list[tuple[list[int], list[float]]] = [([], []), ([], [])]
        self._received = [0, 0]
        self._frame_id = ""
        self._callback_errors = 0
        self._last_callback_error = ""
        self._latency = LatencyHistogram()
        self._diagnoser = BackgroundDiagnoser()
        self._diagnosis: dict[str, Any] = {}  # the latest successful diagnosis
        self._diagnosis_error = ""
        self._diagnosis_at = math.nan  # when the data of that diagnosis were taken (clock, s)
        self._submitted_at = math.nan
        self._submitted: tuple[tuple[str, ...] | None, tuple | None] = ((), None)
        self._output_fitted_at = math.nan  # when the data of the output model were taken
        # Start a job as soon as the window is long enough and the worker free.
        self._diagnosis_wanted = self._effects_set

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
        """Stop the diagnosis worker (abandoning a running job), then destroy the node."""
        self._diagnoser.close()
        super().destroy_node()

    # -- state -------------------------------------------------------------------------------
    @property
    def _effects_set(self) -> bool:
        """Whether effects (or ``auto``) are asked for."""
        return self._effects is None or bool(self._effects)

    @property
    def _compensating(self) -> bool:
        return bool(self._values["compensate_effects"])

    @property
    def engine(self) -> Engine:
        """The online engine (read it, do not feed it: the node's callbacks do)."""
        return self._engine

    @property
    def received(self) -> tuple[int, int]:
        """Messages received per input, ``(tc1, tc2)``, whether handed to the engine yet or not."""
        return self._received[0], self._received[1]

    def _now(self) -> float:
        """The node's clock, seconds (ROS time: simulated time under ``use_sim_time``)."""
        return self.get_clock().now().nanoseconds * 1e-9

    # -- parameters --------------------------------------------------------------------------
    @staticmethod
    def _engine_config(values: dict[str, Any]) -> OnlineConfig:
        return OnlineConfig(**{name: values[name] for name in ENGINE_PARAMETERS})

    @staticmethod
    def _diagnosis_effects(values: dict[str, Any]) -> tuple[str, ...] | None:
        """The requested effects (None: ``auto``); ValueError on a bad name or period."""
        period = float(values["diagnosis_period_s"])
        if 0.0 < period < MIN_DIAGNOSIS_PERIOD_S:
            raise ValueError(
                f"diagnosis_period_s={period!r} must be 0 (no periodic diagnosis) or "
                f">= {MIN_DIAGNOSIS_PERIOD_S} s"
            )
        text = str(values["effects"]).strip()
        return None if text == "auto" else parse_effects(text)

    def _start_diagnosis_timer(self) -> None:
        """(Re)create the timer of the periodic diagnosis; none when the period is 0."""
        if self._diagnosis_timer is not None:
            self._diagnosis_timer.cancel()
            self.destroy_timer(self._diagnosis_timer)
            self._diagnosis_timer = None
        period = float(self._values["diagnosis_period_s"])
        if period > 0.0:
            self._diagnosis_timer = self.create_timer(
                period, lambda: self._guarded("diagnosis", self._periodic_diagnosis)
            )

    def _periodic_diagnosis(self) -> None:
        """Diagnose while the first-order fit is poor or effects are set; else spare the CPU.

        A job costs the worker seconds of CPU and the node the copy of the window; on a small
        machine that shows in the publish latency, for nothing when the model fits.
        """
        self._check_output_age()
        status = self._engine.last_status
        if self._effects_set or (status is not None and status.poor_fit):
            self.start_diagnosis()

    def _validate_parameters(self, parameters: Sequence[Parameter]) -> SetParametersResult:
        """On-set callback: accept a change only when every value is sound, as a whole."""
        values = dict(self._values)
        values.update({parameter.name: parameter.value for parameter in parameters})
        try:
            self._engine_config(values)
            self._diagnosis_effects(values)
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: Sequence[Parameter]) -> None:
        """Post-set callback: apply a change the on-set callback has accepted."""
        values = dict(self._values)
        values.update({parameter.name: parameter.value for parameter in parameters})
        changed = {name for name in values if values[name] != self._values[name]}
        self._values = values
        if changed & set(ENGINE_PARAMETERS):
            self._engine.reconfigure(self._engine_config(values))
        if changed & {"sync_slop_s", "queue_size"}:
            self._engine.set_matching(
                round(float(values["sync_slop_s"]) * 1e9), int(values["queue_size"])
            )
        if changed & {"update_period_s", "silence_timeout_s"}:
            self._engine.set_timing(
                float(values["update_period_s"]), float(values["silence_timeout_s"])
            )
        effects = self._diagnosis_effects(values)
        if "update_period_s" in changed:
            self._estimate_timer.cancel()
            self.destroy_timer(self._estimate_timer)
            self._estimate_timer = self.create_timer(
                float(values["update_period_s"]), self.update_estimate
            )
        if "diagnosis_period_s" in changed:
            self._start_diagnosis_timer()
        if "compensate_effects" in changed and not self._compensating:
            self._set_output(None, "compensate_effects is false")
        if effects != self._effects or ("compensate_effects" in changed and self._compensating):
            self._effects = effects
            self._diagnosis_wanted = True
            self.start_diagnosis()
        if changed:
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
        for index in (0, 1):
            stamps, values = self._inbox[index]
            if stamps:
                self._inbox[index] = ([], [])
                engine.add_samples(index, stamps, values, now)
        period = engine.compensator.period_s
        if self._compensating and period and engine.recent is None:
            engine.keep_recent(round(MAX_DIAGNOSIS_S / period))
        try:
            out = engine.reconstruct()
        except DataError as exc:  # never die on data: count, report, carry on
            self._callback_errors += 1
            self._last_callback_error = f"pairs refused: {exc}"[:200]
            self.get_logger().warning(self._last_callback_error, throttle_duration_sec=5.0)
            return
        self._publish(out)

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

    @property
    def matched_pairs(self) -> int:
        """Sample pairs matched so far."""
        return self._engine.counters.matched

    def update_estimate(self) -> None:
        """Re-estimate τ1, τ2 now (the timer calls this every ``update_period_s``)."""
        self._guarded("estimate", lambda: self._engine.update_estimate(self._now()))

    # -- background diagnosis ----------------------------------------------------------------
    def _diagnosis_segment(self) -> np.ndarray | None:
        """The window's longest gap-free stretch, shape (n, 2), if long enough to diagnose.

        At most its newest :data:`MAX_DIAGNOSIS_S` seconds; degrees C.
        """
        period = self._engine.compensator.period_s
        if not period:
            return None
        longest = self._engine.compensator.longest_segment()
        needed = max(MIN_DIAGNOSIS_SAMPLES, round(MIN_DIAGNOSIS_S / period))
        if longest.shape[0] < needed:
            return None
        return longest[-max(needed, round(MAX_DIAGNOSIS_S / period)) :]

    def start_diagnosis(self) -> bool:
        """Diagnose the window in the background now (the timer calls this periodically).

        Returns
        -------
        bool
            Whether a job started; not while one runs or the window is too short.
        """
        self._collect_diagnosis()  # a finished job's result belongs to the previous submit
        record = self._output_record() if self._compensating else None
        segment = np.column_stack(record[1:]) if record is not None else self._diagnosis_segment()
        if segment is None or self._diagnoser.busy:
            return False
        period = float(self._engine.compensator.period_s or math.nan)
        status = self._engine.last_status
        try:
            started = self._diagnoser.submit(
                np.arange(segment.shape[0]) * period,
                segment[:, 0],
                segment[:, 1],
                period,
                effects=self._effects,
                find_suspect=self._effects_set or bool(status and status.poor_fit),
                output=record is not None,
            )
        except Exception as exc:  # never die for the diagnosis (e.g. no worker could start)
            self._diagnosis_error = f"{type(exc).__name__}: {exc}"
            self.get_logger().warning(
                f"diagnosis not started: {self._diagnosis_error}", throttle_duration_sec=60.0
            )
            return False
        if started:
            self._submitted_at = self._now()
            self._submitted = (self._effects, record)
            self._diagnosis_wanted = False
        return started

    def _output_record(self) -> tuple | None:
        """The newest gap-free pairs with stamps (at most MAX_DIAGNOSIS_S), if long enough."""
        engine = self._engine
        period = engine.compensator.period_s
        if not period or engine.recent is None or engine.recent.size == 0:
            return None
        stamps, tc1, tc2 = engine.recent.newest(engine.compensator.config.gap_factor)
        needed = max(MIN_DIAGNOSIS_SAMPLES, round(MIN_DIAGNOSIS_S / period))
        if stamps.size < needed:
            return None
        return stamps, tc1, tc2

    # -- the published model ------------------------------------------------------------------
    def use_output_model(
        self,
        model: OutputModel | None,
        origin_ns: int = 0,
        record: tuple | None = None,
        note: str = "",
    ) -> None:
        """Publish the gas of ``model`` from now on (None: first order), saying why in ``note``.

        The background fit calls this; a caller may hand a model fitted elsewhere (e.g. the
        one ``tcomp process --effects`` fitted), with the stamps of its record's first sample.
        """
        self._set_output(model, note, origin_ns, record)

    def _set_output(
        self,
        model: OutputModel | None,
        note: str,
        origin_ns: int = 0,
        record: tuple | None = None,
    ) -> None:
        compensator = self._engine.compensator
        prime = None
        recent = self._engine.recent
        if model is not None and recent is not None and recent.size:
            stamps, tc1, tc2 = recent.newest(compensator.config.gap_factor)
            prime = (stamps[-PRIME_PAIRS:], tc1[-PRIME_PAIRS:], tc2[-PRIME_PAIRS:])
        was = compensator.output_model
        self._publish(compensator.use_output_model(model, origin_ns, record, prime))
        compensator.output_note = note
        if model is not None or was is not None:
            name = model.name(causal_stream=True) if model is not None else "first-order"
            self.get_logger().info(f"published gas now uses {name}: {note}")

    def _accept_output(self, result: dict[str, Any]) -> None:
        """Use a landed background fit for the published gas if it passes, else first order."""
        model = result.get("output_model")
        _, record = self._submitted
        if model is None or record is None:
            return
        error, base = float(result["error_pct"]), float(result["base_error_pct"])
        where = (
            f"fit of {record[0].size} pairs: held-out error {error:.3g} % ({base:.3g} % "
            "first order)"
        )
        if not model.applied(causal_stream=True):
            self._set_output(None, f"no effect to compensate; {where}")
        elif result["at_bound"]:
            self._set_output(
                None, f"parameters on a bound ({', '.join(result['at_bound'])}); {where}"
            )
        elif not error <= (1.0 - MIN_ERROR_FALL) * base:
            fall = f"{100 * MIN_ERROR_FALL:g} %"
            self._set_output(None, f"the effects lower the error by less than {fall}; {where}")
        else:
            self._output_fitted_at = self._submitted_at
            self._set_output(model, where, int(record[0][0]), record)

    def _check_output_age(self) -> None:
        """Back to first order when the output model's fit is stale."""
        period = float(self._values["diagnosis_period_s"])
        if self._engine.compensator.output_model is None or period <= 0.0:
            return
        age = self._now() - self._output_fitted_at
        if age > OUTPUT_STALE_PERIODS * period:
            self._set_output(None, f"stale: the last accepted fit is {age:.3g} s old")

    def _collect_diagnosis(self) -> None:
        """Take a finished job's result, if any."""
        result = self._diagnoser.poll()
        if result is not None and "error" in result:
            self._diagnosis_error = str(result["error"])
            self.get_logger().warning(
                f"diagnosis failed: {self._diagnosis_error}", throttle_duration_sec=60.0
            )
        elif result is not None:
            result["requested"] = self._submitted[0]
            self._diagnosis = result
            self._diagnosis_error = ""
            self._diagnosis_at = self._submitted_at
            if self._compensating:
                self._accept_output(result)
            self.get_logger().info(
                f"diagnosis of {result['samples']} samples in {result['seconds']:.1f} s: "
                f"error {result['base_error_pct']:.3g} % (base), {result['error_pct']:.3g} % "
                f"(effects: {', '.join(result['effects']) or 'none'}); top suspect "
                f"{result['top_suspect']}"
            )

    def _diagnosis_values(self, now: float) -> dict[str, str]:
        """Key-values of the latest diagnosis (NaN or 'none' until one is known)."""
        result = self._diagnosis
        # Held-out error and τ with the effects only from a job that fitted the current ones.
        fitted = result if result.get("requested", ()) == self._effects and result else {}
        return {
            "effects": "auto" if self._effects is None else ",".join(self._effects) or "none",
            "effects_error_pct": _fmt(fitted.get("error_pct", math.nan)),
            "base_error_pct": _fmt(result.get("base_error_pct", math.nan)),
            "effects_tau1_s": _fmt(fitted.get("tau1", math.nan)),
            "effects_tau2_s": _fmt(fitted.get("tau2", math.nan)),
            "top_suspect": str(result.get("top_suspect", "none")),
            "top_suspect_error_pct": _fmt(result.get("top_suspect_error_pct", math.nan)),
            "diagnosis_age_s": _fmt(now - self._diagnosis_at),
            "diagnosis_duration_s": _fmt(result.get("seconds", math.nan)),
            "diagnosis_error": self._diagnosis_error,
        }

    # -- diagnostics -------------------------------------------------------------------------
    def health_status(self, new_period: bool = False) -> DiagnosticStatus:
        """The current diagnostic status (also published once a second).

        Parameters
        ----------
        new_period : bool
            Start a new report period (the diagnostics timer does).
        """
        now = self._now()
        extra = {
            **self._diagnosis_values(now),
            **self._latency.summary(),
            "callback_errors": str(self._callback_errors),
            "last_callback_error": self._last_callback_error,
        }
        health: Health = self._engine.report(now, extra, new_period=new_period)
        message = health.message
        status = self._engine.last_status
        suspect = health.values["top_suspect"]
        if health.level == Level.WARN and status and status.poor_fit and suspect != "none":
            message += f"; top suspect: {suspect}"
        return DiagnosticStatus(
            level=bytes([int(health.level)]),
            name=f"tcomp: {self.get_name()}",
            message=message,
            hardware_id=str(self._values["hardware_id"]),
            values=[KeyValue(key=key, value=value) for key, value in health.values.items()],
        )

    def publish_diagnostics(self) -> None:
        """Publish the status on /diagnostics and start a new report period.

        Also collects a finished diagnosis and starts one that was asked for while the worker
        was busy or the window too short.
        """
        if self._diagnosis_wanted:
            self.start_diagnosis()
        else:
            self._collect_diagnosis()
        self._check_output_age()
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
    rclpy.init(args=None if args is None else list(args))
    try:
        node = CompensatorNode()
    except (ParameterException, ValueError, TypeError) as exc:  # a bad value given at start
        print(f"compensator_node: error: {' '.join(str(exc).split())}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        spin_until_shutdown(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
