"""`virtmech ros2 SCENARIO`: the scenario's renderer as a ROS 2 node between a device driver
and the rest of a ROS stack (docs/ros2.md).

Topics (relative names: remap them with ``--ros-args -r joint_states:=/phantom/joint_states``):

- in  ``joint_states``     sensor_msgs/JointState: the driver's joint positions by name (and
                            velocities, where it sends them)
- out ``joint_command``    sensor_msgs/JointState: the joint efforts, every joint by name
- out ``effort_commands``  std_msgs/Float64MultiArray: the actuated joints' efforts in order
                            (ros2_control's forward effort controller's `commands`)
- out ``force_feedback``   geometry_msgs/WrenchStamped: the force at the handle that gives
                            the actuated joints' torques, in the driver's axes
- out ``markers``          visualization_msgs/MarkerArray: mechanism, theta, theta*, forces
- out ``status``           std_msgs/String: JSON with the status names, the input's rate,
                            late and dropped messages, the stale flag

Each command carries the header stamp of the joint state it answers. One input kind is
implemented: joint states (`JointStateInput`); a device served by its pose would be one more
input kind beside it (a geometry_msgs/PoseStamped on ``handle_pose``).
"""

from __future__ import annotations

import collections
import json
import time

import numpy as np

from ..errors import UserError
from .render import RenderLoop, Settings, default_parameters, settings_from_parameters
from .runtime import Session, declare_parameters, stamp_ns

__all__ = ["INPUT_KINDS", "JointStateInput", "RenderNode", "run"]


def _qos_input():
    """The latest sample only, best effort: a late joint state is worth nothing, and a best
    effort reader takes a reliable writer's samples too."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT
    )


def _qos_output():
    """Reliable (any reader matches), the latest command only."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
    )


class JointStateInput:
    """sensor_msgs/JointState on ``joint_states``: a serial device's joints."""

    topic = "joint_states"

    def subscribe(self, node, callback):
        from sensor_msgs.msg import JointState

        return node.create_subscription(
            JointState,
            self.topic,
            lambda msg: callback(msg.header.stamp, msg.name, msg.position, msg.velocity),
            _qos_input(),
        )


#: the input kind of each device type (its name)
INPUT_KINDS = {"default": JointStateInput}


class RenderNode:
    """The node: the input's subscription, the outputs' publishers, a watchdog timer and a
    status timer around a RenderLoop."""

    def __init__(self, session: Session, rig, name: str = "virtmech"):
        from geometry_msgs.msg import WrenchStamped
        from rclpy.node import Node
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray, String

        self.node = Node(name, context=session.context)
        self.rig = rig
        values = declare_parameters(self.node, default_parameters(rig))
        try:
            settings, jmap = settings_from_parameters(values, rig.device)
        except ValueError as e:
            raise UserError(*str(e).split("\n")) from None
        self.settings: Settings = settings
        self.loop = RenderLoop(rig, settings, jmap)
        self.input = INPUT_KINDS.get(rig.device.name, INPUT_KINDS["default"])()
        self.sub = self.input.subscribe(self.node, self.on_input)
        qos = _qos_output()
        self.pub_joint = self.node.create_publisher(JointState, "joint_command", qos)
        self.pub_effort = self.node.create_publisher(Float64MultiArray, "effort_commands", qos)
        self.pub_wrench = self.node.create_publisher(WrenchStamped, "force_feedback", qos)
        self.pub_status = self.node.create_publisher(String, "status", qos)
        self.msg_joint = JointState()
        self.msg_joint.name = list(jmap.names)
        self.msg_effort = Float64MultiArray()
        self.msg_wrench = WrenchStamped()
        self.msg_wrench.header.frame_id = settings.force_frame_id
        self.String = String
        self.markers = None
        if settings.marker_rate_hz > 0:
            from visualization_msgs.msg import MarkerArray

            from .markers import MarkerBuilder

            self.markers = MarkerBuilder(
                rig.device, [m.to_dict() for m in rig.mechanisms], settings.frame_id
            )
            self.pub_markers = self.node.create_publisher(MarkerArray, "markers", qos)
        self._next_marker = 0.0
        self._next_shapes = 0.0
        self._window = (time.monotonic(), 0)  # (wall, messages) at the last status
        self.rate_hz = 0.0
        self.node.create_timer(settings.watchdog_s / 2.0, self.check_stale)
        self.node.create_timer(1.0 / settings.status_rate_hz, self.publish_status)
        self.logger = self.node.get_logger()
        self._faulted = False
        #: the node's own work per joint state answered: its thread's processor time from the
        #: callback's start to the command's last publication [ns] (the latest 65536)
        self.work_ns: collections.deque = collections.deque(maxlen=65536)
        efforts = ", ".join(jmap.names[i] for i in self.loop.effort_joints)
        self.logger.info(
            f"rendering {rig.scenario.name} ({rig.device.name}, "
            f"{rig.mechanism.to_dict()['type']}): {self.sub.topic_name} -> "
            f"{self.pub_joint.topic_name}, {self.pub_effort.topic_name} ({efforts}), "
            f"{self.pub_wrench.topic_name}"
        )

    # -- per message ---------------------------------------------------------------------

    def on_input(self, stamp, names, position, velocity) -> None:
        wall, cpu = time.monotonic_ns(), time.thread_time_ns()
        cmd = self.loop.on_joint_state(names, position, velocity, stamp_ns(stamp), wall)
        if cmd is None:
            return
        self.publish(cmd, stamp)
        self.work_ns.append(time.thread_time_ns() - cpu)
        out = cmd.output
        # (a zero answer to a sample sent again after the watchdog ran no cycle: no change)
        fault = bool(int(out.status) & 0xFF00) if out is not None else self._faulted
        if fault != self._faulted:
            self._faulted = fault
            if fault:
                self.logger.warning(f"zero torque: {', '.join(out.status_names)}")
            else:
                self.logger.info("rendering again (the force ramps in)")
        if self.markers is not None and wall * 1e-9 >= self._next_marker:
            self.publish_markers(stamp, wall * 1e-9)

    def publish(self, cmd, stamp) -> None:
        """The command on joint_command, effort_commands and force_feedback, stamped with the
        input's stamp."""
        self.msg_joint.header.stamp = stamp
        self.msg_joint.effort = cmd.efforts.tolist()
        self.pub_joint.publish(self.msg_joint)
        self.msg_effort.data = cmd.efforts[self.loop.effort_joints].tolist()
        self.pub_effort.publish(self.msg_effort)
        w = self.msg_wrench.wrench
        self.msg_wrench.header.stamp = stamp
        w.force.x, w.force.y, w.force.z = (float(v) for v in cmd.wrench[:3])
        w.torque.x, w.torque.y, w.torque.z = (float(v) for v in cmd.wrench[3:])
        self.pub_wrench.publish(self.msg_wrench)

    def publish_markers(self, stamp, now_s: float) -> None:
        shapes = now_s >= self._next_shapes
        if shapes:
            self._next_shapes = now_s + 1.0
        self._next_marker = now_s + 1.0 / self.settings.marker_rate_hz
        cycle = None if self.loop.zeroed else self.loop.last_cycle()
        self.pub_markers.publish(self.markers.array(stamp, self.loop.q, cycle, shapes))

    # -- timers --------------------------------------------------------------------------

    def check_stale(self) -> None:
        cmd = self.loop.stale(time.monotonic_ns())
        if cmd is None:
            return
        stamp = self.node.get_clock().now().to_msg()
        self.publish(cmd, stamp)
        self.logger.warning(
            f"no joint state for {self.settings.watchdog_s:g} s on {self.sub.topic_name}: "
            "zero command"
        )
        if self.markers is not None:
            self.publish_markers(stamp, time.monotonic())
        self.publish_status()

    def status(self) -> dict:
        now = time.monotonic()
        w0, m0 = self._window
        if now - w0 >= 0.5:
            self.rate_hz = (self.loop.messages - m0) / (now - w0)
            self._window = (now, self.loop.messages)
        return {
            "node": self.node.get_fully_qualified_name(),
            "scenario": self.rig.scenario.name,
            "input": self.sub.topic_name,
            "rate_hz": round(self.rate_hz, 1),
            **self.loop.stats(),
        }

    def publish_status(self) -> None:
        self.pub_status.publish(self.String(data=json.dumps(self.status())))

    def zero(self) -> None:
        """A zero command on every output (at the end of a run)."""
        z = self.loop.stale(float("inf"))
        if z is None:
            n = self.loop.n
            from .render import Command

            z = Command(0.0, np.zeros(n), np.zeros(n), np.zeros(6), zero=True)
        self.publish(z, self.node.get_clock().now().to_msg())

    def close(self) -> None:
        self.node.destroy_node()


def run(scenario, ros_args: list[str], duration_s: float | None = None) -> int:
    """Runs the node until Ctrl-C, SIGTERM or `duration_s`; a zero command at the end."""
    from ..builder import build

    rig = build(scenario, simulated=False)
    with Session("ros2", ros_args) as session:
        node = RenderNode(session, rig)
        executor = session.executor(node.node)
        try:
            how = session.spin(executor, duration_s)
        finally:
            node.zero()
            node.publish_status()
            time.sleep(0.05)  # the last messages leave before the node goes
            stats = node.loop.stats()
            work_us = np.asarray(node.work_ns, dtype=float) * 1e-3
            executor.shutdown()
            node.close()
    work = (
        f"; the node's processor time per joint state median {np.median(work_us):.0f} µs, p99 "
        f"{np.percentile(work_us, 99):.0f} µs"
        if work_us.size
        else ""
    )
    print(
        f"virtmech ros2: {rig.scenario.name}: {stats['messages']} joint states, "
        f"{stats['late']} late, {stats['out_of_order']} out of order, {stats['repeated']} "
        f"repeated, {stats['rejected']} "
        f"rejected, {stats['stale_events']} stale{work}; ended by {how}"
    )
    return 0
