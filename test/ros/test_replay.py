"""Replay node: in-process publishing tests and subprocess error / signal tests."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import next_domain_id
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Temperature

from tcomp_core.errors import DataError
from tcomp_core.io import write_bag
from tcomp_ros.replay import LOOP_GAP_STEPS, ReplayNode
from tcomp_ros.spin import make_executor

TOPICS = ("tc1/temperature", "tc2/temperature", "tref/temperature")
START_NS = 1_650_000_000_123_456_789


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory):
    rng = np.random.default_rng(17)
    count = 2000
    time_s = np.arange(count) * 0.001
    series = {
        "/tc1/temperature": 300.0 + rng.standard_normal(count),
        "/tc2/temperature": 310.0 + rng.standard_normal(count),
        "/tref/temperature": 320.0 + rng.standard_normal(count),
    }
    path = tmp_path_factory.mktemp("bags") / "small"
    write_bag(path, time_s, series, start_ns=START_NS)
    stamps = START_NS + np.rint(time_s * 1e9).astype(np.int64)
    return path, stamps, series


class Collector:
    def __init__(self, context, topics=TOPICS):
        self.node = Node("collector", context=context)
        self.received = {topic: [] for topic in topics}
        self.clock = []
        for topic in topics:
            self.node.create_subscription(
                Temperature,
                topic,
                lambda message, topic=topic: self.received[topic].append(
                    (
                        message.header.stamp.sec * 10**9 + message.header.stamp.nanosec,
                        message.temperature,
                    )
                ),
                10000,
            )
        self.node.create_subscription(
            Clock,
            "/clock",
            lambda m: self.clock.append(m.clock.sec * 10**9 + m.clock.nanosec),
            100,
        )


def run(context, spin_until, parameters, predicate, timeout=20.0):
    collector = Collector(context)
    replay = ReplayNode(
        context=context,
        parameter_overrides=[Parameter(name, value=value) for name, value in parameters.items()],
    )
    executor = make_executor(context)
    executor.add_node(collector.node)
    executor.add_node(replay)
    try:
        assert spin_until(executor, lambda: predicate(replay, collector), timeout)
        spin_until(executor, lambda: False, 0.3)  # let the last messages arrive
    finally:
        executor.shutdown()
        replay.destroy_node()
        collector.node.destroy_node()
    return replay, collector


@pytest.mark.slow
def test_bag_replayed_in_full_and_in_order(ros_context, spin_until, small_bag):
    path, stamps, series = small_bag
    replay, collector = run(
        ros_context,
        spin_until,
        {"bag": str(path), "rate": 1.0},
        lambda replay, c: replay.done and len(c.received[TOPICS[-1]]) >= stamps.size,
    )
    assert replay.published == stamps.size
    for topic, bag_topic in zip(TOPICS, series, strict=True):
        got = collector.received[topic]
        assert len(got) == stamps.size, topic
        got_stamps = np.array([stamp for stamp, _ in got])
        np.testing.assert_array_equal(got_stamps, stamps)
        np.testing.assert_array_equal([value for _, value in got], series[bag_topic])


@pytest.mark.slow
def test_replay_paces_at_the_requested_rate(ros_context, spin_until, small_bag):
    path, stamps, _ = small_bag
    started = time.monotonic()
    run(ros_context, spin_until, {"bag": str(path), "rate": 2.0}, lambda r, _: r.done)
    elapsed = time.monotonic() - started
    bag_seconds = (stamps[-1] - stamps[0]) * 1e-9
    assert bag_seconds / 2.0 * 0.8 < elapsed < bag_seconds / 2.0 + 3.0


@pytest.mark.slow
def test_loop_replays_with_increasing_stamps(ros_context, spin_until, small_bag):
    path, stamps, _ = small_bag
    _, collector = run(
        ros_context,
        spin_until,
        {"bag": str(path), "rate": 2.0, "loop": True},
        lambda _, c: len(c.received["tc1/temperature"]) > stamps.size + 200,
    )
    got = np.array([stamp for stamp, _ in collector.received["tc1/temperature"]])
    assert np.all(np.diff(got) > 0)
    np.testing.assert_array_equal(got[: stamps.size], stamps)
    # The next pass leaves a gap of LOOP_GAP_STEPS samples, then continues at the bag's step.
    assert got[stamps.size] == stamps[-1] + (1 + LOOP_GAP_STEPS) * 1_000_000


@pytest.mark.slow
def test_wait_for_subscribers_holds_the_start_until_every_topic_is_matched(
    ros_context, spin_until, small_bag
):
    path, stamps, _ = small_bag
    replay = ReplayNode(
        context=ros_context,
        parameter_overrides=[
            Parameter("bag", value=str(path)),
            Parameter("rate", value=4.0),
            Parameter("wait_for_subscribers", value=1),
        ],
    )
    executor = make_executor(ros_context)
    executor.add_node(replay)
    collectors = []
    try:
        spin_until(executor, lambda: False, 1.0)  # > the whole bag at 4x: nobody listens yet
        assert replay.published == 0
        collectors.append(Collector(ros_context, topics=TOPICS[:1]))  # tc2 still unmatched
        executor.add_node(collectors[-1].node)
        spin_until(executor, lambda: False, 1.0)
        assert replay.published == 0
        collectors.append(Collector(ros_context, topics=TOPICS[:2]))  # tref is not waited for
        executor.add_node(collectors[-1].node)
        assert spin_until(executor, lambda: replay.done, 10.0)
        spin_until(executor, lambda: False, 0.3)
    finally:
        executor.shutdown()
        replay.destroy_node()
        for collector in collectors:
            collector.node.destroy_node()
    for topic in TOPICS[:2]:
        got = np.array([stamp for stamp, _ in collectors[-1].received[topic]])
        np.testing.assert_array_equal(got, stamps)


@pytest.mark.slow
def test_publish_clock(ros_context, spin_until, small_bag):
    path, stamps, _ = small_bag
    _, collector = run(
        ros_context,
        spin_until,
        {"bag": str(path), "rate": 2.0, "publish_clock": True},
        lambda r, c: r.done and c.clock and c.clock[-1] == stamps[-1],
    )
    assert collector.clock[0] >= stamps[0]
    assert collector.clock[-1] == stamps[-1]
    assert np.all(np.diff(collector.clock) >= 0)


@pytest.mark.slow
def test_simulate_source_publishes_at_the_sample_rate(ros_context, spin_until):
    started = time.monotonic()
    replay, collector = run(
        ros_context,
        spin_until,
        {"source": "simulate", "sample_rate_hz": 1000.0, "duration_s": 1.0, "signal": "ramp"},
        lambda r, _: r.done,
    )
    elapsed = time.monotonic() - started
    assert replay.published == 1000
    for topic in TOPICS:
        assert len(collector.received[topic]) == 1000
    steps = np.diff([stamp for stamp, _ in collector.received["tc1/temperature"]])
    np.testing.assert_array_equal(steps, 1_000_000)
    assert 0.8 < elapsed < 4.0


def test_missing_bag_raises_data_error(ros_context, tmp_path):
    with pytest.raises(DataError, match="nowhere"):
        ReplayNode(
            context=ros_context,
            parameter_overrides=[Parameter("bag", value=str(tmp_path / "nowhere"))],
        )


def _node_env():
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(next_domain_id())
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def _run_replay(*ros_args, timeout=30):
    return subprocess.run(
        [sys.executable, "-m", "tcomp_ros.replay", "--ros-args", *ros_args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=_node_env(),
        check=False,
    )


@pytest.mark.slow
def test_missing_bag_exits_with_clear_error(tmp_path):
    missing = tmp_path / "no_such_bag"
    completed = _run_replay("-p", f"bag:={missing}")
    assert completed.returncode == 1
    output = completed.stdout + completed.stderr
    assert "no_such_bag" in output and "no such bag" in output
    assert "Traceback" not in output


@pytest.mark.slow
def test_truncated_bag_replays_up_to_its_last_complete_record_with_a_warning(tmp_path, small_bag):
    path, _, _ = small_bag
    broken = tmp_path / "broken"
    broken.mkdir()
    for item in path.iterdir():
        data = item.read_bytes()
        if item.suffix == ".mcap":
            data = data[: len(data) // 2]
        (broken / item.name).write_bytes(data)
    completed = _run_replay("-p", f"bag:={broken}")
    assert completed.returncode == 0  # as every verb and tcomp process read it
    output = completed.stdout + completed.stderr
    assert "[WARN]" in output and f"{broken}/small.mcap: input truncated:" in output
    assert "replay finished" in output
    assert "Traceback" not in output


@pytest.mark.slow
def test_bag_without_the_topics_exits_with_clear_error(tmp_path):
    path = tmp_path / "other"
    write_bag(path, np.arange(100) * 0.01, {"/other/temperature": np.ones(100)})
    completed = _run_replay("-p", f"bag:={path}")
    assert completed.returncode == 1
    output = completed.stdout + completed.stderr
    assert "no topic /tc1/temperature" in output and "/other/temperature" in output
    assert "Traceback" not in output


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_running_replay_stops_on_signal(small_bag, signum):
    path, _, _ = small_bag
    command = [sys.executable, "-m", "tcomp_ros.replay", "--ros-args", "-p", f"bag:={path}"]
    process = subprocess.Popen(
        [*command, "-p", "loop:=true"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_node_env(),
    )
    try:
        started = process.stderr.readline()  # the node logs "replaying ..." once it runs
        assert "replaying" in started, started
        time.sleep(0.5)
        assert process.poll() is None
        process.send_signal(signum)
        _, stderr = process.communicate(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, stderr
    assert "Traceback" not in stderr
