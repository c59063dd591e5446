"""Fixtures for launch-free, in-process rclpy tests (design.md, convention 8).

Every test gets its own ``rclpy.context.Context`` on a domain id of its own, discovery limited to
localhost, and a clean shutdown; ``spin_until`` spins an executor until a predicate holds or a
deadline passes.
"""

import itertools
import os
import time

import node_harness
import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

_domains = itertools.count()
#: Domain ids the tests use, 1..DOMAINS, split evenly among pytest-xdist's workers.
DOMAINS = 200


def next_domain_id() -> int:
    """A domain id (1..200) of this test process's own, not shared with a parallel worker.

    Under pytest-xdist each worker (``PYTEST_XDIST_WORKER`` gw0, gw1, ... of
    ``PYTEST_XDIST_WORKER_COUNT``) takes its own block of ids in turn, so two tests running at
    once never meet on one domain; a run without workers takes them all, starting where its
    process id points (another run on the machine most likely elsewhere).
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if worker.startswith("gw") and count > 1:
        block = DOMAINS // count
        return 1 + int(worker[2:]) % count * block + next(_domains) % block
    return 1 + (os.getpid() * 13 + next(_domains)) % DOMAINS


def spin_until_condition(executor, predicate, timeout_s: float) -> bool:
    """Spin ``executor`` until ``predicate()`` is true or ``timeout_s`` passes; return the last."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=0.01)
    return bool(predicate())


@pytest.fixture
def ros_domain_id():
    return next_domain_id()


@pytest.fixture
def ros_context(ros_domain_id):
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture
def spin_until():
    return spin_until_condition


@pytest.fixture
def harness(ros_context, spin_until):
    from rclpy.executors import SingleThreadedExecutor

    made = []

    def make(**parameters):
        made.append(
            node_harness.Harness(
                ros_context,
                lambda context: SingleThreadedExecutor(context=context),
                spin_until,
                **parameters,
            )
        )
        return made[-1]

    yield make
    for item in made:
        item.executor.shutdown()
        item.node.destroy_node()
        item.peer.destroy_node()
