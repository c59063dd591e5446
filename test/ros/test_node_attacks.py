"""Attacks on both nodes from outside (issue 13): the node stays alive, its outputs are finite,
its diagnostics say what happened. Real QoS profiles, namespaces, sim time and bad parameters.

Launch-free and in-process (one Context per test) except the replay's command-line cases, which
run ``replay_node`` as a process to see its exit code and stderr.
"""

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from node_harness import level, stamps_for, values
from rcl_interfaces.msg import ParameterType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Temperature
from test_replay import Collector, _node_env

from tcomp_core.simulate import simulate_pair
from tcomp_ros.compensator import CompensatorNode
from tcomp_ros.replay import ReplayNode
from tcomp_ros.spin import make_executor

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


def ramp(duration=3.0, seed=3):
    return simulate_pair("ramp", noise_percent=0.5, duration=duration, seed=seed)


def finite_gas(h):
    return all(math.isfinite(value) for _, value in h.gas)


# -- QoS ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_best_effort_sensor_driver_gets_gas_out(harness):
    # REP 2003 sensor drivers publish best effort (SensorDataQoS): the default must hear them.
    data = ramp()
    h = harness(window_s=1.0, update_period_s=0.1)
    best_effort = [
        h.peer.create_publisher(Temperature, "tc1/temperature", qos_profile_sensor_data),
        h.peer.create_publisher(Temperature, "tc2/temperature", qos_profile_sensor_data),
    ]
    h.pub = best_effort
    h.spin_until(h.executor, lambda: best_effort[0].get_subscription_count() > 0, 30.0)
    stamps = stamps_for(data.tc1.size, data.dt)
    h.feed(stamps, data.tc1, data.tc2, batch=50)
    assert h.spin_until(h.executor, lambda: len(h.gas) > 500, 30.0), len(h.gas)
    assert finite_gas(h)


@pytest.mark.slow
def test_reliable_inputs_on_request_hear_reliable_publishers_only(harness):
    h = harness(input_reliability="reliable")
    best_effort = h.peer.create_publisher(Temperature, "tc1/temperature", qos_profile_sensor_data)
    h.settle(0.5)
    assert best_effort.get_subscription_count() == 0  # incompatible: as ROS says
    assert h.pub[0].get_subscription_count() == 1  # the harness's reliable publisher


@pytest.mark.slow
def test_input_reliability_is_checked(ros_context):
    with pytest.raises(ValueError, match="input_reliability"):
        CompensatorNode(
            context=ros_context,
            parameter_overrides=[Parameter("input_reliability", value="sometimes")],
        )


# -- malformed messages ------------------------------------------------------------------------
def malformed_payloads():
    rng = np.random.default_rng(5)
    huge_frame = bytes((0, 1, 0, 0)) + (100).to_bytes(4, "little") + bytes(4)
    huge_frame += (2**32 - 1).to_bytes(4, "little") + b"probe\x00"
    return [bytes(8), huge_frame, rng.integers(0, 256, 64, dtype=np.uint8).tobytes(), b""]


@pytest.mark.slow
def test_malformed_messages_are_counted_reported_and_skipped(harness):
    data = ramp()
    h = harness(window_s=1.0, update_period_s=0.1)
    stamps = stamps_for(data.tc1.size, data.dt)
    half = data.tc1.size // 2
    h.feed(stamps[:half], data.tc1[:half], data.tc2[:half])
    seen = len(h.diagnostics)
    for payload in malformed_payloads():
        h.pub[0].publish(payload)  # raw bytes, as a broken driver or an attacker sends them
    h.settle(0.5)
    h.feed(stamps[half:], data.tc1[half:], data.tc2[half:])
    # The counter is cumulative; a report may fall between the messages (seen on a loaded
    # machine: a first report with 1 of them), so the one that has seen three is awaited.
    status = h.next_diagnostics(
        lambda s: "malformed" in s.message and int(values(s)["malformed_tc1"]) >= 3, since=seen
    )
    found = values(status)
    assert found["malformed_tc2"] == "0"
    assert level(status) in ("WARN", "ERROR", "STALE")
    assert "tc1:" in status.message and "bytes" in status.message
    # The node kept going after them: every pair sent after them has its gas (pair k's gas is
    # stamped with pair k-1's stamp) ...
    after = set(stamps[half - 1 : -1].tolist())
    assert h.spin_until(h.executor, lambda: after <= {stamp for stamp, _ in h.gas}, 30.0), (
        f"{len(after - {stamp for stamp, _ in h.gas})} of the {len(after)} pairs after the "
        f"malformed messages have no gas; last: {h.last_summary()}"
    )
    assert finite_gas(h)
    # ... and every matched pair but the newest (whose interval its successor closes) is
    # published or counted: a hold that outgrew one window before the first τ was accepted
    # (a slow first estimate) drops its oldest pairs.
    found = values(h.next_diagnostics())
    assert found["held"] == "0"
    published, lost = int(found["published"]), int(found["unreconstructed"])
    assert published + lost + 1 == int(found["matched"]) == data.tc1.size, found
    assert len(h.gas) == published and lost < half, found


# -- physical range ----------------------------------------------------------------------------
@pytest.mark.slow
def test_absurd_values_are_invalid_and_the_output_stays_finite_and_sane(harness):
    data = simulate_pair("ramp", noise_percent=0.5, duration=6.0, seed=4)
    tc1 = data.tc1.copy()
    tc1[700] = 1.7e308
    one_second = round(1.0 / data.dt)
    tc1[1500 : 1500 + one_second] = -273.16  # below absolute zero for a second
    h = harness(window_s=2.0, update_period_s=0.1)
    h.feed(stamps_for(tc1.size, data.dt), tc1, data.tc2)
    status = h.next_diagnostics(lambda s: int(values(s)["invalid_tc1"]) > 0, since=0)
    assert "invalid value" in status.message
    h.settle(1.5)
    found = values(h.diagnostics[-1])
    assert int(found["invalid_tc1"]) == 1 + one_second
    assert finite_gas(h)
    gas = np.array([value for _, value in h.gas])
    assert gas.min() > data.gas.min() - 50 and gas.max() < data.gas.max() + 50
    assert float(found["tau1_s"]) == pytest.approx(data.tau1, rel=0.2)
    assert float(found["tau2_s"]) == pytest.approx(data.tau2, rel=0.2)


# -- stamps ------------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_pair_stamped_far_in_the_future_is_a_discontinuity_not_an_outage(harness):
    data = ramp(duration=6.0)
    h = harness(window_s=1.0, update_period_s=0.1)
    stamps = stamps_for(data.tc1.size, data.dt)
    h.feed(stamps[:1000], data.tc1[:1000], data.tc2[:1000])
    future = (2**31 - 100) * 10**9
    h.send(0, future, data.tc1[1000])
    h.send(1, future, data.tc2[1000])
    h.catch_up()
    before = len(h.gas)
    h.feed(stamps[1001:], data.tc1[1001:], data.tc2[1001:])
    status = h.next_diagnostics(lambda s: int(values(s)["discontinuities"]) == 1, since=0)
    assert "stamps jumped back" in status.message and level(status) != "OK"
    # Output resumes after the jump: nearly every later pair is reconstructed again.
    assert h.spin_until(h.executor, lambda: len(h.gas) - before > data.tc1.size - 1001 - 50, 30)
    assert int(values(h.diagnostics[-1])["out_of_order"]) < 10
    assert finite_gas(h)


@pytest.mark.slow
def test_stamps_one_nanosecond_apart_do_not_exhaust_memory(harness):
    h = harness(window_s=2.0, update_period_s=0.1, max_window_samples=20_000)
    data = ramp()
    stamps = (10**18 + np.arange(data.tc1.size)).astype(np.int64)  # 1 ns apart
    h.feed(stamps, data.tc1, data.tc2)
    h.settle(1.2)
    found = values(h.diagnostics[-1])
    assert int(found["window_samples"]) <= 20_000
    assert int(found["matched"]) == data.tc1.size


@pytest.mark.slow
def test_a_window_beyond_the_memory_budget_is_refused_on_set_and_at_start(ros_context):
    node = CompensatorNode(context=ros_context)
    try:
        result = node.set_parameters([Parameter("sample_period_s", value=1e-9)])[0]
        assert not result.successful and "max_window_samples" in result.reason
        assert node.get_parameter("sample_period_s").value == 0.0  # unchanged
    finally:
        node.destroy_node()
    with pytest.raises(ValueError, match="needs 2e\\+09 samples"):
        CompensatorNode(
            context=ros_context, parameter_overrides=[Parameter("sample_period_s", value=1e-9)]
        )


# -- parameters --------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("node_class", [CompensatorNode, ReplayNode])
def test_every_range_is_well_formed_as_clients_see_it(ros_context, spin_until, node_class):
    # Through the DescribeParameters service, as `ros2 param describe` and rqt read them.
    from rclpy.parameter_client import AsyncParameterClient

    overrides = [Parameter("source", value="simulate")] if node_class is ReplayNode else []
    node = node_class(context=ros_context, parameter_overrides=overrides)
    peer = Node("describer", context=ros_context)
    executor = make_executor(ros_context)
    executor.add_node(node)
    executor.add_node(peer)
    try:
        client = AsyncParameterClient(peer, node.get_fully_qualified_name())
        assert client.wait_for_services(timeout_sec=5.0)
        names = sorted(node._parameters)
        described = client.describe_parameters(names)
        current = client.get_parameters(names)
        assert spin_until(executor, lambda: described.done() and current.done(), 30.0)
        pairs = zip(described.result().descriptors, current.result().values, strict=True)
        for descriptor, value in pairs:
            for bounds in descriptor.floating_point_range:
                assert descriptor.type == ParameterType.PARAMETER_DOUBLE, descriptor.name
                assert abs(bounds.to_value) > 1e-300, (descriptor.name, bounds.to_value)
                assert bounds.from_value < bounds.to_value, descriptor.name
                assert bounds.from_value <= value.double_value <= bounds.to_value, descriptor.name
            for bounds in descriptor.integer_range:
                assert bounds.from_value < bounds.to_value, descriptor.name
                assert bounds.from_value <= value.integer_value <= bounds.to_value
    finally:
        executor.shutdown()
        peer.destroy_node()
        node.destroy_node()


@pytest.mark.slow
def test_the_config_file_applies_under_a_namespace(tmp_path):
    import rclpy
    from rclpy.context import Context

    custom = tmp_path / "custom.yaml"
    custom.write_text(
        textwrap.dedent(
            """\
            /**:
              ros__parameters:
                window_s: 3.5
            """
        )
    )
    for path, expected in ((ROOT / "config" / "compensator.yaml", 2.0), (custom, 3.5)):
        context = Context()
        rclpy.init(
            context=context,
            args=["--ros-args", "-r", "__ns:=/rig1", "--params-file", str(path)],
        )
        try:
            node = CompensatorNode(context=context, parameter_overrides=[])
            assert node.get_namespace() == "/rig1"
            assert node.get_parameter("window_s").value == expected
            assert node.get_parameter("diagnosis_period_s").value == 10.0
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)


@pytest.mark.slow
def test_compensator_under_sim_time_follows_clock(harness):
    h = harness(use_sim_time=True, silence_timeout_s=1.0)
    clock = h.peer.create_publisher(Clock, "/clock", 10)
    h.spin_until(h.executor, lambda: clock.get_subscription_count() > 0, 30.0)
    message = Clock()
    message.clock.sec = 5000
    clock.publish(message)
    assert h.spin_until(
        h.executor, lambda: h.node.get_clock().now().nanoseconds == 5000 * 10**9, 5.0
    )
    # Simulated time stands still: no sensor is silent for longer than the timeout yet.
    data = ramp(duration=1.0)
    h.feed(stamps_for(data.tc1.size, data.dt), data.tc1, data.tc2)
    status = h.node.health_status()
    assert "silent" not in status.message


# -- replay ------------------------------------------------------------------------------------
def test_replay_publishes_its_clock_under_sim_time(ros_context, spin_until):
    collector = Collector(ros_context)
    replay = ReplayNode(
        context=ros_context,
        parameter_overrides=[
            Parameter("use_sim_time", value=True),
            Parameter("publish_clock", value=True),
            Parameter("source", value="simulate"),
            Parameter("duration_s", value=1.0),
            Parameter("sample_rate_hz", value=500.0),
        ],
    )
    executor = make_executor(ros_context)
    executor.add_node(collector.node)
    executor.add_node(replay)
    try:
        assert spin_until(
            executor,
            lambda: len(collector.received["tc1/temperature"]) > 100 and collector.clock,
            10.0,
        )
    finally:
        executor.shutdown()
        replay.destroy_node()
        collector.node.destroy_node()


def replay_command(*ros_args):
    return [sys.executable, "-m", "tcomp_ros.replay", "--ros-args", *ros_args]


@pytest.mark.slow
@pytest.mark.parametrize(
    "argument", ["signal:=bogus", "rate:=abc", "rate:=0.0", "rate:=5", "noise_percent:=-1.0"]
)
def test_replay_bad_parameter_is_one_line_and_exit_1(argument):
    completed = subprocess.run(
        [
            sys.executable,
            "-m",
            "tcomp_ros.replay",
            "--ros-args",
            "-p",
            "source:=simulate",
            "-p",
            argument,
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env=_node_env(),
        check=False,
    )
    assert completed.returncode == 1, completed.stderr
    assert "Traceback" not in completed.stderr + completed.stdout
    errors = [line for line in completed.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and argument.split(":=")[0] in errors[0], completed.stderr
