"""virtmech: haptic devices, fully or under-actuated, rendered as virtual mechanisms.

Implements Luecke & Beckman, "Haptic Interactions With Under-Actuated Robots Using Virtual
Mechanisms", in its general six-degree-of-freedom form. The servo cycle runs in C++
(``virtmech._core``); this package re-exports it and adds the simulation, scenarios,
figures and CLI (imported lazily, so ``import virtmech`` stays fast).

Conventions (docs/theory.md): SI units; poses are (4, 4) homogeneous transforms; Jacobians
are (6, n) with rows [v; w] in world axes; pose error e = [p_a - p_b; log(R_a R_b^T)].
"""

from . import status
from ._core import (
    CONTROLLER_DEFAULTS,
    MAX_DOF,
    MAX_NURBS_DEGREE,
    ChainMechanism,
    Controller,
    Curve,
    CycleOutput,
    Cylinder,
    Device,
    DeviceBase,
    Joint,
    LineGuide,
    Mechanism,
    NurbsCurve,
    NurbsSurface,
    PhantomOmni,
    Planar3R,
    PlanarArm,
    Plane,
    PointPivot,
    Probe,
    SerialChain,
    Sphere,
    Surface,
    TrackResult,
    __version__,
    null_filter,
    pose_error,
    range_filter,
    so3_exp,
    so3_log,
    track,
)

__all__ = [
    "CONTROLLER_DEFAULTS",
    "MAX_DOF",
    "MAX_NURBS_DEGREE",
    "Controller",
    "ChainMechanism",
    "Curve",
    "CycleOutput",
    "Cylinder",
    "Device",
    "DeviceBase",
    "Joint",
    "LineGuide",
    "Mechanism",
    "NurbsCurve",
    "NurbsSurface",
    "PhantomOmni",
    "Plane",
    "Planar3R",
    "PlanarArm",
    "PointPivot",
    "Probe",
    "SerialChain",
    "Sphere",
    "Surface",
    "TrackResult",
    "__version__",
    "null_filter",
    "pose_error",
    "range_filter",
    "so3_exp",
    "so3_log",
    "status",
    "track",
]
