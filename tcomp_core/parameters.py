"""Every parameter of the compensator, declared once: name, type, default, range, description.

The compensator node declares its ROS parameters from :data:`PARAMETERS` (with descriptors and
ranges), :class:`~tcomp_core.online.OnlineConfig` takes its defaults and checks from it,
``tcomp process`` its option defaults, and the shipped ``config/compensator.yaml`` is written
from it (``python -m tcomp_core.parameters > config/compensator.yaml``; a test parses the file
with rclpy's own reader and fails when it lacks a parameter or disagrees on a value).

Like :mod:`tcomp_core.choices` this module imports nothing but the standard library, so the
command line builds its parser from it without loading numpy.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Literal

from .choices import (
    DEFAULT_METHOD,
    EFFECT_NAMES,
    METHODS,
    RECONSTRUCT_FROM,
    RECONSTRUCTIONS,
    SIGNAL_MODELS,
)

__all__ = [
    "INPUT_RELIABILITIES",
    "MIN_DIAGNOSIS_PERIOD_S",
    "PARAMETERS",
    "ParameterSpec",
    "Value",
    "default",
    "spec",
    "yaml_text",
]

#: A parameter's value: ROS parameters of these four types only.
Value = bool | int | float | str
#: ``input_reliability``: best effort receives from best-effort and reliable publishers alike.
INPUT_RELIABILITIES = ("best_effort", "reliable")
#: Shortest period of the background diagnosis, seconds (a job takes seconds anyway).
MIN_DIAGNOSIS_PERIOD_S = 1.0


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of the compensator.

    Attributes
    ----------
    name : str
    default : bool, int, float or str
        Its type is the parameter's type.
    description : str
        What it does, with its unit.
    low, high : float or None
        Inclusive range of a number.
    choices : tuple of str
        The values a string may take (empty: any string).
    read_only : bool
        Read at start only (the node refuses a change).
    scope : {'engine', 'node'}
        ``engine``: a field of :class:`~tcomp_core.online.OnlineConfig` (the node and
        ``tcomp process`` alike); ``node``: the ROS adapter's alone (QoS, frame, hardware id).
    comment : str
        The short note beside it in the YAML file.
    """

    name: str
    default: Value
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False
    scope: Literal["engine", "node"] = "engine"
    comment: str = ""

    @property
    def kind(self) -> type:
        """bool, int, float or str."""
        return type(self.default)

    def check(self, value: object) -> None:
        """Raise ValueError naming the parameter when ``value`` is of the wrong type or range."""
        kind = self.kind
        allowed = (int, float) if kind is float else (kind,)
        if (isinstance(value, bool) and kind is not bool) or not isinstance(value, allowed):
            raise ValueError(f"{self.name}={value!r} must be a {kind.__name__}")
        if kind in (int, float):
            number = float(value)  # type: ignore[arg-type]
            if not math.isfinite(number):
                raise ValueError(f"{self.name}={value!r} must be finite")
            if self.low is not None and number < self.low:
                raise ValueError(f"{self.name}={value!r} must be >= {self.low:g}")
            if self.high is not None and number > self.high:
                raise ValueError(f"{self.name}={value!r} must be <= {self.high:g}")
        if self.choices and value not in self.choices:
            raise ValueError(f"{self.name}={value!r} is not one of {', '.join(self.choices)}")


PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec(
        "window_s",
        2.0,
        "estimation window length, s",
        0.05,
        3600.0,
        comment="estimation window, s",
    ),
    ParameterSpec(
        "update_period_s",
        0.5,
        "period of re-estimation, s",
        0.01,
        60.0,
        comment="re-estimation period, s",
    ),
    ParameterSpec(
        "method",
        DEFAULT_METHOD,
        "estimator of tau1, tau2: ml-eiv (maximum likelihood, 95 % intervals, unbiased at every "
        "sample rate without a pre-filter) or one of the paper's six",
        choices=METHODS,
        comment="ml-eiv (maximum likelihood, with 95 % intervals) | tdr-kee | gamma-ls "
        "| gamma-tls | beta-ls | beta-tls | beta-gtls",
    ),
    ParameterSpec(
        "phi",
        0.0,
        "noise variance ratio sigma1^2/sigma2^2 of ml-eiv, beta-gtls and the fused Eq. (7); "
        "0 = measured from each window (the model's residual, as tcomp estimate --phi auto)",
        0.0,
        1e6,
        comment="noise variance ratio sigma1^2 / sigma2^2 (0 = measured from each window)",
    ),
    ParameterSpec(
        "prefilter_hz",
        0.0,
        "zero-phase pre-filter on the window before estimation, Hz (0 = off)",
        0.0,
        1e6,
        comment="zero-phase pre-filter of the window, Hz (0 = off; ml-eiv needs none)",
    ),
    ParameterSpec(
        "postfilter_hz",
        0.0,
        "causal Butterworth low-pass on gas_temperature, Hz (0 = off)",
        0.0,
        1e6,
        comment="causal low-pass on gas_temperature, Hz (0 = off)",
    ),
    ParameterSpec(
        "sync_slop_s",
        0.0,
        "largest stamp difference of a tc1/tc2 pair, s (0 = exact stamps)",
        0.0,
        1.0,
        comment="pair tc1/tc2 samples within this stamp difference, s (0 = exact)",
    ),
    ParameterSpec(
        "reconstruction",
        "kalman",
        "'kalman': the causal Kalman filter of both sensors, its signal model fitted to the "
        "data off the stream (the published variance is its own); 'difference': the paper's "
        "Eq. (7) per sensor, combined by reconstruct_from",
        choices=RECONSTRUCTIONS,
        comment="kalman (causal filter of both sensors: the best streaming gas) "
        "| difference (the paper's Eq. 7)",
    ),
    ParameterSpec(
        "signal_model",
        "auto",
        "gas temperature model of the Kalman filter, fitted by maximum likelihood in a worker "
        "process; 'auto' fits all and keeps the likeliest; a model that cannot be fitted gives "
        "way to one that can",
        choices=SIGNAL_MODELS,
        comment="kalman's gas model: auto | random-walk | integrated-random-walk "
        "| band-limited | periodic | autoregressive",
    ),
    ParameterSpec(
        "reconstruct_from",
        "fused",
        "which Eq. (7) reconstruction is published (reconstruction: difference)",
        choices=RECONSTRUCT_FROM,
        comment="fused | tc1 | tc2 (reconstruction: difference)",
    ),
    ParameterSpec(
        "tracking_memory_s",
        0.0,
        "forgetting time of a tau that changes with the flow, s: tau from an exponentially "
        "forgetting beta-GTLS with tau1/tau2 held to its long-term value (0 = the window)",
        0.0,
        3600.0,
        comment="> 0: track a tau that changes with the flow, ratio held, s",
    ),
    ParameterSpec(
        "hardware_id",
        "thermocouple-pair",
        "hardware_id of the diagnostic status",
        scope="node",
        comment="hardware_id of the diagnostic status",
    ),
    ParameterSpec(
        "sample_period_s",
        0.0,
        "sample period of the pairs, s (0 = learn from the stamps)",
        0.0,
        10.0,
        comment="0 = learn from the stamps, s",
    ),
    ParameterSpec(
        "silence_timeout_s",
        1.0,
        "a sensor silent this long is an ERROR, s",
        0.01,
        3600.0,
        comment="a sensor silent this long is an ERROR, s",
    ),
    ParameterSpec(
        "max_condition",
        1e3,
        "estimates with a larger condition figure are refused",
        1.0,
        1e12,
        comment="refuse estimates with a larger condition figure",
    ),
    ParameterSpec(
        "max_model_error_pct",
        10.0,
        "model error above which the fit is poor (WARN), percent",
        0.01,
        1000.0,
        comment="WARN above this model error, %",
    ),
    ParameterSpec(
        "queue_size",
        2000,
        "unmatched samples kept per input",
        1,
        10**6,
        comment="unmatched samples kept per input",
    ),
    ParameterSpec(
        "frame_id",
        "",
        "frame_id of gas_temperature ('' = that of tc1)",
        scope="node",
        comment="'' = frame_id of tc1",
    ),
    ParameterSpec(
        "input_reliability",
        "best_effort",
        "reliability of the tc1/tc2 subscriptions: best_effort receives from best-effort and "
        "reliable publishers alike, reliable from reliable ones only (read at start)",
        choices=INPUT_RELIABILITIES,
        read_only=True,
        scope="node",
        comment="best_effort (hears sensor drivers and reliable publishers) | reliable",
    ),
    ParameterSpec(
        "min_temperature_c",
        -273.15,
        "readings below are invalid (counted, reported, left out), degrees C",
        -273.15,
        1e6,
        comment="readings below are invalid (counted, left out), degrees C",
    ),
    ParameterSpec(
        "max_temperature_c",
        2000.0,
        "readings above are invalid (counted, reported, left out), degrees C",
        -273.15,
        1e6,
        comment="readings above are invalid (counted, left out), degrees C",
    ),
    ParameterSpec(
        "max_window_samples",
        500_000,
        "memory budget of the window in sample pairs (48 bytes each): a window_s that needs "
        "more at sample_period_s is refused, a learnt period clips the window",
        100,
        10**8,
        comment="memory budget of the window, sample pairs (48 bytes each)",
    ),
    ParameterSpec(
        "discontinuity_s",
        10.0,
        "stamps this far behind the last matched one, several in a row, restart the window (a "
        "clock reset or a bag starting over), s",
        0.001,
        1e9,
        comment="stamps this far behind, several in a row, restart the window, s",
    ),
    ParameterSpec(
        "effects",
        "none",
        "effects the background diagnosis adds to the first-order model, comma-separated "
        "('none' = the first-order model alone), 'auto' (the diagnosis's final model), or a "
        "diagnosis saved by 'tcomp diagnose --json' (FILE.json: the effects its final model "
        "found, read when the parameter is set); they change the diagnosis and the error it "
        "reports, and with compensate_effects the published gas",
        comment="none | auto (the diagnosis's final model) | FILE.json (a saved diagnosis's) | "
        "comma-separated: " + ", ".join(EFFECT_NAMES),
    ),
    ParameterSpec(
        "compensate_effects",
        False,
        "publish gas_temperature compensated with the background fit of effects once it lands, "
        "lowers the held-out error by 20 % with no parameter on a bound, and while it is fresh "
        "(3 diagnosis periods); first order otherwise (see output_model in /diagnostics)",
        comment="true: publish the gas compensated with the fit of effects while it passes",
    ),
    ParameterSpec(
        "diagnosis_period_s",
        10.0,
        "period of the background diagnosis of the window while the fit is poor or effects is "
        f"set, s (0 = only when effects changes, else >= {MIN_DIAGNOSIS_PERIOD_S:g}); one job "
        "at a time, each taking seconds in a worker process",
        0.0,
        3600.0,
        comment=f"background diagnosis period, s (0 = only when effects changes, "
        f"else >= {MIN_DIAGNOSIS_PERIOD_S:g})",
    ),
)

_BY_NAME = {parameter.name: parameter for parameter in PARAMETERS}


def spec(name: str) -> ParameterSpec:
    """The declaration of parameter ``name`` (KeyError for an unknown one)."""
    return _BY_NAME[name]


def default(name: str) -> Value:
    """The default of parameter ``name``."""
    return _BY_NAME[name].default


def _yaml_value(value: Value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"' if value in ("", "none", "true", "false") else value
    return repr(value)


def yaml_text() -> str:
    """The shipped ``config/compensator.yaml``: every parameter at its default, with its note."""
    lines = [
        "# Parameters of the compensator node, every one at its default (written by",
        "#   python -m tcomp_core.parameters > config/compensator.yaml",
        "# from tcomp_core/parameters.py, where each is declared once; a test checks the two",
        "# agree). Run with:",
        "#   ros2 run tcomp_ros compensator_node --ros-args --params-file config/compensator.yaml",
        "# Keyed /** (any namespace, any node name): the file applies to a compensator started",
        "# under a namespace (-r __ns:=/rig1) or renamed (-r __node:=probe_a) too. To give one",
        "# node of a launch its own values, key them by its full name, e.g. /rig1/compensator:",
        "/**:",
        "  ros__parameters:",
    ]
    width = max(len(f"{p.name}: {_yaml_value(p.default)}") for p in PARAMETERS)
    for parameter in PARAMETERS:
        entry = f"{parameter.name}: {_yaml_value(parameter.default)}"
        lines.append(f"    {entry:<{width}}  # {parameter.comment}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(yaml_text())
