"""Executor choice and the spin loop shared by the nodes.

rclpy 7.1.6 ships ``rclpy.experimental.EventsExecutor``, which keeps up with 10 k messages/s
where the SingleThreadedExecutor saturates near 2–3 k/s on a 2-core machine. It is experimental:
``spin()`` in a background thread was seen to busy-loop and ignore SIGTERM, while a
``spin_once`` loop on the main thread behaves, so that is what :func:`spin_until_shutdown` does.
SIGINT and SIGTERM shut the context down through rclpy's own signal handlers, which ends the loop.

Each slice costs native memory that is never given back: a bare node with the compensator's
timers grew 2.34 MiB an hour spun in 50 ms slices, 0.23 with ``spin_once`` (15 minutes each,
side by side), whatever it published; the compensator had grown 2.7–2.9 MiB an hour. A process
that runs for weeks spins in slices of :data:`LONG_RUN_SLICE_S`.
"""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future
from rclpy.utilities import get_default_context

__all__ = ["LONG_RUN_SLICE_S", "make_executor", "shut_down", "spin_until_shutdown"]

#: Slice of a process that runs for weeks (the compensator), s: twenty times fewer slices than
#: the default's, so twenty times less of their memory; ``done()`` is checked between slices.
LONG_RUN_SLICE_S = 1.0


def make_executor(context: Context | None = None) -> Executor:
    """An EventsExecutor when this rclpy has one, else a SingleThreadedExecutor."""
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:
        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def spin_until_shutdown(
    node: Node, done: Callable[[], bool] = lambda: False, timeout_sec: float = 0.05
) -> None:
    """Spin ``node`` on the main thread until shutdown (Ctrl-C, SIGTERM) or ``done()``.

    ``timeout_sec`` is the slice of the EventsExecutor (module notes): ``done()`` is checked
    between slices.
    """
    context = node.context
    executor = make_executor(context)
    executor.add_node(node)
    try:
        # The EventsExecutor dispatches events in C++ until the (never done) future's timeout:
        # one Python call per slice instead of one per message, ~10 µs saved per message.
        slice_spin = getattr(executor, "spin_until_future_complete", None)
        never = Future()
        while context.ok() and not done():
            try:
                if slice_spin is not None and not isinstance(executor, SingleThreadedExecutor):
                    slice_spin(never, timeout_sec=timeout_sec)
                else:
                    executor.spin_once(timeout_sec=timeout_sec)
            except RCLError:
                # A signal can shut the context down while a callback publishes; that error is
                # the shutdown itself, anything else is not.
                if context.ok():
                    raise
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        shut_down(context)


def shut_down(context: Context | None = None) -> None:
    """``rclpy.try_shutdown``, where a signal's own shutdown racing it is no error.

    rclpy's signal handler shuts the contexts down from its own thread, without the lock
    ``try_shutdown`` checks under: when it lands between that check and the shutdown, rcl
    refuses the second one (ros2/rclpy#1352: ``RCLError: rcl_shutdown already called``) and a
    node stopped by Ctrl-C or SIGTERM exited with a traceback and status 1. The context being
    down is all that was asked; any other failure is raised.
    """
    try:
        rclpy.try_shutdown(context=context)
    except RCLError:
        if (context if context is not None else get_default_context()).ok():
            raise
