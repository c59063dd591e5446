"""``make demo`` (ROS part): replay a bundled bag into the compensator and print its estimates.

Both nodes run in this process on one executor, talking over DDS on localhost as they would in
separate processes. Every diagnostics message of the compensator is printed as one line: level,
τ1, τ2, fit, the model the published gas uses and the message. When the bag carries the true
gas temperature (``tref/temperature``), the published gas is compared with it at the end, for
each model it was published with (with ``compensate_effects:=true``: first order until the
background fit lands, then the extended model).
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
from pathlib import Path

from tcomp_core.bundled import bundled_bag
from tcomp_core.parameters import PARAMETERS

__all__ = ["main"]

LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def main(argv: list[str] | None = None) -> int:
    """Replay ``--bag`` at ``--rate`` into a compensator; print its diagnostics."""
    parser = argparse.ArgumentParser(
        description=__doc__,
        epilog="Compensator parameters follow as ROS arguments, the current way: "
        "--ros-args --params-file config/compensator.yaml -p update_period_s:=0.25",
    )
    parser.add_argument("--bag", type=Path, default=bundled_bag("rig_sine_5khz"))
    parser.add_argument("--rate", type=float, default=1.0, help="replay speed factor")
    argv = sys.argv[1:] if argv is None else list(argv)
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    args = parser.parse_args(argv[:split])
    ros_args = ["tcomp_demo", *argv[split:]]
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Temperature

    from tcomp_core.io import read_bag

    from .compensator import CompensatorNode
    from .replay import ReplayNode
    from .spin import make_executor, shut_down

    record = read_bag(args.bag)
    context = rclpy.context.Context()
    rclpy.init(
        args=ros_args, context=context, domain_id=int(os.environ.get("ROS_DOMAIN_ID", "42"))
    )
    compensator = CompensatorNode(context=context)
    parameters = {spec.name: compensator.get_parameter(spec.name).value for spec in PARAMETERS}
    print(
        "compensator: reconstruction {reconstruction} (signal model {signal_model}), method "
        "{method}, window {window_s:g} s, update every {update_period_s:g} s".format(**parameters)
    )
    replay = ReplayNode(
        context=context,
        use_global_arguments=False,  # the compensator's parameters are not the replay's
        parameter_overrides=[
            Parameter("bag", value=str(args.bag)),
            Parameter("rate", value=float(args.rate)),
        ],
    )
    last: dict[str, str] = {}
    gas: dict[int, float] = {}
    truth: dict[int, float] = {}

    def building(values: dict[str, str]) -> str:
        pending = values.get("output_model_pending", "")
        return f" (building {pending})" if pending else ""

    def show(array: DiagnosticArray) -> None:
        status = array.status[0]
        values = {item.key: item.value for item in status.values}
        last.update(values)
        last["level"] = LEVELS[status.level[0]]
        print(
            f"[{LEVELS[status.level[0]]:>5}] tau1 = {values['tau1_s']:>9} s  "
            f"tau2 = {values['tau2_s']:>9} s  matched {values['matched']:>6}  "
            f"fit {values['fit_error_pct']:>7} %  gas: {values['output_model']}"
            f"{building(values)}  "
            f"{status.message}",
            flush=True,
        )

    def keep(into: dict[int, float], message: Temperature) -> None:
        stamp = message.header.stamp
        into[stamp.sec * 1_000_000_000 + stamp.nanosec] = message.temperature

    compensator.create_subscription(DiagnosticArray, "/diagnostics", show, 10)
    compensator.create_subscription(Temperature, "gas_temperature", lambda m: keep(gas, m), 10000)
    compensator.create_subscription(
        Temperature, "tref/temperature", lambda m: keep(truth, m), 10000
    )
    executor = make_executor(context)
    executor.add_node(compensator)
    executor.add_node(replay)
    print(
        f"replaying {args.bag} ({record.tc1.size} samples at {1 / record.dt:.0f} Hz, "
        f"{record.tc1.size * record.dt:.1f} s) into the compensator at {args.rate:g}x real time"
    )
    try:
        while context.ok() and not replay.done:
            executor.spin_once(timeout_sec=0.05)
        # Let the compensator drain what is still in flight, then report once more.
        settled, seen = time.monotonic(), -1
        while context.ok() and time.monotonic() - settled < 0.5:
            executor.spin_once(timeout_sec=0.05)
            matched = compensator.matched_pairs
            if matched != seen:
                settled, seen = time.monotonic(), matched
        compensator.update_estimate()
        compensator.publish_diagnostics()
        for _ in range(20):
            executor.spin_once(timeout_sec=0.05)
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        compensator.destroy_node()
        replay.destroy_node()
        shut_down(context)
    if last:
        print(
            f"final: tau1 = {last['tau1_s']} s, tau2 = {last['tau2_s']} s, "
            f"matched {last['matched']} pairs, published {last['published']} gas samples "
            f"({len(gas)} received here)"
        )
        since = last.get("output_model_since", "")
        _compare(gas, truth, int(since) if since else None, last.get("output_model", ""))
    return 0


def _compare(
    gas: dict[int, float], truth: dict[int, float], since: int | None, model: str
) -> None:
    """Print the published gas's error against the reference, before and after a switch."""
    import numpy as np

    # Element k is the gas held over [t_k, t_k+1): compare it with the mean of ref at both ends
    # (the reference's own next sample, whether or not its gas message was received).
    following = dict(itertools.pairwise(sorted(truth)))
    stamps = sorted(stamp for stamp in gas if stamp in following)
    if len(stamps) < 100:
        return
    pairs = [(s, gas[s], 0.5 * (truth[s] + truth[following[s]])) for s in stamps]
    parts = {"first order": [p for p in pairs if since is None or p[0] < since]}
    if since is not None:
        parts[model] = [p for p in pairs if p[0] >= since]
    spread = float(np.std([ref for _, _, ref in pairs]))
    for name, part in parts.items():
        if len(part) < 50:
            continue
        errors = np.array([value - ref for _, value, ref in part])
        print(
            f"published gas, {name}: {len(part)} samples, rms error against the reference "
            f"{100 * np.sqrt(np.mean(errors**2)) / spread:.3g} % of its spread, mean "
            f"{np.mean(errors):+.3g} degC"
        )


if __name__ == "__main__":
    sys.exit(main())
