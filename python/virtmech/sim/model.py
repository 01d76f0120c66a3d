"""MuJoCo models (MJCF) of the simulated devices, generated from the core's own kinematics.

A device's MJCF is built from ``device.joints`` (the core's chain, in *chain* coordinates
s = C q + c0 of the device's joint values q), so the two cannot drift apart: the test suite
checks that the MJCF handle site and ``device.forward`` agree to 1e-9 m at random angles.

The coupling C (the PHANTOM Omni's parallelogram: serial elbow = absolute elbow - shoulder)
lives at the actuator and sensor boundary: every device joint i is a MuJoCo *fixed tendon*
of length sum_j Cinv[i, j] s_j (or the chain joint itself when that row is a unit vector), so

- a motor on device joint i is an actuator on that tendon, and its force f produces chain
  forces Cinv[i, :] f, i.e. tau_chain = Cinv^T tau_device (power is the same in both
  coordinates), with the motor's torque limit as the actuator's force range;
- device joint limits are the tendon's (or joint's) range;
- the sensor reads q = Cinv (s - c0).

Physical parameters are documented in :class:`DeviceModel` and ``docs/simulation.md``;
the ones not confirmed against a primary source are marked "(check)".
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

import virtmech as vm

# ---------------------------------------------------------------------------------------
# parameters


@dataclass
class DeviceModel:
    """Physical parameters of a simulated device (SI units).

    Defaults are for the PHANTOM Omni (``../shared/REFERENCE.md``); ``for_device`` picks
    per-device defaults. Values marked (check) are estimates, kept as parameters.
    """

    #: mass of each arm link (upper arm, forearm; Planar3R: link1, link2) [kg] (check)
    link_mass: float = 0.015
    #: mass of the waist turret (Omni only) [kg] (check)
    base_mass: float = 0.08
    #: reflected motor-rotor inertia on every actuated joint [kg·m²] (check); with the
    #: link, gimbal and stylus masses it gives the Omni 30..50 g apparent mass at the
    #: handle (REFERENCE.md: about 45 g, check)
    armature: float = 1.5e-4
    #: Coulomb friction on the actuated joints [N·m]: the Omni's backdrive friction of
    #: about 0.26 N at the tip (check) times half a link length (shared by two joints)
    joint_friction: float = 0.017
    #: viscous damping on the actuated joints [N·m·s/rad] (check)
    joint_damping: float = 2.0e-4
    #: Coulomb friction on the passive (gimbal) joints [N·m] (check)
    passive_friction: float = 2.0e-4
    #: viscous damping on the passive joints [N·m·s/rad] (check)
    passive_damping: float = 2.0e-5
    #: mass of each gimbal ring [kg], centred on the gimbal centre (check)
    gimbal_mass: float = 0.004
    #: stylus (pen) mass [kg] (check) and the offset of its centre of mass from the handle
    #: origin along the stylus, negative toward the hand [m] (check)
    stylus_mass: float = 0.01
    stylus_com: float = -0.02

    @staticmethod
    def for_device(device_type: str) -> DeviceModel:
        if device_type == "Planar3R":
            return DeviceModel(
                link_mass=0.15,
                base_mass=0.0,
                armature=2.0e-3,
                joint_friction=0.01,
                joint_damping=1.0e-3,
                passive_friction=2.0e-4,
                passive_damping=2.0e-5,
                gimbal_mass=0.0,
                stylus_mass=0.03,
                stylus_com=-0.02,
            )
        return DeviceModel()

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class HandBody:
    """The hand's mass and rotational inertia, rigidly on the handle (see human.py)."""

    mass_kg: float = 0.2
    inertia: float = 2.0e-4  # [kg·m²], isotropic about the handle origin


@dataclass
class Coupling:
    """s = C q + c0 between device joints q and chain joints s."""

    C: np.ndarray
    c0: np.ndarray
    Cinv: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.Cinv = np.linalg.inv(self.C)

    def to_chain(self, q: np.ndarray) -> np.ndarray:
        return self.C @ q + self.c0

    def to_device(self, s: np.ndarray) -> np.ndarray:
        return self.Cinv @ (s - self.c0)


def coupling_of(device) -> Coupling:
    """The joint map of a device the simulation knows (PhantomOmni, Planar3R)."""
    n = device.dof
    if isinstance(device, vm.PhantomOmni):
        d = device.to_dict()
        C = np.eye(6)
        C[2, 1] = -1.0  # serial elbow = absolute elbow - shoulder (parallelogram)
        c0 = np.zeros(6)
        for i in range(3):
            C[3 + i, 3 + i] = d["gimbal_sign"][i]
            c0[3 + i] = -d["gimbal_sign"][i] * d["gimbal_offset"][i]
        return Coupling(C, c0)
    return Coupling(np.eye(n), np.zeros(n))


def base_of(device, base: np.ndarray | None = None) -> np.ndarray:
    """The chain's base pose: identity for the Omni, the given base for a Planar3R."""
    if base is not None:
        return np.asarray(base, dtype=float)
    return np.eye(4)


def handle_of(device, base: np.ndarray, coupling: Coupling) -> np.ndarray:
    """The chain's fixed handle offset, recovered from the core: forward at s = 0 is
    base * prod(origin_i) * handle."""
    q0 = coupling.to_device(np.zeros(device.dof))
    T = base.copy()
    for j in device.joints:
        T = T @ j.origin
    return np.linalg.inv(T) @ device.forward(q0)


# ---------------------------------------------------------------------------------------
# MJCF


def _f(x) -> str:
    return repr(float(x))


def _fmt(v) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(v))


def _quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _pose_attrs(T: np.ndarray) -> str:
    return f'pos="{_fmt(T[:3, 3])}" quat="{_fmt(_quat(T[:3, :3]))}"'


def _inertial(mass: float, com, inertia) -> str:
    mass = max(mass, 1e-6)
    inertia = np.maximum(np.asarray(inertia, dtype=float), 1e-10)
    return f'<inertial pos="{_fmt(com)}" mass="{_f(mass)}" diaginertia="{_fmt(inertia)}"/>'


def _rod_inertia(mass: float, length: float) -> np.ndarray:
    i = mass * length * length / 12.0 + 1e-8
    return np.array([i, i, i])


@dataclass
class BuiltModel:
    """An MJCF model of a device with the indices the loop needs."""

    xml: str
    coupling: Coupling
    base: np.ndarray
    handle: np.ndarray
    gravity: np.ndarray
    timestep: float
    device_bodies: list[str]
    handle_site: str = "handle"


def build_mjcf(
    device,
    params: DeviceModel | None = None,
    hand: HandBody | None = None,
    base: np.ndarray | None = None,
    gravity=(0.0, 0.0, -9.81),
    timestep: float = 2.5e-4,
) -> BuiltModel:
    """MJCF of `device` (a vm.PhantomOmni or vm.Planar3R): one body per chain joint, motors
    with torque limits on the actuated joints, friction and damping on every joint, link
    inertias, the hand's mass on the handle, and a site at the handle frame."""
    dtype = device.to_dict()["type"]
    params = params or DeviceModel.for_device(dtype)
    hand = hand or HandBody()
    coupling = coupling_of(device)
    B = base_of(device, base)
    H = handle_of(device, B, coupling)
    joints = device.joints
    n = device.dof
    actuated = list(device.actuated)
    lower, upper = np.asarray(device.lower), np.asarray(device.upper)
    torque_limit = np.asarray(device.torque_limit)

    # link geometry: the offset to the next joint (or the handle) in each body frame
    nxt = [joints[i + 1].origin[:3, 3] for i in range(n - 1)] + [H[:3, 3]]
    last_arm = max(i for i in range(n) if actuated[i])  # bodies after it form the wrist

    # a joint is written on the chain joint directly when its device row is a unit vector
    direct = []
    for i in range(n):
        row = coupling.Cinv[i]
        nz = np.flatnonzero(np.abs(row) > 0)
        direct.append(len(nz) == 1 and nz[0] == i and row[i] == 1.0 and coupling.c0[i] == 0.0)

    lines = [
        f'<mujoco model="{dtype}">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_f(timestep)}" gravity="{_fmt(gravity)}" '
        'integrator="implicitfast">',
        # nothing in the model collides (every geom has contype 0) and it is one kinematic
        # tree: collision detection and island discovery would only cost time
        '    <flag contact="disable" island="disable"/>',
        "  </option>",
        '  <default><geom contype="0" conaffinity="0" rgba="0.6 0.6 0.65 1"/></default>',
        "  <worldbody>",
    ]
    indent = "    "
    bodies: list[str] = []
    first = B @ joints[0].origin
    for i, j in enumerate(joints):
        T = first if i == 0 else j.origin
        name = f"link{i}"
        bodies.append(name)
        lines.append(f'{indent}<body name="{name}" {_pose_attrs(T)}>')
        ind = indent + "  "
        jtype = "hinge" if j.type == "revolute" else "slide"
        passive = not actuated[i]
        fr = params.passive_friction if passive else params.joint_friction
        dm = params.passive_damping if passive else params.joint_damping
        jattr = f'damping="{_f(dm)}"'
        if direct[i]:
            arm = 0.0 if passive else params.armature
            jattr += f' frictionloss="{_f(fr)}" armature="{_f(arm)}"'
            if np.isfinite(lower[i]) and np.isfinite(upper[i]):
                jattr += f' range="{_f(lower[i])} {_f(upper[i])}"'
        lines.append(f'{ind}<joint name="s{i}" type="{jtype}" axis="{_fmt(j.axis)}" {jattr}/>')
        seg = nxt[i]
        L = float(np.linalg.norm(seg))
        mass = params.link_mass if i <= last_arm else params.gimbal_mass
        if dtype == "PhantomOmni" and i == 0:
            # the turret: its frame is at the shoulder; its mass sits on the waist axis
            lines.append(f"{ind}{_inertial(params.base_mass, [0, -0.02, 0], [2e-5, 4e-5, 2e-5])}")
            lines.append(f'{ind}<geom type="cylinder" size="0.02 0.01" euler="1.5708 0 0"/>')
        elif i <= last_arm and L > 1e-9:
            lines.append(f"{ind}{_inertial(mass, seg / 2, _rod_inertia(mass, L))}")
            lines.append(f'{ind}<geom type="capsule" fromto="0 0 0 {_fmt(seg)}" size="0.006"/>')
        elif i < n - 1:
            lines.append(f"{ind}{_inertial(mass, [0, 0, 0], [1e-6, 1e-6, 1e-6])}")
        else:
            # the stylus body: pen mass along the stylus, the handle site, the hand body
            z = H[:3, 2]
            com = H[:3, 3] + params.stylus_com * z
            lines.append(
                f"{ind}{_inertial(params.stylus_mass, com, _rod_inertia(params.stylus_mass, 0.12))}"
            )
            a, b = H[:3, 3] - 0.09 * z, H[:3, 3] + 0.03 * z
            lines.append(
                f'{ind}<geom type="capsule" fromto="{_fmt(a)} {_fmt(b)}" size="0.005" '
                'rgba="0.2 0.2 0.25 1"/>'
            )
            lines.append(f'{ind}<site name="handle" {_pose_attrs(H)} size="0.004"/>')
            # the hand: rigid on the handle, weight carried by the user's arm (gravcomp)
            lines.append(f'{ind}<body name="hand" {_pose_attrs(H)} gravcomp="1">')
            ih = hand.inertia
            lines.append(f"{ind}  {_inertial(hand.mass_kg, [0, 0, 0], [ih, ih, ih])}")
            lines.append(f"{ind}</body>")
        indent = ind
    for _ in range(n):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines.append("  </worldbody>")

    # device joints that are not chain joints: fixed tendons
    tendons, actuators = [], []
    for i in range(n):
        target = f'joint="s{i}"'
        if not direct[i]:
            passive = not actuated[i]
            fr = params.passive_friction if passive else params.joint_friction
            arm = 0.0 if passive else params.armature
            attrs = f'name="q{i}" frictionloss="{_f(fr)}" armature="{_f(arm)}"'
            if np.isfinite(lower[i]) and np.isfinite(upper[i]):
                off = float(coupling.Cinv[i] @ coupling.c0)
                attrs += f' range="{_f(lower[i] + off)} {_f(upper[i] + off)}"'
            parts = "".join(
                f'<joint joint="s{j}" coef="{_f(coupling.Cinv[i, j])}"/>'
                for j in range(n)
                if coupling.Cinv[i, j] != 0.0
            )
            tendons.append(f"    <fixed {attrs}>{parts}</fixed>")
            target = f'tendon="q{i}"'
        if actuated[i]:
            lim = float(torque_limit[i])
            actuators.append(
                f'    <motor name="m{i}" {target} gear="1" ctrlrange="{_f(-lim)} {_f(lim)}"/>'
            )
    if tendons:
        lines += ["  <tendon>", *tendons, "  </tendon>"]
    lines += ["  <actuator>", *actuators, "  </actuator>", "</mujoco>"]
    xml = "\n".join(lines) + "\n"
    return BuiltModel(
        xml=xml,
        coupling=coupling,
        base=B,
        handle=H,
        gravity=np.asarray(gravity, dtype=float),
        timestep=timestep,
        device_bodies=bodies,
    )


def compile_model(built: BuiltModel):
    """The mujoco.MjModel of a built MJCF."""
    import mujoco

    return mujoco.MjModel.from_xml_string(built.xml)


def apparent_mass(model, data, device, coupling: Coupling, q: np.ndarray) -> np.ndarray:
    """Translational apparent mass matrix (3, 3) [kg] at the handle at device joints q:
    (J M^-1 J^T)^-1 with the device's translational Jacobian in chain coordinates."""
    import mujoco

    data.qpos[:] = coupling.to_chain(q)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    J = device.jacobian(q)[:3] @ coupling.Cinv  # chain-coordinate Jacobian
    return np.linalg.pinv(J @ np.linalg.solve(M, J.T))
