"""The nodes' spin loop and shutdown (tcomp_ros.spin)."""

import pytest
from rclpy._rclpy_pybind11 import RCLError

from tcomp_ros import spin


def test_a_signal_shutting_the_context_down_first_is_no_error(ros_context, monkeypatch):
    """rclpy's signal handler can shut the context down between try_shutdown's check and its
    own shutdown (ros2/rclpy#1352): a node stopped by Ctrl-C then exited with status 1."""

    def racing(*, context=None):
        context.shutdown()  # the signal handler's thread, first
        raise RCLError("failed to shutdown: rcl_shutdown already called on the given context")

    monkeypatch.setattr(spin.rclpy, "try_shutdown", racing)
    spin.shut_down(ros_context)
    assert not ros_context.ok()


def test_a_shutdown_that_fails_on_a_live_context_is_raised(ros_context, monkeypatch):
    def failing(*, context=None):
        raise RCLError("failed to shutdown: something else")

    monkeypatch.setattr(spin.rclpy, "try_shutdown", failing)
    with pytest.raises(RCLError, match="something else"):
        spin.shut_down(ros_context)
    assert ros_context.ok()
