"""Replay and compensator as separate processes talking over DDS; clean stop on signals."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node

from tcomp_core.online.engine import DISCONTINUITY_SAMPLES
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2
from tcomp_ros.spin import LONG_RUN_SLICE_S

pytestmark = pytest.mark.slow

BAGS = Path(__file__).resolve().parents[2] / "bags"


def _start(module, domain_id, *ros_args):
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return subprocess.Popen(
        [sys.executable, "-m", module, "--ros-args", *ros_args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def _stop(process, signum=signal.SIGINT, timeout=10.0):
    if process.poll() is None:
        process.send_signal(signum)
    try:
        _, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        _, stderr = process.communicate()
        pytest.fail(f"{process.args[2]} ignored signal {signum}: {stderr[-2000:]}")
    return process.returncode, stderr


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_replay_process_feeds_compensator_process(ros_context, ros_domain_id, spin_until, signum):
    # Reliable inputs: the replay publishes reliably, and "no pair dropped" below holds only
    # with delivery that retransmits (best effort, the default, may lose one under load).
    compensator = _start(
        "tcomp_ros.compensator",
        ros_domain_id,
        *("-p", "window_s:=4.0", "-p", "update_period_s:=0.25"),
        *("-p", "input_reliability:=reliable"),
    )
    replay = _start(
        "tcomp_ros.replay",
        ros_domain_id,
        *("-p", f"bag:={BAGS / 'ramp_500hz'}", "-p", "rate:=2.0", "-p", "loop:=true"),
        *("-p", "wait_for_subscribers:=1"),
    )
    statuses = []
    node = Node("watcher", context=ros_context)
    node.create_subscription(
        DiagnosticArray, "/diagnostics", lambda m: statuses.extend(m.status), 10
    )
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)

    def is_converged(status):
        values = {item.key: item.value for item in status.values}
        return status.level == b"\x00" and int(values["matched"]) >= 2500

    def converged():
        return any(is_converged(status) for status in statuses)

    try:
        assert spin_until(executor, converged, 40.0), [s.message for s in statuses[-3:]]
    finally:
        executor.shutdown()
        node.destroy_node()
        replay_code, replay_err = _stop(replay, signum)
        compensator_code, compensator_err = _stop(compensator, signum)
    status = next(s for s in statuses if is_converged(s))
    values = {item.key: item.value for item in status.values}
    assert status.name == "tcomp: compensator"
    assert float(values["tau1_s"]) == pytest.approx(PAPER_TAU1, rel=0.03)
    assert float(values["tau2_s"]) == pytest.approx(PAPER_TAU2, rel=0.03)
    # Nothing lost in the stream: when the looping replay starts the bag over before this
    # report, the stamps jump back and the samples that show it (DISCONTINUITY_SAMPLES per
    # restart) are dropped, nothing else. (Without wait_for_subscribers DDS discovers the two
    # topics independently and up to 5 leading tc1 messages went unpaired.)
    restarts = int(values["discontinuities"])
    assert int(values["dropped"]) == restarts * DISCONTINUITY_SAMPLES
    assert (replay_code, compensator_code) == (0, 0), (replay_err[-2000:], compensator_err[-2000:])
    assert "Traceback" not in replay_err + compensator_err


@pytest.mark.parametrize(
    ("argument", "complaint"),
    [
        ("diagnosis_period_s:=0", "expecting type 'DOUBLE'"),
        ("effects:=smoke", "unknown effect 'smoke'"),
        ("method:=nope", "method='nope'"),
    ],
)
def test_a_bad_parameter_at_start_is_one_clear_line(ros_domain_id, argument, complaint):
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(ros_domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    completed = subprocess.run(
        [sys.executable, "-m", "tcomp_ros.compensator", "--ros-args", "-p", argument],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
        check=False,
    )
    assert completed.returncode == 1
    assert complaint in completed.stderr
    assert "Traceback" not in completed.stderr


#: The compensator's entry point with the spin loop replaced by one that notes its options.
_SLICE_CHECK = """
import sys
import tcomp_ros.compensator as compensator
seen = {}
compensator.spin_until_shutdown = lambda node, **options: seen.update(options)
assert compensator.main(sys.argv[1:]) == 0
print(seen.get("timeout_sec"))
"""


def test_the_compensator_process_spins_in_long_slices(ros_domain_id):
    # Each slice of the EventsExecutor keeps native memory (tcomp_ros.spin: 2.34 MiB an hour in
    # 50 ms slices): the node, which runs for weeks, spins in slices of a second or more.
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain_id)}
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    done = subprocess.run(
        [sys.executable, "-c", _SLICE_CHECK, "--ros-args", "-p", "diagnosis_period_s:=0.0"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=True,
    )
    assert float(done.stdout.split()[-1]) == LONG_RUN_SLICE_S >= 1.0, done.stdout
