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

    Defaults are for the PHANTOM Omni (docs/devices.md); ``for_device`` picks per-device
    defaults. Values marked (check) are estimates, kept as parameters.
    """

    #: mass of each arm link (upper arm, forearm; Planar3R: link1, link2) [kg] (check)
    link_mass: float = 0.015
    #: mass of a turret on the first joint (the Omni's waist; 0: none) [kg] (check)
    base_mass: float = 0.08
    #: reflected motor-rotor inertia on every actuated joint [kg·m²] (check); with the
    #: link, gimbal and stylus masses it gives the Omni 30..50 g apparent mass at the
    #: handle (commonly given as about 45 g, check)
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
    def for_device(device_name: str) -> DeviceModel:
        """Defaults by device name: the Omni's, the Planar3R's, a Cartesian device's (its
        scenario type or one of its models' names), else the Omni's without its waist turret
        (a generic arm of light links)."""
        if device_name == "PhantomOmni":
            return DeviceModel()
        if device_name == "CartesianDevice" or device_name in vm.CartesianDevice.MODELS:
            # three slides and a wrist: link_mass is each slide's carriage [kg], armature the
            # mass its motor and transmission reflect there [kg], joint_friction [N] and
            # joint_damping [N·s/m] on the slides; a handle of about 0.2 kg apparent mass and
            # 0.1 N of friction: simulation parameters, not measured or datasheet figures
            return DeviceModel(
                link_mass=0.02,
                base_mass=0.0,
                armature=0.15,
                joint_friction=0.1,
                joint_damping=0.05,
                passive_friction=2.0e-4,
                passive_damping=2.0e-5,
                gimbal_mass=0.01,
                stylus_mass=0.02,
                stylus_com=-0.02,
            )
        if device_name == "Planar3R":
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
        return DeviceModel(base_mass=0.0)

    def to_dict(self) -> dict:
        return asdict(self)


def device_physics(scenario_device: dict) -> DeviceModel:
    """The physical parameters of a scenario's [device] table: the device's defaults
    (DeviceModel.for_device) with the keys the table sets."""
    p = DeviceModel.for_device(scenario_device["type"])
    for k in p.to_dict():
        if k in scenario_device:
            setattr(p, k, float(scenario_device[k]))
    return p


@dataclass
class HandBody:
    """The hand's mass and rotational inertia, rigidly on the handle (see human.py). Both
    zero: no hand body at all (a model built without the hand, e.g. to compare a released
    hand with)."""

    mass_kg: float = 0.2
    inertia: float = 2.0e-4  # [kg·m²], isotropic about the handle origin

    @property
    def present(self) -> bool:
        return not (self.mass_kg == 0.0 and self.inertia == 0.0)


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


# gravity in each device's base frame where it is not -z: OpenHaptics' frames have y up
_GRAVITY = {"PhantomOmni": (0.0, -9.81, 0.0)}


def world_gravity(device) -> np.ndarray:
    """Gravity [m/s²] in the device's world frame (its base frame's parent)."""
    return np.array(_GRAVITY.get(device.name, (0.0, 0.0, -9.81)))


def _serial(device):
    """The device as a serial chain (the simulation builds its bodies from the chain)."""
    if not isinstance(device, vm.Device):
        raise TypeError(
            f"device: the simulation needs a serial-chain device (vm.Device and its "
            f"subclasses), got {type(device).__name__}"
        )
    return device


def coupling_of(device) -> Coupling:
    """The device's joint map s = C q + c0, as the core holds it."""
    d = _serial(device)
    return Coupling(np.asarray(d.coupling, dtype=float), np.asarray(d.coupling_offset, dtype=float))


# ---------------------------------------------------------------------------------------
# the MuJoCo model, built with MjSpec (MuJoCo's model-editing API)


def _quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _place(element, T: np.ndarray) -> None:
    element.pos = T[:3, 3]
    element.quat = _quat(T[:3, :3])


def _inertial(body, mass: float, com, inertia) -> None:
    body.explicitinertial = True
    body.mass = max(mass, 1e-6)
    body.ipos = np.asarray(com, dtype=float)
    body.inertia = np.maximum(np.asarray(inertia, dtype=float), 1e-10)


def _rod_inertia(mass: float, length: float) -> np.ndarray:
    i = mass * length * length / 12.0 + 1e-8
    return np.array([i, i, i])


@dataclass
class BuiltModel:
    """A device's MuJoCo model (its MjSpec) with the indices the loop needs."""

    spec: object  # mujoco.MjSpec
    coupling: Coupling
    base: np.ndarray
    handle: np.ndarray
    gravity: np.ndarray
    timestep: float
    device_bodies: list[str]
    handle_site: str = "handle"

    @property
    def xml(self) -> str:
        """The model as MJCF."""
        return self.spec.to_xml()


def _limits(element, lo: float, hi: float) -> None:
    """A joint's or tendon's range where both ends are finite."""
    import mujoco

    if np.isfinite(lo) and np.isfinite(hi):
        element.range = [lo, hi]
        element.limited = mujoco.mjtLimited.mjLIMITED_TRUE


def _spec(name: str, gravity, timestep: float):
    """An empty MjSpec with the options every device model shares."""
    import mujoco

    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.option.timestep = timestep
    spec.option.gravity = np.asarray(gravity, dtype=float)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # nothing in the model collides (every geom has contype 0) and it is one kinematic
    # tree: collision detection and island discovery would only cost time
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
    spec.default.geom.contype = 0
    spec.default.geom.conaffinity = 0
    spec.default.geom.rgba = [0.6, 0.6, 0.65, 1.0]
    return spec


class _ChainModel:
    """The MJCF of a serial-chain device, built stage by stage (build_mjcf)."""

    def __init__(self, device, params: DeviceModel, hand: HandBody):
        self.device, self.params, self.hand = device, params, hand
        self.coupling = coupling_of(device)
        self.B = np.asarray(device.base, dtype=float)
        self.H = np.asarray(device.handle, dtype=float)
        self.joints = device.joints
        self.n = device.dof
        self.actuated = list(device.actuated)
        self.lower, self.upper = np.asarray(device.lower), np.asarray(device.upper)
        self.torque_limit = np.asarray(device.torque_limit)
        n, joints = self.n, self.joints
        # link geometry: the offset to the next joint (or the handle) in each body frame
        self.nxt = [joints[i + 1].origin[:3, 3] for i in range(n - 1)] + [self.H[:3, 3]]
        self.last_arm = max((i for i in range(n) if self.actuated[i]), default=-1)
        # a joint is written on the chain joint directly when its device row is a unit vector
        self.direct = []
        for i in range(n):
            row = self.coupling.Cinv[i]
            nz = np.flatnonzero(np.abs(row) > 0)
            self.direct.append(
                len(nz) == 1 and nz[0] == i and row[i] == 1.0 and self.coupling.c0[i] == 0.0
            )

    def bodies(self, spec) -> list[str]:
        """One body per chain joint, each with its joint and its mass and geometry."""
        parent, names = spec.worldbody, []
        for i, j in enumerate(self.joints):
            body = parent.add_body(name=f"link{i}")
            _place(body, self.B @ j.origin if i == 0 else j.origin)
            names.append(body.name)
            self.joint(body, i, j)
            self.mass(body, i)
            parent = body
        return names

    def joint(self, body, i: int, j) -> None:
        import mujoco

        p = self.params
        passive = not self.actuated[i]
        kind = mujoco.mjtJoint.mjJNT_HINGE if j.type == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        joint = body.add_joint(
            name=f"s{i}",
            type=kind,
            axis=np.asarray(j.axis, dtype=float),
            damping=p.passive_damping if passive else p.joint_damping,
        )
        if self.direct[i]:
            joint.frictionloss = p.passive_friction if passive else p.joint_friction
            joint.armature = 0.0 if passive else p.armature
            _limits(joint, self.lower[i], self.upper[i])

    def mass(self, body, i: int) -> None:
        """Body i's inertia and geometry: a turret, an arm link, a gimbal ring or the
        stylus."""
        import mujoco

        p, seg = self.params, self.nxt[i]
        L = float(np.linalg.norm(seg))
        mass = p.link_mass if i <= self.last_arm else p.gimbal_mass
        if i == 0 and p.base_mass > 0.0:
            # a turret: its frame at the shoulder, its mass on the first joint's axis
            _inertial(body, p.base_mass, [0, -0.02, 0], [2e-5, 4e-5, 2e-5])
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.02, 0.01, 0],
                          quat=_quat(vm.so3_exp([np.pi / 2, 0, 0])))
        elif i <= self.last_arm and L > 1e-9:
            _inertial(body, mass, seg / 2, _rod_inertia(mass, L))
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.006, 0, 0],
                          fromto=np.concatenate([np.zeros(3), seg]))
        elif i < self.n - 1:
            _inertial(body, mass, np.zeros(3), [1e-6, 1e-6, 1e-6])
        else:
            self.stylus(body)

    def stylus(self, body) -> None:
        """The last body: the pen's mass along the stylus, the handle site, the hand."""
        import mujoco

        p, H = self.params, self.H
        z = H[:3, 2]
        com = H[:3, 3] + p.stylus_com * z
        _inertial(body, p.stylus_mass, com, _rod_inertia(p.stylus_mass, 0.12))
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.005, 0, 0],
                      fromto=np.concatenate([H[:3, 3] - 0.09 * z, H[:3, 3] + 0.03 * z]),
                      rgba=[0.2, 0.2, 0.25, 1.0])
        site = body.add_site(name="handle", size=[0.004, 0.004, 0.004])
        _place(site, H)
        # the hand: rigid on the handle, weight carried by the user's arm (gravcomp)
        if self.hand.present:
            hb = body.add_body(name="hand", gravcomp=1.0)
            _place(hb, H)
            _inertial(hb, self.hand.mass_kg, np.zeros(3), np.full(3, self.hand.inertia))

    def actuation(self, spec) -> None:
        """Device joints that are not chain joints as fixed tendons; motors on the actuated
        ones."""
        import mujoco

        p, cp = self.params, self.coupling
        for i in range(self.n):
            trn, target = mujoco.mjtTrn.mjTRN_JOINT, f"s{i}"
            if not self.direct[i]:
                passive = not self.actuated[i]
                tendon = spec.add_tendon(
                    name=f"q{i}",
                    frictionloss=p.passive_friction if passive else p.joint_friction,
                    armature=0.0 if passive else p.armature,
                )
                off = float(cp.Cinv[i] @ cp.c0)
                _limits(tendon, self.lower[i] + off, self.upper[i] + off)
                for k in range(self.n):
                    if cp.Cinv[i, k] != 0.0:
                        tendon.wrap_joint(f"s{k}", float(cp.Cinv[i, k]))
                trn, target = mujoco.mjtTrn.mjTRN_TENDON, f"q{i}"
            if self.actuated[i]:
                lim = float(self.torque_limit[i])
                spec.add_actuator(
                    name=f"m{i}", trntype=trn, target=target, gear=[1, 0, 0, 0, 0, 0],
                    ctrlrange=[-lim, lim], ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
                )


def build_mjcf(
    device,
    params: DeviceModel | None = None,
    hand: HandBody | None = None,
    gravity=(0.0, 0.0, -9.81),
    timestep: float = 2.5e-4,
) -> BuiltModel:
    """The MuJoCo model of any serial-chain `device` (vm.Device, vm.PhantomOmni,
    vm.Planar3R ...): one body per chain joint, motors with torque limits on the actuated
    joints, friction and damping on every joint, link inertias, the hand's mass on the
    handle, and a site at the handle frame. Built with MjSpec from the core's chain."""
    device = _serial(device)
    chain = _ChainModel(device, params or DeviceModel.for_device(device.name), hand or HandBody())
    spec = _spec(device.name, gravity, timestep)
    bodies = chain.bodies(spec)
    chain.actuation(spec)
    return BuiltModel(
        spec=spec,
        coupling=chain.coupling,
        base=chain.B,
        handle=chain.H,
        gravity=np.asarray(gravity, dtype=float),
        timestep=timestep,
        device_bodies=bodies,
    )


def compile_model(built: BuiltModel):
    """The mujoco.MjModel of a built model."""
    return built.spec.compile()


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
