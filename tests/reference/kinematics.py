"""Kinematics of the reference: rotations, pose errors, serial chains, and the devices and
mechanisms of the benchmark cases (bench/bench_cases.hpp), written with 4x4 products."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


def rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return c * np.eye(3) + (1.0 - c) * np.outer(axis, axis) + s * K


def pose(R: np.ndarray | None = None, p: Any = (0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = p
    return T


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R (angle in [0, pi]), through the unit quaternion."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    q = np.zeros(3)
    if t > 0.0:
        s = math.sqrt(t + 1.0)
        w = 0.5 * s
        s = 0.5 / s
        q[0] = (R[2, 1] - R[1, 2]) * s
        q[1] = (R[0, 2] - R[2, 0]) * s
        q[2] = (R[1, 0] - R[0, 1]) * s
    else:
        i = 0
        if R[1, 1] > R[0, 0]:
            i = 1
        if R[2, 2] > R[i, i]:
            i = 2
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(R[i, i] - R[j, j] - R[k, k] + 1.0)
        q[i] = 0.5 * s
        s = 0.5 / s
        w = (R[k, j] - R[j, k]) * s
        q[j] = (R[j, i] + R[i, j]) * s
        q[k] = (R[k, i] + R[i, k]) * s
    n = float(np.linalg.norm(q))
    if n < 1e-300:
        return np.zeros(3)
    angle = 2.0 * math.atan2(n, abs(w))
    return (-1.0 if w < 0.0 else 1.0) * angle / n * q


def pose_error(Ta: np.ndarray, Tb: np.ndarray) -> np.ndarray:
    """e = [p_a - p_b; log(R_a R_b^T)]."""
    return np.concatenate([Ta[:3, 3] - Tb[:3, 3], so3_log(Ta[:3, :3] @ Tb[:3, :3].T)])


#: Singular values of sqrt(W) J below this fraction of the largest count as zero (the
#: filters' documented rank tolerance, include/virtmech/filters.hpp).
RANK_TOL = 1e-10


def gram_pinv(J: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, int]:
    """(J^T W J)^+ for diagonal weights w, from the SVD of sqrt(W) J (not from J^T W J,
    which squares the condition number), and the rank of sqrt(W) J."""
    m = J.shape[1]
    if m == 0:
        return np.zeros((0, 0)), 0
    _, s, Vt = np.linalg.svd(np.sqrt(np.maximum(w, 0.0))[:, None] * J, full_matrices=False)
    if not s.size or not s[0] > 0.0:
        return np.zeros((m, m)), 0
    k = int(np.sum(s > RANK_TOL * s[0]))
    V = Vt[:k].T
    return (V / s[:k] ** 2) @ V.T, k


class NpChain:
    """A serial chain: base, joints (type, unit axis, origin), handle; pose and Jacobian."""

    def __init__(self, base: np.ndarray, joints: list[tuple[str, Any, np.ndarray]],
                 handle: np.ndarray, lower: Any = None, upper: Any = None,
                 length_scale: float = 0.1):
        self.base, self.handle = base, handle
        self.types = [j[0] for j in joints]
        self.axes = [np.asarray(j[1], float) / np.linalg.norm(j[1]) for j in joints]
        self.origins = [j[2] for j in joints]
        n = len(joints)
        self.dof = n
        self.lower = np.full(n, -np.inf) if lower is None else np.asarray(lower, float)
        self.upper = np.full(n, np.inf) if upper is None else np.asarray(upper, float)
        self.length_scale = length_scale
        self.home = np.clip(np.zeros(n), self.lower, self.upper)
        #: starting points for a global placement: target pose -> list of joint vectors
        self.seeds: Any = None

    def _motion(self, i: int, x: float) -> np.ndarray:
        if self.types[i] == "revolute":
            return pose(rot(self.axes[i], x))
        return pose(None, x * self.axes[i])

    def forward(self, q: np.ndarray) -> np.ndarray:
        T = self.base
        for i in range(self.dof):
            T = T @ self.origins[i] @ self._motion(i, q[i])
        return T @ self.handle

    def forward_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        T = self.base
        axes = np.empty((self.dof, 3))
        points = np.empty((self.dof, 3))
        for i in range(self.dof):
            T = T @ self.origins[i]
            axes[i] = T[:3, :3] @ self.axes[i]
            points[i] = T[:3, 3]
            T = T @ self._motion(i, q[i])
        T = T @ self.handle
        J = np.zeros((6, self.dof))
        for i in range(self.dof):
            if self.types[i] == "revolute":
                J[:3, i] = np.cross(axes[i], T[:3, 3] - points[i])
                J[3:, i] = axes[i]
            else:
                J[:3, i] = axes[i]
        return T, J


@dataclass
class NpDevice:
    """A chain in serial coordinates s = C q + c0, an actuation mask and limits."""

    chain: NpChain
    C: np.ndarray
    c0: np.ndarray
    actuated: np.ndarray
    torque_limit: np.ndarray

    def forward_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        T, J = self.chain.forward_jacobian(self.C @ q + self.c0)
        return T, J @ self.C


def np_omni(l1: float = 0.13335, l2: float = 0.13335) -> NpDevice:
    ux, uy, uz = np.eye(3)
    joints = [("revolute", -uy, pose(None, [0.0, l2, -l1])),
              ("revolute", -ux, pose()),
              ("revolute", -ux, pose(None, [0.0, 0.0, l1])),
              ("revolute", -uy, pose(None, [0.0, -l2, 0.0])),
              ("revolute", -ux, pose()),
              ("revolute", -uz, pose())]
    chain = NpChain(np.eye(4), joints, pose(rot(ux, math.pi)))
    C = np.eye(6)
    C[2, 1] = -1.0
    return NpDevice(chain, C, np.zeros(6), np.array([True] * 3 + [False] * 3),
                    np.array([0.44, 0.44, 0.44, 0.0, 0.0, 0.0]))


def np_planar3r(l1: float, l2: float, torque_limit: float, max_force: float) -> NpDevice:
    uz = np.array([0.0, 0.0, 1.0])
    joints = [("revolute", uz, pose()), ("revolute", uz, pose(None, [l1, 0, 0])),
              ("revolute", uz, pose(None, [l2, 0, 0]))]
    handle = pose(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    return NpDevice(NpChain(np.eye(4), joints, handle), np.eye(3), np.zeros(3),
                    np.array([True, True, False]), np.array([torque_limit, torque_limit, 0.0]))


def np_arm6() -> NpDevice:
    axes = ([0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0])
    offs = ([0, 0, 0.1], [0, 0, 0.05], [0.25, 0, 0], [0.1, 0, 0], [0.15, 0, 0], [0, 0, 0])
    joints = [("revolute", np.array(a, float), pose(None, o)) for a, o in zip(axes, offs)]
    handle = pose(rot(np.array([0.0, 1.0, 0.0]), math.pi / 2), [0.05, 0, 0])
    chain = NpChain(np.eye(4), joints, handle, np.full(6, -2.5), np.full(6, 2.5))
    return NpDevice(chain, np.eye(6), np.zeros(6), np.ones(6, bool), np.full(6, 20.0))


def _tangent_frame(p: Any, n: np.ndarray, t1: np.ndarray) -> np.ndarray:
    return pose(np.column_stack([t1, np.cross(n, t1), n]), p)


def _any_orthogonal(n: np.ndarray) -> np.ndarray:
    t = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    return t / np.linalg.norm(t)


def _handle_behind_tip(length: float) -> np.ndarray:
    return pose(rot(np.array([1.0, 0.0, 0.0]), math.pi), [0.0, 0.0, length])


def np_probe(point: Any, normal: Any, length: float) -> NpChain:
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    ux, uy, uz = np.eye(3)
    joints = [("prismatic", ux, pose()), ("prismatic", uy, pose()), ("revolute", ux, pose()),
              ("revolute", uy, pose()), ("revolute", uz, pose())]
    chain = NpChain(_tangent_frame(point, n, _any_orthogonal(n)), joints,
                    _handle_behind_tip(length), length_scale=length)
    chain.seeds = lambda T: probe_seeds(chain, length, T)
    return chain


def np_planar_arm(pivot: Any, normal: Any, length: float, zero_direction: Any) -> NpChain:
    n = np.asarray(normal, float)
    d = np.asarray(zero_direction, float)
    Rh = np.empty((3, 3))
    Rh[:, 2] = [-1.0, 0.0, 0.0]
    Rh[:, 1] = [0.0, 0.0, 1.0]
    Rh[:, 0] = np.cross(Rh[:, 1], Rh[:, 2])
    chain = NpChain(_tangent_frame(pivot, n, d), [("revolute", np.array([0.0, 0, 1]), pose())],
                    pose(Rh, [length, 0.0, 0.0]), length_scale=length)
    chain.seeds = lambda T: [np.array([x]) for x in np.linspace(-np.pi, np.pi, 12, endpoint=False)]
    return chain


def np_serial5() -> NpChain:
    joints = [("prismatic" if i < 2 else "revolute", np.eye(3)[i % 3], pose()) for i in range(5)]
    return NpChain(np.eye(4), joints, pose(None, [0.3, 0, 0.2]), length_scale=0.1)


def probe_seeds(m: NpChain, L: float, T: np.ndarray) -> list[np.ndarray]:
    """Starts for the probe's placement: the handle's own orientation with the tip dropped
    onto the plane along the normal (both Euler branches)."""
    B, p0 = m.base[:3, :3], m.base[:3, 3]
    M = B.T @ (T[:3, :3] * np.array([1.0, -1.0, -1.0]))  # Rx(a) Ry(b) Rz(c)
    tip = T[:3, 3] - L * (B @ M[:, 2])
    x, y = B[:, 0] @ (tip - p0), B[:, 1] @ (tip - p0)
    a = math.atan2(-M[1, 2], M[2, 2])
    b = math.atan2(M[0, 2], math.hypot(M[1, 2], M[2, 2]))
    c = math.atan2(-M[0, 1], M[0, 0])
    return [np.array([x, y, a, b, c]),
            np.array([x, y, a + math.pi, math.pi - b, c + math.pi])]


CASES = (
    "omni+probe", "omni+planar_arm", "planar3r+planar_arm", "omni+probe_lifted", "arm6+serial5",
)


def case_models(name: str) -> tuple[NpDevice, NpChain]:
    """The device and mechanism of a benchmark case (bench/bench_cases.hpp)."""
    if name in ("omni+probe", "omni+probe_lifted"):
        point = [0.0, 0.01 if name == "omni+probe" else -0.03, 0.0]
        return np_omni(), np_probe(point, [0, 1, 0], 0.1)
    if name == "omni+planar_arm":
        return np_omni(), np_planar_arm([0.0, 0.0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
    if name == "planar3r+planar_arm":
        return (np_planar3r(0.2, 0.2, 50.0, 100.0),
                np_planar_arm([0.25, 0.0, 0.0], [0, 0, 1], 0.1, [1, 0, 0]))
    if name == "arm6+serial5":
        return np_arm6(), np_serial5()
    raise ValueError(f"case: expected one of {', '.join(CASES)}, got {name!r}")
