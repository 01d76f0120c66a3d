"""`virtmech ros2-sim SCENARIO`: the scenario's simulated device (its MuJoCo model, the hand of
its [[intent]] timeline, its sensors) served as a ROS 2 driver, on the topics `virtmech ros2`
uses, so that the pair runs with no hardware (docs/ros2.md).

- out ``joint_states``     sensor_msgs/JointState: the sensed joints (quantised, delayed, as
                            the simulated encoders give them) in the driver's convention (the
                            same joint map parameters as the rendering node), stamped with the
                            sample's time; the velocity too with --velocity; the efforts the
                            motors apply
- in  ``joint_command``    sensor_msgs/JointState efforts by name (the default), or
      ``effort_commands``  std_msgs/Float64MultiArray (the actuated joints in order), or
      ``force_feedback``   geometry_msgs/WrenchStamped at the handle (force_rotation's axes)
                            (--command chooses), held until the next one (zero-order hold)

Each control cycle runs the simulation's own C++ loop (virtmech.sim.inner.ServoLoop) over a
held torque, one cycle at a time. Real time (the default): a cycle every period of the wall
clock, with the command that has arrived by then. --lockstep: each cycle waits for the
command that answers the last joint state (its header stamp), up to --timeout; the command
then acts one period later than in `virtmech run`, whatever the machine's load, so that a
run is reproducible. At the end: the run's metrics (the distance from the mechanism, as
`virtmech run` reports it) and the round trip joint state -> command (median, p99).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError
from .render import HandleWrench, default_parameters, settings_from_parameters
from .runtime import Session, declare_parameters, stamp_ns, stamp_of_ns

__all__ = ["COMMANDS", "SimDevice", "SimNode", "run"]

#: the command topics ros2-sim can take its torques from
COMMANDS = ("joint_command", "effort_commands", "force_feedback")


class SimDevice:
    """The scenario's simulated device stepped one control cycle at a time: the hand's plan
    and the sensor draws made a stretch ahead, as `virtmech run` makes them (the same draws
    in the same order), the torque held between calls."""

    STRETCH = 1000

    def __init__(self, rig, duration_s: float):
        from .. import _sim
        from ..sim.run_loop import StretchInputs

        self.rig = rig
        self.T = rig.period_s
        self.n = rig.device.dof
        self.N = int(round(duration_s / self.T)) + 1
        self.held = _sim.HeldTorque(rig.device)
        self.servo = rig.servo_loop(renderer=self.held)
        self.inputs = StretchInputs(rig)
        starts = set(self.inputs.intent.start_cycles(self.N))
        cuts = sorted(starts | set(range(0, self.N, self.STRETCH)) | {self.N})
        self.stretches = list(zip(cuts[:-1], cuts[1:]))
        self.log = np.zeros((self.N, len(rig.columns)))
        self.col = {c: i for i, c in enumerate(rig.columns)}
        self._stretch = -1
        self._inputs: tuple = ()
        self.k = 0

    def _handle_pose(self) -> np.ndarray:
        sim = self.rig.sim
        cp = sim.coupling
        return self.rig.device.forward(cp.Cinv @ (sim.data.qpos - cp.c0))

    def _prepare(self, i: int) -> None:
        """Stretch i's inputs, once the stretch before has run (checked stable)."""
        from ..sim.run_loop import check_stable

        k0, k1 = self.stretches[i]
        if i > 0:
            check_stable(self.rig.scenario, self.rig.sim, self.stretches[i - 1][0] * self.T,
                         k0 * self.T)
        self._stretch = i
        self._inputs = (k0, *self.inputs(k0, k1, self._handle_pose()))

    @property
    def done(self) -> bool:
        return self.k >= self.N

    def step(self, torque: np.ndarray) -> np.ndarray:
        """Cycle k with `torque` on the device's joints; returns its log row."""
        k = self.k
        if self._stretch < 0 or k >= self.stretches[self._stretch][1]:
            self._prepare(self._stretch + 1)
        k0, plan, noise, dropout = self._inputs
        j = k - k0
        self.held.torque = torque
        row = self.log[k : k + 1]
        self.servo.run(k, plan[j : j + 1], noise[j : j + 1], dropout[j : j + 1], row)
        self.k += 1
        return row[0]

    def sensed(self, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The row's sensed joints and their velocity estimate (the simulated driver's)."""
        c = self.col
        return row[c["qm0"] : c["qm0"] + self.n], row[c["dqm0"] : c["dqm0"] + self.n]

    def result(self, wall_s: float, info: dict):
        """The run as `virtmech run` describes it (the log's derived columns filled)."""
        from ..sim.log import SimResult
        from ..sim.run_loop import check_stable

        if self._stretch >= 0:
            k0 = self.stretches[self._stretch][0]
            check_stable(self.rig.scenario, self.rig.sim, k0 * self.T, self.k * self.T)
        log = self.log[: self.k]
        self.rig.derived_columns()(log)
        return SimResult(
            scenario=self.rig.scenario,
            columns=self.rig.columns,
            log=log,
            sim_time_s=(self.k - 1) * self.T,
            wall_time_s=wall_s,
            info={**self.rig.info(), **info},
        )


@dataclass
class Exchange:
    """The commands received, for the stepping thread (callbacks and the stepping thread share
    it under `lock`), and the round trips measured."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    arrived: threading.Condition = None  # type: ignore[assignment]
    torque: np.ndarray | None = None  # the latest command's joint torques (device)
    wrench: np.ndarray | None = None  # or its handle wrench (force_feedback)
    stamp: int = -1  # the latest command's stamp [ns]
    received: int = 0
    ignored: int = 0  # lockstep: commands answering no joint state of this run (stale zeros)
    sent: dict = field(default_factory=dict)  # stamp [ns] -> wall time it was published [s]
    round_trips: list = field(default_factory=list)  # [s]

    def __post_init__(self):
        self.arrived = threading.Condition(self.lock)


class SimNode:
    """The node: joint_states out, the chosen command topic in."""

    def __init__(self, session: Session, rig, device: SimDevice, command: str,
                 velocity: bool, lockstep: bool, name: str = "virtmech_sim"):
        from geometry_msgs.msg import WrenchStamped
        from rclpy.node import Node
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray

        self.node = Node(name, context=session.context)
        values = declare_parameters(self.node, default_parameters(rig))
        try:
            settings, jmap = settings_from_parameters(values, rig.device)
        except ValueError as e:
            raise UserError(*str(e).split("\n")) from None
        self.map, self.settings, self.device = jmap, settings, device
        self.command, self.velocity, self.lockstep = command, velocity, lockstep
        self.effort_joints = jmap.effort_joints(rig.device.actuated)
        self.act = np.asarray(rig.device.actuated, dtype=bool)
        self.wrench = HandleWrench(rig.device, settings.force_rotation)
        self.ex = Exchange()
        reliable = QoSProfile(
            depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
        )
        self.pub = self.node.create_publisher(JointState, "joint_states", reliable)
        self.msg = JointState()
        self.msg.name = list(jmap.names)
        kind = {
            "joint_command": (JointState, self.on_joint_command),
            "effort_commands": (Float64MultiArray, self.on_effort_commands),
            "force_feedback": (WrenchStamped, self.on_force_feedback),
        }
        msg_type, callback = kind[command]
        self.sub = self.node.create_subscription(msg_type, command, callback, reliable)
        self.logger = self.node.get_logger()
        self.rejected = 0
        self.resent = 0  # lockstep: joint states sent again

    # -- commands in (executor thread) ---------------------------------------------------

    def _take(self, stamp, torque=None, wrench=None) -> None:
        ns = stamp_ns(stamp) if stamp is not None else -1
        now = time.perf_counter()
        with self.ex.lock:
            sent = self.ex.sent.pop(ns, None)
            if sent is not None:
                self.ex.round_trips.append(now - sent)
            elif self.lockstep and stamp is not None:
                # lockstep: the device runs slower than the wall clock, the node's watchdog may
                # send a zero command of its own: only the answers to the joint states count
                self.ex.ignored += 1
                return
            self.ex.torque, self.ex.wrench = torque, wrench
            self.ex.stamp = ns
            self.ex.received += 1
            self.ex.arrived.notify_all()

    def on_joint_command(self, msg) -> None:
        efforts = np.zeros(self.map.dof)
        index = {name: i for i, name in enumerate(msg.name)}
        if len(msg.effort) != len(msg.name) or any(n not in index for n in self.map.names):
            self.rejected += 1
            return
        for i, name in enumerate(self.map.names):
            efforts[i] = msg.effort[index[name]]
        self._take(msg.header.stamp, torque=self.map.device_efforts(efforts))

    def on_effort_commands(self, msg) -> None:
        if len(msg.data) != len(self.effort_joints):
            self.rejected += 1
            return
        efforts = np.zeros(self.map.dof)
        efforts[self.effort_joints] = msg.data
        self._take(None, torque=self.map.device_efforts(efforts))

    def on_force_feedback(self, msg) -> None:
        f, m = msg.wrench.force, msg.wrench.torque
        self._take(msg.header.stamp, wrench=np.array([f.x, f.y, f.z, m.x, m.y, m.z]))

    # -- the device's side (stepping thread) ---------------------------------------------

    def torque(self, q: np.ndarray) -> np.ndarray:
        """The held command as joint torques at q (the actuated joints')."""
        with self.ex.lock:
            torque, wrench = self.ex.torque, self.ex.wrench
        if wrench is not None:
            return self.wrench.torques(q, wrench)
        tau = np.zeros(self.device.n)
        if torque is not None:
            tau[self.act] = torque[self.act]
        return tau

    def publish(self, stamp_ns_: int, row: np.ndarray) -> int:
        qm, dqm = self.device.sensed(row)
        c = self.device.col
        tau = row[c["tau_motor0"] : c["tau_motor0"] + self.device.n]
        m = self.msg
        stamp_of_ns(stamp_ns_, m.header.stamp)
        m.position = self.map.driver_positions(qm).tolist()
        m.velocity = self.map.driver_velocities(dqm).tolist() if self.velocity else []
        m.effort = self.map.driver_efforts(tau).tolist()
        with self.ex.lock:
            self.ex.sent[stamp_ns_] = time.perf_counter()
            if len(self.ex.sent) > 10000:  # never answered: forgotten
                for key in sorted(self.ex.sent)[:5000]:
                    del self.ex.sent[key]
            received = self.ex.received
        self.pub.publish(m)
        return received

    #: lockstep: a joint state not answered within this is sent again (best-effort readers
    #: may lose a sample) [s]
    RESEND_S = 0.05

    def wait_answer(self, stamp_ns_: int, received: int, timeout_s: float) -> bool:
        """Waits for a command stamped `stamp_ns_` (effort_commands carry no stamp: the first
        command after the `received`-th), sending the joint state again every RESEND_S;
        False after timeout_s."""
        end = time.monotonic() + timeout_s
        while True:
            resend = min(end, time.monotonic() + self.RESEND_S)
            with self.ex.lock:
                while True:
                    if self.command == "effort_commands":
                        if self.ex.received > received:
                            return True
                    elif self.ex.stamp == stamp_ns_:
                        return True
                    left = resend - time.monotonic()
                    if left <= 0:
                        break
                    self.ex.arrived.wait(left)
            if time.monotonic() >= end:
                return False
            self.resent += 1
            self.pub.publish(self.msg)


def _percentile_ms(values: list, p: float) -> float:
    return float(np.percentile(values, p) * 1e3) if values else math.nan


class Stepper:
    """The stepping thread: a cycle, its joint state out, and (lockstep) its answer awaited;
    or real time, paced by the wall clock."""

    def __init__(self, node: SimNode, lockstep: bool, timeout_s: float):
        self.node, self.dev = node, node.device
        self.lockstep, self.timeout_s = lockstep, timeout_s
        self.stop = threading.Event()
        self.missed = 0  # lockstep: joint states not answered within the timeout
        self.behind = 0  # real time: cycles run late by more than a period
        self.error: BaseException | None = None
        self.wall_s = 0.0
        self.thread = threading.Thread(target=self._run, name="virtmech-ros2-sim", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as e:  # reported by run()
            self.error = e

    def _loop(self) -> None:
        dev, node = self.dev, self.node
        T_ns = int(round(dev.T * 1e9))
        t0_ns = time.time_ns()  # the samples' stamps: t0 + k T on the device's clock
        wall0 = time.perf_counter()
        q = dev.sensed(dev.log[0])[0]
        while not dev.done and not self.stop.is_set():
            k = dev.k
            if not self.lockstep:
                due = wall0 + k * dev.T
                lag = time.perf_counter() - due
                if lag < 0:
                    time.sleep(-lag)
                elif lag > dev.T:
                    self.behind += 1
            row = dev.step(node.torque(q))
            q = dev.sensed(row)[0]
            stamp = t0_ns + k * T_ns
            received = node.publish(stamp, row)
            if self.lockstep and not node.wait_answer(stamp, received, self.timeout_s):
                self.missed += 1
        self.wall_s = time.perf_counter() - wall0


def _serve(rig, device: SimDevice, ros_args: list[str], command: str, velocity: bool,
           lockstep: bool, timeout_s: float, wait_s: float):
    """The ROS 2 side of a run: the node up, the rendering node awaited (up to `wait_s`), the
    device stepped to its end. (node, stepper, how the spin ended), or None when a signal
    ended the wait."""
    with Session("ros2-sim", ros_args) as session:
        node = SimNode(session, rig, device, command, velocity, lockstep)
        executor = session.executor(node.node)
        # the rendering node first: the run starts once the command topic has a publisher
        how = session.spin(
            executor, wait_s, done=lambda: node.node.count_publishers(node.sub.topic_name) > 0
        )
        if how == "signal":
            node.node.destroy_node()
            return None
        if how == "duration" and wait_s > 0:
            node.logger.warning(
                f"no publisher on {node.sub.topic_name} after {wait_s:g} s: the device runs "
                "with zero torque until commands come"
            )
        stepper = Stepper(node, lockstep, timeout_s)
        stepper.start()
        try:
            how = session.spin(executor, None, done=lambda: not stepper.thread.is_alive())
        finally:
            stepper.stop.set()
            stepper.thread.join()
            executor.shutdown()
            node.node.destroy_node()
    if stepper.error is not None:
        raise stepper.error
    return node, stepper, how


def _ros_figures(node: SimNode, stepper: Stepper, device: SimDevice, command: str,
                 lockstep: bool) -> dict:
    """The run's ROS 2 figures (run.json's "ros2_sim")."""
    rt = node.ex.round_trips
    return {
        "command": command,
        "lockstep": lockstep,
        "cycles": device.k,
        "commands_received": node.ex.received,
        "commands_rejected": node.rejected,
        "commands_ignored": node.ex.ignored,
        "joint_states_resent": node.resent,
        "lockstep_missed": stepper.missed,
        "realtime_behind": stepper.behind,
        "round_trip_median_ms": _percentile_ms(rt, 50),
        "round_trip_p99_ms": _percentile_ms(rt, 99),
        "round_trip_count": len(rt),
        "wall_time_s": stepper.wall_s,
    }


def _summary(name: str, node: SimNode, stepper: Stepper, ros: dict, m: dict, out,
             how: str) -> str:
    """The line printed at the end of a run."""
    lockstep = ros["lockstep"]
    return (
        f"virtmech ros2-sim: {name}: {ros['cycles']} cycles in {stepper.wall_s:.2f} s "
        f"wall ({'lockstep' if lockstep else 'real time'}, commands on {ros['command']}: "
        f"{node.ex.received} received, {node.rejected} rejected"
        + (
            f", {node.ex.ignored} ignored, {stepper.missed} missed, {node.resent} joint states "
            "sent again"
            if lockstep
            else f", {stepper.behind} cycles behind"
        )
        + f"); round trip median {ros['round_trip_median_ms']:.3f} ms, p99 "
        f"{ros['round_trip_p99_ms']:.3f} ms; dist max {m['dist_max_m'] * 1e3:.3f} mm"
        + (f"; wrote {out}/log.csv, run.json" if out is not None else "")
        + (f"; ended by {how}" if how == "signal" else "")
    )


def run(
    scenario,
    ros_args: list[str],
    duration_s: float | None = None,
    seed: int | None = None,
    command: str = "joint_command",
    lockstep: bool = False,
    timeout_s: float = 1.0,
    wait_s: float = 10.0,
    velocity: bool = False,
    out=None,
) -> int:
    """Serves the simulated device for the scenario's duration (or `duration_s`), then prints
    the run's figures (and writes log.csv and run.json to `out`)."""
    from ..builder import build
    from ..sim.output import metrics, write_run

    rig = build(scenario, seed)
    duration = rig.scenario.duration_s if duration_s is None else duration_s
    device = SimDevice(rig, duration)
    served = _serve(rig, device, ros_args, command, velocity, lockstep, timeout_s, wait_s)
    if served is None:
        return 0
    node, stepper, how = served
    ros = _ros_figures(node, stepper, device, command, lockstep)
    result = device.result(stepper.wall_s, {"ros2_sim": ros})
    m = metrics(result)
    if out is not None:
        write_run(result, out, metrics=m)
    print(_summary(rig.scenario.name, node, stepper, ros, m, out, how))
    return 0
