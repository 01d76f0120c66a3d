"""What `virtmech ros2` does with each message, without ROS: the device's joints from the
driver's, a velocity estimate where the message carries none, the scenario's renderer (a
Controller or a MechanismSet), and the command in the forms the outputs publish (device
torques, the driver's joint efforts, a handle wrench in the driver's axes). The node
(virtmech.ros2.node) moves messages in and out; everything it decides is here, so that it
is tested without a middleware.

Per input message (one servo cycle):

    r, stamp     <- the driver's joint positions by name (any order), the header's time
    q            <- A^-1 (r - b)                                   (joint_map.JointMap)
    dq           <- the message's velocities through A^-1, or the estimate:
                    dq += alpha ((q - q_last) / dt - dq), alpha = dt / (dt + 1 / (2 pi f_c)),
                    dt from the stamps (the simulation's sensor filter, sim.sensors)
    out          <- renderer.step(q, dq, stamp)      (its watchdog: the stamps' gaps)
    efforts      <- A^-T tau                                       (virtual work)
    wrench       <- the handle wrench that gives the actuated joints' torques (force only
                    where the force alone can: the Touch), in the driver's axes

A message older than the last one is dropped (counted); a gap between stamps longer than the
period by `late_s` counts as late. No new sample for `watchdog_s` of wall time (a sample sent
again is none): the command is zero (published once, and to every repeat after it), and the
controller's own watchdog ramps the force in again when the stamps resume after a gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .joint_map import JointMap, default_map

__all__ = [
    "Command",
    "HandleWrench",
    "RenderLoop",
    "Settings",
    "VelocityEstimate",
    "settings_from_parameters",
]

#: the Touch drivers' force axes from OpenHaptics' (x right, y up, z toward the user): x,
#: -z, y (omni_state.cpp sends a force (fx, fy, fz) to HD as (fx, fz, -fy))
TOUCH_FORCE_ROTATION = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))


@dataclass
class Settings:
    """The node's settings (its ROS parameters; the defaults from the scenario file)."""

    period_s: float = 1e-3  #: the driver's nominal period [s] (the scenario's controller)
    velocity_cutoff_hz: float = 100.0  #: the velocity estimate's cut-off [Hz]; 0: none
    watchdog_s: float = 0.02  #: no message for this long [s]: zero command
    late_s: float = 0.5e-3  #: a gap longer than period_s + late_s counts as late [s]
    use_message_velocity: bool = True  #: take the message's velocities where it has them
    marker_rate_hz: float = 30.0  #: markers per second; 0: none
    status_rate_hz: float = 2.0  #: status messages per second
    frame_id: str = "virtmech"  #: the markers' frame: the device's world axes
    force_frame_id: str = "base"  #: force_feedback's frame
    #: force_feedback's axes from the device's world axes (3 x 3, row by row)
    force_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def late_gap_s(self) -> float:
        return self.period_s + self.late_s


def _number(name: str, v, errors: list, positive: bool = False, nonneg: bool = False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        errors.append(f"{name}: expected a number, got {v!r}")
        return None
    if positive and not v > 0:
        errors.append(f"{name}: expected a number > 0, got {v!r}")
        return None
    if nonneg and not v >= 0:
        errors.append(f"{name}: expected a number >= 0, got {v!r}")
        return None
    return float(v)


def _numbers(name: str, v, errors: list):
    try:
        a = np.asarray(list(v), dtype=float)
    except (TypeError, ValueError):
        errors.append(f"{name}: expected a list of numbers, got {v!r}")
        return None
    return a


def default_parameters(rig) -> dict:
    """The node's parameters with their defaults: the joint map for the scenario's device,
    the period and the velocity filter's cut-off from the scenario's [controller] and
    [sensors]."""
    s = Settings()
    touch = rig.device.name == "PhantomOmni" and rig.device.dof == 6
    rotation = np.asarray(TOUCH_FORCE_ROTATION if touch else np.eye(3), dtype=float)
    return {
        **default_map(rig.device).to_parameters(),
        "period_s": float(rig.period_s),
        "velocity_cutoff_hz": float(rig.sensors.velocity_cutoff_hz),
        "watchdog_s": s.watchdog_s,
        "late_s": s.late_s,
        "use_message_velocity": s.use_message_velocity,
        "marker_rate_hz": s.marker_rate_hz,
        "status_rate_hz": s.status_rate_hz,
        "frame_id": s.frame_id,
        "force_frame_id": s.force_frame_id,
        "force_rotation": rotation.ravel().tolist(),
    }


def settings_from_parameters(values: dict, device) -> tuple[Settings, JointMap]:
    """Settings and the joint map from the parameters' values; a ValueError listing every
    mistake (one per line, each naming its parameter)."""
    errors: list[str] = []
    s = Settings()
    for name, kind in (
        ("period_s", "positive"),
        ("velocity_cutoff_hz", "nonneg"),
        ("watchdog_s", "positive"),
        ("late_s", "nonneg"),
        ("marker_rate_hz", "nonneg"),
        ("status_rate_hz", "positive"),
    ):
        v = _number(name, values[name], errors, kind == "positive", kind == "nonneg")
        if v is not None:
            setattr(s, name, v)
    if s.watchdog_s <= s.period_s and "watchdog_s" in values:
        errors.append(
            f"watchdog_s: expected more than the period ({s.period_s:g} s), got "
            f"{values['watchdog_s']!r}"
        )
    if not isinstance(values["use_message_velocity"], bool):
        errors.append(
            f"use_message_velocity: expected true or false, got {values['use_message_velocity']!r}"
        )
    else:
        s.use_message_velocity = values["use_message_velocity"]
    for name in ("frame_id", "force_frame_id"):
        if not isinstance(values[name], str):
            errors.append(f"{name}: expected a string, got {values[name]!r}")
        else:
            setattr(s, name, values[name])
    R = _numbers("force_rotation", values["force_rotation"], errors)
    if R is not None:
        if R.size != 9 or not np.all(np.isfinite(R)):
            errors.append(f"force_rotation: expected 9 numbers (3 x 3, row by row), got {R.size}")
        else:
            R = R.reshape(3, 3)
            if not (np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0):
                errors.append("force_rotation: expected a rotation matrix (orthonormal, det +1)")
            else:
                s.force_rotation = R
    jmap = None
    names = values["joint_names"]
    if isinstance(names, str) or not all(isinstance(x, str) for x in names):
        errors.append(f"joint_names: expected a list of strings, got {names!r}")
    else:
        A = _numbers("joint_map", values["joint_map"], errors)
        b = _numbers("joint_offsets", values["joint_offsets"], errors)
        if A is not None and b is not None:
            try:
                jmap = JointMap.checked(names, A, b, device.dof)
            except ValueError as e:
                errors.append(str(e))
    if errors:
        raise ValueError("\n".join(errors))
    assert jmap is not None
    return s, jmap


def _lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(A, b, rcond=None)[0]


class VelocityEstimate:
    """The backward difference through a first-order low-pass of cut-off f_c, as the
    simulation's sensors (sim.sensors.SensorSettings.velocity_alpha), at the gap dt between
    the samples' stamps: dq += alpha(dt) ((q - q_last) / dt - dq); zero on the first sample."""

    def __init__(self, n: int, cutoff_hz: float):
        from ..sim.sensors import SensorSettings

        self._filter = SensorSettings(velocity_cutoff_hz=cutoff_hz)
        self.dq = np.zeros(n)
        self._q: np.ndarray | None = None

    def update(self, q: np.ndarray, dt: float) -> np.ndarray:
        if self._q is not None and dt > 0.0:
            alpha = self._filter.velocity_alpha(dt)
            self.dq += alpha * ((q - self._q) / dt - self.dq)
        self._q = q.copy()
        return self.dq

    def reset(self) -> None:
        self.dq[:] = 0.0
        self._q = None


class HandleWrench:
    """The wrench at the handle whose joint torques J^T w are the command's on the actuated
    joints: a force alone where the force's Jacobian columns of the actuated joints have full
    rank at the device's home pose (the Touch: three motors, the gimbal centre's force; the
    least-squares force near a singular pose), else the least-squares wrench of smallest
    norm; then in the output's axes."""

    def __init__(self, device, rotation: np.ndarray):
        self.device = device
        self.act = np.flatnonzero(np.asarray(device.actuated, dtype=bool))
        self.R = np.asarray(rotation, dtype=float)
        J = np.asarray(device.jacobian(device.home))[:, self.act]
        self.force_only = np.linalg.matrix_rank(J[:3]) == self.act.size

    def __call__(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        w = np.zeros(6)
        if self.act.size == 0:
            return w
        Ja = np.asarray(self.device.jacobian(q))[:, self.act]
        ta = np.asarray(tau, dtype=float)[self.act]
        if self.force_only:
            A = Ja[:3].T
            try:
                w[:3] = np.linalg.solve(A, ta) if A.shape[0] == 3 else _lstsq(A, ta)
            except np.linalg.LinAlgError:  # a singular pose
                w[:3] = _lstsq(A, ta)
        else:
            w[:] = _lstsq(Ja.T, ta)
        out = np.empty(6)
        out[:3], out[3:] = self.R @ w[:3], self.R @ w[3:]
        return out

    def torques(self, q: np.ndarray, w_out: np.ndarray) -> np.ndarray:
        """The joint torques J^T w of a wrench in the output's axes, on the actuated joints
        (what a driver that takes a Cartesian force commands)."""
        w = np.concatenate([self.R.T @ w_out[:3], self.R.T @ w_out[3:]])
        tau = np.asarray(self.device.jacobian(q)).T @ w
        out = np.zeros_like(tau)
        out[self.act] = tau[self.act]
        return out


@dataclass
class Command:
    """One command, in every form the node publishes."""

    stamp_s: float  #: the input's stamp (the outputs carry it) [s]
    torque: np.ndarray  #: the device's joint torques [N·m or N]
    efforts: np.ndarray  #: the driver's joint efforts (joint_map's names)
    wrench: np.ndarray  #: force [N] and moment [N·m] at the handle, in force_rotation's axes
    zero: bool = False  #: a zero command for stale input
    output: object = None  #: the renderer's output (None for a zero command)


class RenderLoop:
    """The renderer over a stream of joint states; `on_joint_state` per message, `stale`
    from a timer, `stats` for the status topic."""

    def __init__(self, rig, settings: Settings, joint_map: JointMap):
        self.settings, self.map = settings, joint_map
        self.rig = rig.with_controller(watchdog_s=settings.watchdog_s)
        self.renderer = self.rig.renderer
        self.device = self.rig.device
        self.n = self.device.dof
        self.velocity = VelocityEstimate(self.n, settings.velocity_cutoff_hz)
        self.wrench = HandleWrench(self.device, settings.force_rotation)
        self.index: dict[str, int] = {name: i for i, name in enumerate(joint_map.names)}
        self.effort_joints = joint_map.effort_joints(self.device.actuated)
        self._order: tuple | None = None  # the last message's names, and their indices
        self._perm = np.arange(self.n)
        self._origin_ns: int | None = None  # the first message's time [ns]
        self.last_stamp = -math.inf  # [s] since the first message
        self.last_wall = -math.inf  # the node's clock at the last message taken [s]
        self.q = np.asarray(self.device.home, dtype=float).copy()
        self.zeroed = False  # the command is zero for stale input
        self._last_command: Command | None = None  # the answer to the last sample taken
        # counters
        self.messages = 0
        self.late = 0
        self.out_of_order = 0
        self.repeated = 0  # samples sent again (the stamp of the last): answered again
        self.rejected = 0  # messages without the joints (names missing, sizes wrong)
        self.stale_events = 0
        self.last_error = ""

    # -- input ---------------------------------------------------------------------------

    def _permutation(self, names) -> np.ndarray | None:
        """Indices into the message of the map's joints, cached for a message's name order;
        None (and last_error) where a joint is missing."""
        key = tuple(names)
        if key != self._order:
            try:
                pos = {name: i for i, name in enumerate(key)}
                self._perm = np.array([pos[name] for name in self.map.names], dtype=np.intp)
            except KeyError as e:
                self.last_error = (
                    f"joint_states: no joint {e.args[0]!r} in the message (names: {list(key)}); "
                    f"expected {list(self.map.names)} (parameter joint_names)"
                )
                return None
            self._order = key
        return self._perm

    def on_joint_state(self, names, position, velocity, stamp_ns: int, wall_ns: int):
        """One message: names and positions (and velocities, possibly empty) as the driver
        sends them, its stamp [ns] (0: none: the node's clock `wall_ns` [ns] instead).
        Returns the Command, or None where the message is dropped (counted)."""
        perm = self._permutation(names)
        position = np.asarray(position, dtype=float)
        if perm is None or position.size != len(names):
            if perm is not None:
                self.last_error = (
                    f"joint_states: {len(names)} names but {position.size} positions"
                )
            self.rejected += 1
            return None
        ns = stamp_ns if stamp_ns > 0 else wall_ns
        if self._origin_ns is None:
            self._origin_ns = ns
        t = (ns - self._origin_ns) * 1e-9  # [s] since the first message
        if t == self.last_stamp and self._last_command is not None:
            # the same sample again (a driver sending it again because its answer was lost):
            # the command that answered it again, the controller not stepped twice. It is no
            # news of the device: the watchdog still counts from the last new sample (a driver
            # frozen on one sample is zeroed), and once it has zeroed the command a repeat
            # gets zero, not the force from before the silence
            self.repeated += 1
            return self._zero(wall_ns * 1e-9) if self.zeroed else self._last_command
        if t < self.last_stamp:
            self.out_of_order += 1
            return None
        gap = t - self.last_stamp
        if self.messages > 0 and gap > self.settings.late_gap_s:
            self.late += 1
        q = self.map.device_positions(position[perm])
        velocity = np.asarray(velocity, dtype=float)
        if self.settings.use_message_velocity and velocity.size == len(names):
            dq = self.map.device_velocities(velocity[perm])
            self.velocity.update(q, 0.0)  # keeps the last sample for a later estimate
        else:
            dq = self.velocity.update(q, gap if self.messages > 0 else 0.0)
        self.last_stamp, self.last_wall, self.q = t, wall_ns * 1e-9, q
        self.messages += 1
        self.zeroed = False
        out = self.renderer.step(q, dq, t)
        tau = np.asarray(out.torque, dtype=float)
        self._last_command = Command(
            stamp_s=t,
            torque=tau,
            efforts=self.map.driver_efforts(tau),
            wrench=self.wrench(q, tau),
            output=out,
        )
        return self._last_command

    # -- watchdog ------------------------------------------------------------------------

    def stale(self, wall_ns: float):
        """A zero Command when no message has come for watchdog_s of the node's clock
        `wall_ns` [ns] (once per silence), else None."""
        wall_s = wall_ns * 1e-9
        if self.zeroed or wall_s - self.last_wall <= self.settings.watchdog_s:
            return None
        if self.messages == 0:
            return None  # nothing commanded yet
        self.zeroed = True
        self.stale_events += 1
        return self._zero(wall_s)

    def _zero(self, stamp_s: float) -> Command:
        """The zero command (no torque, no effort, no wrench)."""
        return Command(
            stamp_s=stamp_s,
            torque=np.zeros(self.n),
            efforts=np.zeros(self.n),
            wrench=np.zeros(6),
            zero=True,
        )

    # -- what the status topic says ------------------------------------------------------

    def last_cycle(self):
        """The last cycle's CycleOutput (a set's: the member rendered), or None."""
        if self.messages == 0:
            return None
        last = self.renderer.last
        return getattr(last, "cycle", last)

    def stats(self) -> dict:
        last = self.last_cycle()
        return {
            "messages": self.messages,
            "late": self.late,
            "out_of_order": self.out_of_order,
            "repeated": self.repeated,
            "rejected": self.rejected,
            "stale": self.zeroed,
            "stale_events": self.stale_events,
            "status": [] if last is None else list(last.status_names),
            "ramp": None if last is None else float(last.ramp),
            "force_n": 0.0
            if last is None or self.zeroed
            else float(np.linalg.norm(np.asarray(last.wrench)[:3])),
            "last_error": self.last_error,
        }
