"""The scenario format (docs/scenarios.md): one Field per key, with defaults and ranges."""

from __future__ import annotations

from .._core import CONTROLLER_DEFAULTS as _C
from .._core import CartesianDevice as _Cartesian
from .schema import Field

INF = float("inf")


def num(default=None, required=False, min=None, max=None, min_exclusive=False, doc=""):
    kw = {} if default is None else {"default": default}
    return Field(
        "number", required=required, min=min, max=max, min_exclusive=min_exclusive, doc=doc, **kw
    )


def vec(n, default=None, required=False, doc="", nonzero=False):
    kw = {} if default is None else {"default": default}
    return Field("vector", length=n, required=required, doc=doc, nonzero=nonzero, **kw)


def opt_vec(n, doc="", nonzero=False):
    return Field("vector", length=n, doc=doc, nonzero=nonzero)


def direction(default=None, required=False, doc="3 numbers, not all zero"):
    """A direction: 3 finite numbers, not all zero, read as the unit vector x / |x|."""
    if default is None and not required:
        return opt_vec(3, doc, nonzero=True)
    return vec(3, default, required, doc, nonzero=True)


#: a scenario's name is the folder its outputs go to: a plain file name, never a path
SAFE_NAME = r"[A-Za-z0-9_-][A-Za-z0-9._-]*"


DEVICE_PHYSICS = {
    "link_mass": num(min=0, doc="arm link mass [kg]"),
    "base_mass": num(min=0, doc="Omni turret mass [kg]"),
    "armature": num(min=0, doc="motor rotor inertia [kg m^2]"),
    "joint_friction": num(min=0, doc="actuated-joint Coulomb friction [N m]"),
    "joint_damping": num(min=0, doc="actuated-joint damping [N m s/rad]"),
    "passive_friction": num(min=0, doc="passive-joint Coulomb friction [N m]"),
    "passive_damping": num(min=0, doc="passive-joint damping [N m s/rad]"),
    "gimbal_mass": num(min=0, doc="gimbal ring mass [kg]"),
    "stylus_mass": num(min=0, doc="stylus mass [kg]"),
    "stylus_com": num(min=-0.2, max=0.2, doc="stylus centre of mass along the stylus [m]"),
}

#: one joint of a serial-chain device, as vm.Joint takes it (limits: none when omitted)
DEVICE_JOINT = Field(
    "tables",
    required=True,
    children={
        "type": Field("string", required=True, choices=("revolute", "prismatic")),
        "axis": direction(required=True, doc="3 numbers, not all zero, in the joint frame"),
        "origin": vec(3, [0.0, 0.0, 0.0], doc="the joint frame's position in the previous [m]"),
        "origin_rotation": vec(
            3, [0.0, 0.0, 0.0], doc="the joint frame's rotation vector in the previous [rad]"
        ),
        "lower": num(min=-1e3, max=1e3, doc="lower limit [rad or m]; none when omitted"),
        "upper": num(min=-1e3, max=1e3, doc="upper limit [rad or m]; none when omitted"),
    },
)

DEVICE = Field(
    "table",
    required=True,
    variant_key="type",
    variants={
        "PhantomOmni": {
            "l1": num(0.13335, min=0.01, max=1.0),
            "l2": num(0.13335, min=0.01, max=1.0),
            "max_force": num(3.3, min=0, min_exclusive=True, max=100),
            "motor_torque_limit": vec(3, [0.44, 0.44, 0.44]),
            "actuated": Field(
                "vector",
                element=Field("bool"),
                length=6,
                default=[True, True, True, False, False, False],
                doc="6 true or false: which joints have a motor (a fully actuated variant: "
                "all true)",
            ),
            "gimbal_torque_limit": num(
                0.1, min=0, min_exclusive=True, max=10,
                doc="torque limit of a gimbal joint made actuated [N m]",
            ),
            **DEVICE_PHYSICS,
        },
        "Planar3R": {
            "link1": num(0.2, min=0.01, max=2.0),
            "link2": num(0.2, min=0.01, max=2.0),
            "torque_limit": num(1.0, min=0, min_exclusive=True, max=1000),
            "max_force": num(5.0, min=0, min_exclusive=True, max=1000),
            "base_position": vec(3, [0.0, 0.0, 0.0]),
            **DEVICE_PHYSICS,
        },
        "CartesianDevice": {
            "model": Field(
                "string",
                required=True,
                choices=tuple(_Cartesian.MODELS),
                doc="the device model: its coordinates, actuation, workspace and limits",
            ),
            "handle_rotation": vec(
                3,
                [3.141592653589793, 0.0, 0.0],
                doc="the handle frame's rotation vector in the SDK's end-effector frame [rad] "
                "(default: the stylus along its -z)",
            ),
            **DEVICE_PHYSICS,
        },
        "Device": {
            "joints": DEVICE_JOINT,
            "actuated": Field(
                "vector", element=Field("bool"), required=True, doc="one true or false per joint"
            ),
            "torque_limit": Field(
                "vector", required=True, doc="one limit per joint [N m or N]; 0 where passive"
            ),
            "max_force": num(min=0, min_exclusive=True, max=1000, doc="force limit [N]"),
            "handle": vec(3, [0.0, 0.0, 0.0], doc="the handle in the last joint's frame [m]"),
            "handle_rotation": vec(3, [0.0, 0.0, 0.0], doc="its rotation vector [rad]"),
            "base_position": vec(3, [0.0, 0.0, 0.0], doc="the chain's base [m]"),
            "base_rotation": vec(3, [0.0, 0.0, 0.0], doc="its rotation vector [rad]"),
            **DEVICE_PHYSICS,
        },
    },
)

UNILATERAL = Field(
    "bool",
    default=False,
    doc="the tip may lift off toward +normal: the surface pushes but never pulls",
)

#: a surface or curve of a mechanism (docs/geometry.md); NURBS weights default to ones, knots
#: to the clamped uniform vector of the degree
_NURBS_POINT = Field("vector", length=3, doc="3 numbers [m]")
SURFACE = Field(
    "table",
    required=True,
    variant_key="type",
    variants={
        "NurbsSurface": {
            "control_points": Field(
                "vector",
                required=True,
                element=Field("vector", element=_NURBS_POINT),
                doc="nu rows of nv points of 3 numbers [m]",
            ),
            "weights": Field("vector", element=Field("vector"), doc="nu rows of nv numbers > 0"),
            "knots_u": Field("vector", doc="nu + degree_u + 1 numbers (default clamped uniform)"),
            "knots_v": Field("vector", doc="nv + degree_v + 1 numbers (default clamped uniform)"),
            "degree_u": Field("integer", default=3, min=1, max=7),
            "degree_v": Field("integer", default=3, min=1, max=7),
        },
        "Sphere": {
            "center": vec(3, required=True, doc="3 numbers [m]"),
            "radius": num(required=True, min=0, min_exclusive=True, max=10, doc="a number [m]"),
            "axis": direction([0.0, 0.0, 1.0], doc="the poles' direction (keep them unused)"),
        },
        "Cylinder": {
            "point": vec(3, required=True, doc="3 numbers [m]"),
            "direction": direction(required=True),
            "radius": num(required=True, min=0, min_exclusive=True, max=10, doc="a number [m]"),
        },
        "Plane": {
            "point": vec(3, required=True, doc="3 numbers [m]"),
            "normal": direction(required=True),
        },
    },
)

CURVE = Field(
    "table",
    required=True,
    variant_key="type",
    variants={
        "NurbsCurve": {
            "control_points": Field(
                "vector", required=True, element=_NURBS_POINT, doc="n points of 3 numbers [m]"
            ),
            "weights": Field("vector", doc="n numbers > 0 (default ones)"),
            "knots": Field("vector", doc="n + degree + 1 numbers (default clamped uniform)"),
            "degree": Field("integer", default=3, min=1, max=7),
        },
    },
)

MECHANISM = Field(
    "table",
    required=True,
    variant_key="type",
    variants={
        "PlanarArm": {
            "pivot": vec(3, required=True, doc="3 numbers [m]"),
            "normal": direction([0.0, 0.0, 1.0]),
            "length": num(required=True, min=0, min_exclusive=True, max=10, doc="a number [m]"),
            "zero_direction": direction(),
        },
        "PointPivot": {
            "point": vec(3, required=True, doc="3 numbers [m]"),
            "normal": direction([0.0, 0.0, 1.0]),
            "length": num(0.1, min=0, min_exclusive=True, max=10),
            "tangent": direction(),
            "unilateral": UNILATERAL,
            "insertion": Field(
                "bool",
                default=False,
                doc="a trocar: the stylus passes through the point and slides along itself",
            ),
        },
        "Probe": {
            "plane_point": vec(3, required=True, doc="3 numbers [m]"),
            "plane_normal": direction(required=True),
            "length": num(required=True, min=0, min_exclusive=True, max=10, doc="a number [m]"),
            "tangent": direction(),
            "unilateral": UNILATERAL,
        },
        "LineGuide": {
            "point": vec(3, required=True, doc="3 numbers [m]"),
            "direction": direction(required=True),
            "length": num(0.1, min=0, min_exclusive=True, max=10),
            "normal": direction(),
            "unilateral": UNILATERAL,
        },
        "SurfaceProbe": {
            "surface": SURFACE,
            "length": num(0.1, min=0, min_exclusive=True, max=10),
            "unilateral": UNILATERAL,
        },
        "CurveGuide": {
            "curve": CURVE,
            "length": num(0.1, min=0, min_exclusive=True, max=10),
            "normal": direction([0.0, 0.0, 1.0], doc="the side the hand is on"),
        },
        "HandlePath": {
            "curve": CURVE,
            "normal": direction([0.0, 0.0, 1.0]),
            "length_scale": num(0.1, min=0, min_exclusive=True, max=10),
        },
    },
)

#: several mechanisms at once: the [mechanism] is member 0, [[set.members]] the others
#: (docs/scenarios.md); a set of one mechanism is that mechanism's controller alone
SET = Field(
    "table",
    children={
        "members": Field(
            "tables",
            default=[],
            variant_key="type",
            variants=MECHANISM.variants,
            doc="the other mechanisms, as [mechanism] tables",
        ),
        "snap_distance": num(0.005, min=0, min_exclusive=True, max=1.0,
                             doc="a member engages within this distance [m]"),
        "release_distance": num(0.010, min=0, min_exclusive=True, max=1.0,
                                doc="... and lets go beyond this one [m] (>= snap_distance)"),
        "force_rate": num(100.0, min=0, min_exclusive=True, max=1e6,
                          doc="largest change of the force while switching [N/s]"),
        "moment_rate": num(1.0, min=0, min_exclusive=True, max=1e6,
                           doc="largest change of the moment while switching [N m/s]"),
    },
)

CONTROLLER = Field(
    "table",
    children={
        "law": Field(
            "string", default=_C["law"], choices=("auto", "null_space", "under_actuated")
        ),
        "kp": opt_vec(6, "stiffness [N/m x3, N m/rad x3]"),
        "kv": opt_vec(6, "damping [N s/m x3, N m s/rad x3]"),
        "w_a": opt_vec(6),
        "w_e": opt_vec(6),
        "w_e_star": opt_vec(6),
        "error_velocity": Field(
            "string", default=_C["error_velocity"], choices=("relative", "handle")
        ),
        "period_s": num(_C["period_s"], min=1e-5, max=0.1),
        "ramp_time_s": num(_C["ramp_time_s"], min=0, max=10),
        "max_force": num(0.0, min=0, max=1000),
        "max_iterations": Field("integer", default=_C["max_iterations"], min=1, max=1000),
        "passivity": Field(
            "string",
            default=_C["passivity"],
            choices=("energy_tank", "off"),
            doc="energy_tank: eq. 26's range term only as long as the user has put in the "
            "energy it gives (off: the laws as written, the paper's behaviour)",
        ),
        "passivity_max_energy_j": num(
            _C["passivity_max_energy_j"],
            min=0,
            max=1000,
            doc="the most energy the tank holds [J]",
        ),
        "passivity_fade_j": num(
            _C["passivity_fade_j"],
            min=0,
            min_exclusive=True,
            max=1000,
            doc="the range term fades out as the tank falls from 0 to minus this [J]",
        ),
    },
)

PHYSICS = Field(
    "table",
    children={
        "rate_hz": num(4000.0, min=100, max=100000, doc="physics steps per second"),
        "gravity": Field("bool", default=True),
        "gravity_compensation": Field("bool", default=True),
    },
)

SENSORS = Field(
    "table",
    children={
        "counts_per_rev": Field("integer", default=15000, min=0, max=10**9),
        "noise_rad": num(0.0, min=0, max=1),
        "delay_cycles": Field("integer", default=0, min=0, max=1000),
        "dropout_probability": num(
            0.0,
            min=0,
            max=1,
        ),
        "velocity_cutoff_hz": num(100.0, min=0, max=1e6),
    },
)

INITIAL = Field(
    "table",
    children={
        "theta": num(0.0, min=-100, max=100, doc="mechanism joint value giving the start pose"),
        "offset": vec(3, [0.0, 0.0, 0.0]),
        "stylus_theta": num(min=-100, max=100),
        "q": Field("vector"),
    },
)

HUMAN = Field(
    "table",
    children={
        "mass_kg": num(0.2, min=0.001, max=5),
        "damping": num(5.0, min=0, max=100),
        "stiffness": num(200.0, min=0, max=5000),
        "inertia": num(2e-4, min=1e-7, max=1),
        "rot_damping": num(0.01, min=0, max=10),
        "rot_stiffness": num(1.0, min=0, max=100),
        "grip_contacts": Field("vector", length=2, default=[-0.015, -0.05]),
    },
)

_MODE = ("passive", "hold")
_PUSH = {
    "force": opt_vec(3, "3 numbers [N]"),
    "moment": opt_vec(3, "3 numbers [N m]"),
    "force_frame": Field(
        "string", default="world", choices=("world", "handle"),
        doc="the axes of force and moment",
    ),
    "ramp_s": num(0.1, min=0, max=10, doc="a number [s] >= 0"),
}
_COMMON = {
    "start_s": num(required=True, min=0, doc="a number [s] >= 0"),
    "duration_s": num(required=True, min=0, doc="a number [s] >= 0"),
    "translation": Field("string", choices=_MODE),
    "orientation": Field("string", choices=_MODE + ("path",)),
    "stiffness": num(min=0, max=5000),
    "rot_stiffness": num(min=0, max=100),
    **_PUSH,
}
_AXIS = Field("axis", default="normal", choices=("normal", "stylus"))
_OSCILLATION = {
    **_COMMON,
    "axis": _AXIS,
    "amplitude_m": num(min=0, max=1, doc="a number [m] >= 0 (translation along axis)"),
    "amplitude_deg": num(min=-360, max=360, doc="a number [deg] (rotation about axis)"),
}
#: a sine's or chirp's highest frequency [Hz] (the control rate's Nyquist frequency is
#: checked against controller.period_s when the file is read)
_FREQ = {"min": 0, "max": 1e4}
INTENT = Field(
    "tables",
    default=[],
    variant_key="action",
    variants={
        "hold": dict(_COMMON),
        "follow": {
            **_COMMON,
            # required with profile = "min_jerk", not allowed with "constant" (checked with
            # the profile when the file is read)
            "duration_s": num(min=0, doc="a number [s] >= 0"),
            "theta": Field("vector", length=2),
            "offsets": Field("vector", min_length=1, element=Field("vector", length=3)),
            "profile": Field("string", default="min_jerk", choices=("min_jerk", "constant")),
            "speed_m_s": num(
                min=0, min_exclusive=True, max=10, doc="a number [m/s] > 0 (profile constant)"
            ),
        },
        "twist": {
            **_COMMON,
            "angle_deg": num(required=True, min=-720, max=720, doc="a number [deg]"),
            "axis": _AXIS,
        },
        "resist": {
            **_COMMON,
            "angle_deg": num(required=True, min=-720, max=720, doc="a number [deg]"),
            "axis": _AXIS,
        },
        "push": {**_COMMON, "force": vec(3, required=True, doc="3 numbers [N]")},
        "sine": {
            **_OSCILLATION,
            "frequency_hz": num(required=True, min_exclusive=True, doc="a number [Hz] > 0",
                                **_FREQ),
        },
        "chirp": {
            **_OSCILLATION,
            "f0_hz": num(required=True, doc="a number [Hz] >= 0", **_FREQ),
            "f1_hz": num(required=True, doc="a number [Hz] >= 0", **_FREQ),
        },
        "wrench": {
            "start_s": num(required=True, min=0, doc="a number [s] >= 0"),
            "duration_s": num(required=True, min=0, doc="a number [s] >= 0"),
            **_PUSH,
        },
        "release": {"start_s": num(required=True, min=0, doc="a number [s] >= 0")},
    },
)

CHECKS = Field(
    "table",
    children={
        "settle_s": num(min=0),
        "reach_s": num(min=0),
        "max_distance_m": num(min=0),
        "max_lag_deg": num(min=0),
        "perpendicular_deg": num(min=0),
        "min_free_deg": num(min=0),
        "min_travel_deg": num(min=0),
        "min_force_n": num(min=0),
    },
)

SCENARIO = Field(
    "table",
    children={
        "name": Field(
            "string",
            required=True,
            pattern=SAFE_NAME,
            doc="a plain file name (letters, digits, '-', '_', '.'; not starting with '.'): "
            "the name of the run's output folder",
        ),
        "description": Field("string", default=""),
        "duration_s": num(
            required=True, min=0, min_exclusive=True, max=3600, doc="a number [s] > 0"
        ),
        "seed": Field("integer", default=0, min=0, max=2**63 - 1),
        "device": DEVICE,
        "mechanism": MECHANISM,
        "controller": CONTROLLER,
        "physics": PHYSICS,
        "sensors": SENSORS,
        "set": SET,
        "initial": INITIAL,
        "human": HUMAN,
        "intent": INTENT,
        "checks": CHECKS,
    },
)
