"""The map between a ROS driver's joints and a virtmech device's: an affine map of positions

    r = A q + b        (r: the driver's joint positions by name, q: the device's joints)

its inverse q = A^-1 (r - b), velocities through A alone, and joint efforts through its
transpose (virtual work: tau_q . dq = tau_r . dr for every motion, so tau_q = A^T tau_r and
tau_r = A^-T tau_q).

The default for a PhantomOmni is the Touch's ROS 2 drivers' (the maintained
``Geomagic_Touch_ROS2``, ``omni_state.cpp``): joints ``waist, shoulder, elbow, yaw, pitch,
roll`` in the public Omni URDF's convention, from OpenHaptics' joint angles t and gimbal
angles g (1-based):

    waist = -t1,  shoulder = t2,  elbow = t3 - t2,
    yaw = pi - g1,  pitch = -g2 - 3 pi / 4,  roll = -g3 - pi

The gimbal's zero differs between drivers and devices (docs/devices.md, "Gimbal zero and
offsets"): the offsets b are a calibration, set with the node's parameters. No ROS import
here: the map is plain NumPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["TOUCH_JOINTS", "JointMap", "default_map", "touch_map"]

#: the joint names of the Touch's ROS 2 drivers (the public Omni URDF's joints)
TOUCH_JOINTS = ("waist", "shoulder", "elbow", "yaw", "pitch", "roll")

#: the largest condition number of A taken as invertible
_MAX_CONDITION = 1e12


@dataclass(frozen=True)
class JointMap:
    """r = A q + b between the driver's joints (`names`, in the order of A's rows) and the
    device's (A's columns). Built by `JointMap.checked` (messages naming the parameter)."""

    names: tuple[str, ...]
    matrix: np.ndarray  #: A (n, n)
    offset: np.ndarray  #: b (n,) [rad or m]
    inverse: np.ndarray  #: A^-1 (n, n)

    @classmethod
    def checked(cls, names, matrix, offset, dof: int) -> JointMap:
        """The map for a device of `dof` joints from the parameters joint_names, joint_map (A
        row by row, dof * dof numbers) and joint_offsets (b, dof numbers); a ValueError whose
        message starts with the parameter's name."""
        names = tuple(str(s) for s in names)
        if len(names) != dof:
            raise ValueError(
                f"joint_names: expected {dof} names (the device's joints), got {len(names)}: "
                f"{list(names)}"
            )
        if any(not s.strip() for s in names):
            raise ValueError(f"joint_names: expected non-empty names, got {list(names)}")
        twice = sorted({s for s in names if names.count(s) > 1})
        if twice:
            raise ValueError(f"joint_names: each name once, got {', '.join(twice)} twice")
        A = np.asarray(matrix, dtype=float).ravel()
        if A.size != dof * dof:
            raise ValueError(
                f"joint_map: expected {dof * dof} numbers (a {dof} x {dof} matrix, row by row), "
                f"got {A.size}"
            )
        A = A.reshape(dof, dof)
        if not np.all(np.isfinite(A)):
            raise ValueError("joint_map: expected finite numbers")
        if not np.linalg.cond(A) < _MAX_CONDITION:
            raise ValueError(
                "joint_map: expected an invertible matrix (each device joint recoverable from "
                "the driver's), got a singular one"
            )
        b = np.asarray(offset, dtype=float).ravel()
        if b.size != dof:
            raise ValueError(f"joint_offsets: expected {dof} numbers, got {b.size}")
        if not np.all(np.isfinite(b)):
            raise ValueError("joint_offsets: expected finite numbers")
        inverse = np.linalg.inv(A)
        for a in (A, b, inverse):
            a.setflags(write=False)
        return cls(names, A, b, inverse)

    @property
    def dof(self) -> int:
        return len(self.names)

    # positions and velocities
    def device_positions(self, r) -> np.ndarray:
        """q = A^-1 (r - b)."""
        return self.inverse @ (np.asarray(r, dtype=float) - self.offset)

    def driver_positions(self, q) -> np.ndarray:
        """r = A q + b."""
        return self.matrix @ np.asarray(q, dtype=float) + self.offset

    def device_velocities(self, dr) -> np.ndarray:
        """dq = A^-1 dr."""
        return self.inverse @ np.asarray(dr, dtype=float)

    def driver_velocities(self, dq) -> np.ndarray:
        """dr = A dq."""
        return self.matrix @ np.asarray(dq, dtype=float)

    # efforts (virtual work)
    def driver_efforts(self, tau) -> np.ndarray:
        """tau_r = A^-T tau_q: the driver's joint efforts that do the work of the device's
        torques tau_q [N·m or N]."""
        return self.inverse.T @ np.asarray(tau, dtype=float)

    def device_efforts(self, tau_r) -> np.ndarray:
        """tau_q = A^T tau_r."""
        return self.matrix.T @ np.asarray(tau_r, dtype=float)

    def effort_joints(self, actuated) -> list[int]:
        """The driver's joints (indices into `names`) whose effort can be non-zero when only
        the device's `actuated` joints carry torque: those ros2_control's effort controller
        commands, in order."""
        act = np.asarray(actuated, dtype=bool)
        return [i for i in range(self.dof) if np.any(self.inverse.T[i, act] != 0.0)]

    def to_parameters(self) -> dict:
        """The ROS parameters that give this map."""
        return {
            "joint_names": list(self.names),
            "joint_map": self.matrix.ravel().tolist(),
            "joint_offsets": self.offset.tolist(),
        }


def touch_map() -> JointMap:
    """The Touch's ROS 2 drivers' joints from OpenHaptics' (the module's docstring)."""
    A = np.zeros((6, 6))
    A[0, 0] = -1.0  # waist = -t1
    A[1, 1] = 1.0  # shoulder = t2
    A[2, 1], A[2, 2] = -1.0, 1.0  # elbow = t3 - t2
    A[3, 3] = A[4, 4] = A[5, 5] = -1.0
    b = [0.0, 0.0, 0.0, math.pi, -3.0 * math.pi / 4.0, -math.pi]
    return JointMap.checked(TOUCH_JOINTS, A.ravel(), b, 6)


def default_map(device) -> JointMap:
    """The Touch drivers' map for a six-joint PhantomOmni; otherwise the identity, the
    joints named joint1 .. jointN."""
    if device.name == "PhantomOmni" and device.dof == 6:
        return touch_map()
    n = device.dof
    return JointMap.checked([f"joint{i + 1}" for i in range(n)], np.eye(n).ravel(), np.zeros(n), n)
