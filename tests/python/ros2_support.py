"""What the ROS 2 tests share: an isolated DDS domain per test (its own ROS_DOMAIN_ID, discovery
on this machine only), the commands `virtmech ros2` and `virtmech ros2-sim` as processes, and
an rclpy probe in the test's process that publishes joint states and records what the node
answers."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

#: the ROS 2 wheels exist for CPython 3.10 to 3.13 on Linux (pyproject.toml's [ros2] extra)
ROS_PLATFORM = sys.version_info >= (3, 10) and sys.platform == "linux"

_domains = itertools.count()


def domain_id(worker: str) -> int:
    """A DDS domain no other test of this run uses: 1 to 99 per xdist worker (gw0, gw1, ...),
    workers 100 apart below 232 (the largest domain id Fast DDS maps to ports)."""
    w = int(worker[2:]) if worker.startswith("gw") and worker[2:].isdigit() else 0
    return 1 + (w % 2) * 100 + next(_domains) % 99


def ros_env(domain: int) -> dict:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env.pop("ROS_STATIC_PEERS", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def virtmech(args: list[str], env: dict, **kw) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "virtmech", *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def finish(p: subprocess.Popen, timeout: float = 60.0) -> tuple[int, str, str]:
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        raise AssertionError(f"{p.args} did not end in {timeout} s:\n{out}\n{err}") from None
    return p.returncode, out, err


class Probe:
    """A node in the test's process (its own rclpy context): publishes sensor_msgs/JointState on
    `joint_states` and records joint_command, effort_commands, force_feedback, markers and
    status as they come (a spinning thread)."""

    def __init__(self, domain: int, name: str = "probe"):
        import rclpy
        from geometry_msgs.msg import WrenchStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray, String
        from visualization_msgs.msg import MarkerArray

        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(
            context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO
        )
        self.node = rclpy.create_node(name, context=self.context)
        qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.JointState = JointState
        self.pub = self.node.create_publisher(JointState, "joint_states", qos)
        self.lock = threading.Lock()
        self.received: dict[str, list] = {k: [] for k in (
            "joint_command", "effort_commands", "force_feedback", "markers", "status")}
        self.subs = {
            topic: self.node.create_subscription(
                kind, topic, lambda m, t=topic: self._got(t, m), qos
            )
            for topic, kind in (
                ("joint_command", JointState),
                ("effort_commands", Float64MultiArray),
                ("force_feedback", WrenchStamped),
                ("markers", MarkerArray),
                ("status", String),
            )
        }
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _got(self, topic: str, msg) -> None:
        with self.lock:
            self.received[topic].append((time.monotonic(), msg))

    def _spin(self) -> None:
        while not self.stop.is_set():
            self.executor.spin_once(timeout_sec=0.02)

    def messages(self, topic: str) -> list:
        with self.lock:
            return list(self.received[topic])

    def wait_for(self, cond, timeout: float, what: str):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            v = cond()
            if v:
                return v
            time.sleep(0.01)
        raise AssertionError(f"timed out after {timeout} s waiting for {what}")

    def wait_connected(self, topics=("joint_command", "effort_commands", "force_feedback"),
                       timeout: float = 30.0) -> None:
        """Until the node's reader of joint_states and its writers of `topics` have matched
        the probe's."""
        self.wait_for(
            lambda: self.pub.get_subscription_count() > 0
            and all(self.subs[t].get_publisher_count() > 0 for t in topics),
            timeout,
            f"virtmech ros2 on joint_states and {', '.join(topics)}",
        )

    def send(self, names, position, stamp_ns: int, velocity=()) -> None:
        m = self.JointState()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        m.name = list(names)
        m.position = [float(v) for v in position]
        m.velocity = [float(v) for v in velocity]
        self.pub.publish(m)

    def answer(self, stamp_ns: int, timeout: float = 10.0, resend=None):
        """The joint_command stamped `stamp_ns`, calling resend() (which sends the joint state)
        first and every 0.2 s until it comes: the first messages may go before the reader has
        matched the writer."""
        sec, ns = divmod(int(stamp_ns), 1_000_000_000)

        def found():
            for _, m in reversed(self.messages("joint_command")):
                if m.header.stamp.sec == sec and m.header.stamp.nanosec == ns:
                    return m
            return None

        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if resend is not None:
                resend()
            nxt = time.monotonic() + 0.2
            while time.monotonic() < nxt:
                m = found()
                if m is not None:
                    return m
                time.sleep(0.0002)
        raise AssertionError(f"no joint_command stamped {stamp_ns} ns within {timeout} s")

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def efforts_of(msg, names) -> np.ndarray:
    index = {n: i for i, n in enumerate(msg.name)}
    return np.array([msg.effort[index[n]] for n in names])
