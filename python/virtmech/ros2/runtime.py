"""What both ROS 2 commands share: rclpy imported (or a UserError naming the extra), a context
initialised from the command line's ``--ros-args`` (a mistake there is a UserError naming
it), the node's parameters declared from their defaults (an override of an unknown name is
a UserError), and a spin that ends on Ctrl-C, SIGTERM or after a duration, leaving the
node time to send its last (zero) command.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import tempfile
import threading
import time
from typing import Any

from ..errors import UserError

__all__ = ["Session", "declare_parameters", "require_ros", "stamp_ns", "stamp_of_ns"]

#: the pip command that installs the ROS 2 wheels
INSTALL = "pip install 'virtmech[ros2]'"


def require_ros(command: str) -> None:
    """rclpy and the messages the nodes use, or a UserError saying how to install them."""
    for module in (
        "rclpy",
        "sensor_msgs.msg",
        "std_msgs.msg",
        "geometry_msgs.msg",
        "visualization_msgs.msg",
    ):
        try:
            __import__(module)
        except ImportError as e:
            raise UserError(
                f"virtmech {command}: ROS 2 needs the [ros2] extra ({module} cannot be imported: "
                f"{e}); install the ROS 2 Jazzy wheels with: {INSTALL}"
            ) from None


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time as integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def stamp_of_ns(ns: int, stamp) -> Any:
    """Sets a builtin_interfaces/Time from integer nanoseconds; returns it."""
    stamp.sec, stamp.nanosec = divmod(int(ns), 1_000_000_000)
    return stamp


@contextlib.contextmanager
def _quiet_stderr(keep: list):
    """stderr (the file descriptor: rcl's own log lines) captured for the block; what it
    wrote is appended to `keep` as text."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            keep.append(tmp.read().decode(errors="replace"))


class Session:
    """An rclpy context for one command: `with Session(command, ros_args) as s:` ... ;
    `s.stop` is set by SIGINT and SIGTERM (rclpy's own handlers are not installed, so that the
    node still publishes after a Ctrl-C); `s.spin(node, duration_s)` runs its callbacks."""

    def __init__(self, command: str, ros_args: list[str]):
        self.command = command
        self.ros_args = list(ros_args)
        self.stop = threading.Event()
        self.context = None
        self._old: dict = {}

    def __enter__(self) -> Session:
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        self.context = rclpy.Context()
        logged: list[str] = []
        try:
            with _quiet_stderr(logged):
                rclpy.init(
                    args=["virtmech", *self.ros_args],
                    context=self.context,
                    signal_handler_options=SignalHandlerOptions.NO,
                )
        except Exception as e:  # rclpy's RCLError, UnknownROSArgsError
            text = str(e).split(". Error:")[0].replace("failed to initialize rcl: ", "")
            raise UserError(
                f"--ros-args {' '.join(self.ros_args[1:])}: {text}; expected ROS 2 arguments "
                "such as -r joint_states:=/phantom/joint_states or -p watchdog_s:=0.05"
            ) from None
        if logged and logged[0]:
            sys.stderr.write(logged[0])
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, lambda *_: self.stop.set())
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, handler)
        if self.context is not None:
            with contextlib.suppress(Exception):
                self.context.try_shutdown()

    def executor(self, node, threads: int = 1):
        from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

        ex = (
            SingleThreadedExecutor(context=self.context)
            if threads == 1
            else MultiThreadedExecutor(num_threads=threads, context=self.context)
        )
        ex.add_node(node)
        return ex

    def spin(self, executor, duration_s: float | None = None, done=None) -> str:
        """Runs the executor's callbacks until a signal ('signal'), `duration_s` of wall time
        ('duration') or done() ('done')."""
        end = math.inf if duration_s is None else time.monotonic() + duration_s
        while True:
            if self.stop.is_set():
                return "signal"
            if done is not None and done():
                return "done"
            left = end - time.monotonic()
            if left <= 0:
                return "duration"
            executor.spin_once(timeout_sec=min(0.05, left))


def declare_parameters(node, defaults: dict) -> dict:
    """Declares each parameter (any type: the values are checked by the caller, with messages
    naming them) and returns {name: value}. A -p override of a name the node does not have
    is a UserError listing the names it has."""
    from rcl_interfaces.msg import ParameterDescriptor

    overrides = set(getattr(node, "_parameter_overrides", {}) or {})
    unknown = sorted(n for n in overrides - set(defaults) if not n.startswith(("qos_", "use_sim")))
    if unknown:
        raise UserError(
            f"-p {', '.join(unknown)}: no such parameter of virtmech {node.get_name()}; "
            f"expected one of {', '.join(sorted(defaults))}"
        )
    values = {}
    for name, default in defaults.items():
        node.declare_parameter(name, default, ParameterDescriptor(dynamic_typing=True))
        values[name] = node.get_parameter(name).value
    return values
