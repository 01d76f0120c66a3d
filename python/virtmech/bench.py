"""``virtmech bench``: how fast the servo cycle is, measured side by side in one run.

For each benchmark case (a device and a mechanism, driven along a fixed joint trajectory):

- the C++ cycle's per-cycle latency (median, p99, p99.9, worst) and the heap allocations it
  made, from the harness ``virtmech_cycle_bench`` installed with the package (a counting
  ``operator new`` and, on glibc, a counting ``malloc``: real counts, not assumptions);
- ``Controller.step`` called from Python over the same trajectory (median per call), so the
  binding's own cost is the difference;
- a straightforward NumPy implementation of the same cycle (same mathematics: chain
  kinematics, weighted Gauss-Newton placements with the same step rules and the same number
  of iterations as the C++ took in that cycle, or to convergence where the C++ placed in
  closed form; the probe's closed form; pseudo-inverse filters, projection, safety),
  checked to give the same torques;

and, when the simulation is installed, the closed-loop simulation's real-time factor for
every shipped scenario. The trajectory and the cases are those of ``bench/bench_cases.hpp``.

Timing figures are reports, not assertions: they depend on the machine and its load, which
the output describes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

CASES = (
    "omni+probe", "omni+planar_arm", "planar3r+planar_arm", "omni+probe_lifted", "arm6+serial5",
)

#: Default number of timed C++ cycles per case (issue 4 asks for at least 1e6).
DEFAULT_CYCLES = 1_000_000
#: Default number of Python ``step`` calls and NumPy baseline cycles per case.
DEFAULT_PYTHON_CYCLES = 20_000
DEFAULT_NUMPY_CYCLES = 1_000
#: Untimed cycles before timing (the first cycle's initial placement, caches); as the harness.
WARMUP = 2000


# ---------------------------------------------------------------------------------------
# the benchmark cases (bench/bench_cases.hpp)


@dataclass
class Case:
    """A controller, its device's joint trajectory and the NumPy model of the same cycle."""

    name: str
    controller: Any
    center: np.ndarray
    amplitude: np.ndarray
    numpy_device: NpDevice
    numpy_mechanism: NpChain

    def joint_state(self, k: np.ndarray | int, period_s: float) -> tuple[np.ndarray, np.ndarray]:
        """q, dq at cycles k: q_i = c_i + a_i sin(w_i t + i), w_i = 1 + 0.37 i [rad/s]."""
        t = np.asarray(k, dtype=float)[..., None] * period_s
        i = np.arange(self.center.size, dtype=float)
        w = 1.0 + 0.37 * i
        q = self.center + self.amplitude * np.sin(w * t + i)
        dq = self.amplitude * w * np.cos(w * t + i)
        return q, dq


def _arm6_joints(vm: Any) -> tuple[list[Any], np.ndarray]:
    axes = ([0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0])
    offs = ([0, 0, 0.1], [0, 0, 0.05], [0.25, 0, 0], [0.1, 0, 0], [0.15, 0, 0], [0, 0, 0])
    joints = [vm.Joint("revolute", a, o, -2.5, 2.5) for a, o in zip(axes, offs)]
    handle = np.eye(4)
    handle[:3, 3] = [0.05, 0, 0]
    handle[:3, :3] = _rot(np.array([0.0, 1.0, 0.0]), math.pi / 2)
    return joints, handle


def make_case(name: str) -> Case:
    """Builds one benchmark case (the same as the C++ harness's)."""
    import virtmech as vm

    omni_center = np.array([0.0, 0.5, 0.3, 0.0, 0.8, 0.0])
    omni_amplitude = np.array([0.3, 0.2, 0.2, 0.4, 0.3, 0.5])
    if name in ("omni+probe", "omni+probe_lifted"):
        # table 1 cm above the handle's zero height (in reach), or 3 cm below (a stress case:
        # the handle is lifted beyond the probe's reach half the time)
        point = [0.0, 0.01 if name == "omni+probe" else -0.03, 0.0]
        dev = vm.PhantomOmni()
        mech = vm.Probe(point, [0, 1, 0], 0.1)
        return Case(name, vm.Controller(dev, mech), omni_center, omni_amplitude,
                    np_omni(), np_probe(point, [0, 1, 0], 0.1))
    if name == "omni+planar_arm":
        dev = vm.PhantomOmni()
        mech = vm.PlanarArm([0.0, 0.0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
        return Case(name, vm.Controller(dev, mech), omni_center, omni_amplitude,
                    np_omni(), np_planar_arm([0.0, 0.0, -0.05], [0, 0, 1], 0.05, [1, 0, 0]))
    if name == "planar3r+planar_arm":
        dev = vm.Planar3R(0.2, 0.2, torque_limit=50.0, max_force=100.0)
        mech = vm.PlanarArm([0.25, 0.0, 0.0], [0, 0, 1], 0.1, [1, 0, 0])
        return Case(name, vm.Controller(dev, mech), np.array([-0.5, 1.6, 0.5]),
                    np.array([0.2, 0.2, 0.3]), np_planar3r(0.2, 0.2, 50.0, 100.0),
                    np_planar_arm([0.25, 0.0, 0.0], [0, 0, 1], 0.1, [1, 0, 0]))
    if name == "arm6+serial5":
        joints, handle = _arm6_joints(vm)
        dev = vm.Device(joints, [True] * 6, handle=handle, torque_limit=[20.0] * 6,
                        max_force=40.0, max_torque=4.0, stiffness=800.0, damping=2.0)
        sj = [vm.Joint("prismatic" if i < 2 else "revolute", np.eye(3)[i % 3]) for i in range(5)]
        sh = np.eye(4)
        sh[:3, 3] = [0.3, 0, 0.2]
        mech = vm.SerialChain(sj, handle=sh, length_scale=0.1)
        return Case(name, vm.Controller(dev, mech), np.full(6, 0.3), np.full(6, 0.4),
                    np_arm6(), np_serial5())
    raise ValueError(f"case: expected one of {', '.join(CASES)}, got {name!r}")


# ---------------------------------------------------------------------------------------
# the NumPy baseline: the same cycle, written the obvious way


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return c * np.eye(3) + (1.0 - c) * np.outer(axis, axis) + s * K


def _pose(R: np.ndarray | None = None, p: Any = (0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = p
    return T


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R, through the quaternion (as the core)."""
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


def symmetric_pinv(A: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Pseudo-inverse of a symmetric PSD matrix by eigen-decomposition (relative cut)."""
    if A.size == 0:
        return A.copy()
    lam, V = np.linalg.eigh(A)
    lmax = np.abs(lam).max()
    if not lmax > 0.0:
        return np.zeros_like(A)
    keep = lam > tol * lmax
    return (V[:, keep] / lam[keep]) @ V[:, keep].T


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
        #: closed-form placement (target, W, start) -> theta or None, where the core has one
        self.place: Any = None

    def _motion(self, i: int, x: float) -> np.ndarray:
        if self.types[i] == "revolute":
            return _pose(_rot(self.axes[i], x))
        return _pose(None, x * self.axes[i])

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
    joints = [("revolute", -uy, _pose(None, [0.0, l2, -l1])),
              ("revolute", -ux, _pose()),
              ("revolute", -ux, _pose(None, [0.0, 0.0, l1])),
              ("revolute", -uy, _pose(None, [0.0, -l2, 0.0])),
              ("revolute", -ux, _pose()),
              ("revolute", -uz, _pose())]
    chain = NpChain(np.eye(4), joints, _pose(_rot(ux, math.pi)))
    C = np.eye(6)
    C[2, 1] = -1.0
    return NpDevice(chain, C, np.zeros(6), np.array([True] * 3 + [False] * 3),
                    np.array([0.44, 0.44, 0.44, 0.0, 0.0, 0.0]))


def np_planar3r(l1: float, l2: float, torque_limit: float, max_force: float) -> NpDevice:
    uz = np.array([0.0, 0.0, 1.0])
    joints = [("revolute", uz, _pose()), ("revolute", uz, _pose(None, [l1, 0, 0])),
              ("revolute", uz, _pose(None, [l2, 0, 0]))]
    handle = _pose(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    return NpDevice(NpChain(np.eye(4), joints, handle), np.eye(3), np.zeros(3),
                    np.array([True, True, False]), np.array([torque_limit, torque_limit, 0.0]))


def np_arm6() -> NpDevice:
    axes = ([0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0])
    offs = ([0, 0, 0.1], [0, 0, 0.05], [0.25, 0, 0], [0.1, 0, 0], [0.15, 0, 0], [0, 0, 0])
    joints = [("revolute", np.array(a, float), _pose(None, o)) for a, o in zip(axes, offs)]
    handle = _pose(_rot(np.array([0.0, 1.0, 0.0]), math.pi / 2), [0.05, 0, 0])
    chain = NpChain(np.eye(4), joints, handle, np.full(6, -2.5), np.full(6, 2.5))
    return NpDevice(chain, np.eye(6), np.zeros(6), np.ones(6, bool), np.full(6, 20.0))


def _tangent_frame(p: Any, n: np.ndarray, t1: np.ndarray) -> np.ndarray:
    return _pose(np.column_stack([t1, np.cross(n, t1), n]), p)


def _any_orthogonal(n: np.ndarray) -> np.ndarray:
    t = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    return t / np.linalg.norm(t)


def _handle_behind_tip(length: float) -> np.ndarray:
    return _pose(_rot(np.array([1.0, 0.0, 0.0]), math.pi), [0.0, 0.0, length])


def np_probe(point: Any, normal: Any, length: float) -> NpChain:
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    ux, uy, uz = np.eye(3)
    joints = [("prismatic", ux, _pose()), ("prismatic", uy, _pose()), ("revolute", ux, _pose()),
              ("revolute", uy, _pose()), ("revolute", uz, _pose())]
    chain = NpChain(_tangent_frame(point, n, _any_orthogonal(n)), joints,
                    _handle_behind_tip(length), length_scale=length)
    chain.place = lambda T, W, start: np_probe_place(chain, length, T, W, start)
    return chain


def _bracketed_newton(derivatives: Any, lo: float, hi: float, x: float) -> float:
    """The root of f' in [lo, hi] where f' runs from - to +, from x inside: Newton steps kept
    in the shrinking bracket, bisection where they would leave it (as the core)."""
    x = min(max(x, lo + 1e-3 * (hi - lo)), hi - 1e-3 * (hi - lo))
    for _ in range(100):
        f1, f2 = derivatives(x)
        if f1 < 0.0:
            lo = x
        elif f1 > 0.0:
            hi = x
        else:
            return x
        nxt = x - f1 / f2 if f2 > 0.0 else 0.5 * (lo + hi)
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - x) <= 1e-16 * (1.0 + abs(x)) or hi - lo <= 4e-16 * (1.0 + abs(hi)):
            return nxt
        x = nxt
    return x


def np_probe_place(m: NpChain, L: float, T: np.ndarray, W: np.ndarray,
                   start: np.ndarray) -> np.ndarray | None:
    """The probe's weighted optimum in closed form (docs/theory.md, section 4): the stylus's
    angle phi from the normal minimises wp (d - L cos phi)^2 + wr (phi - phi_r)^2, the
    orientation is the handle's turned toward the normal, the tip below the handle."""
    if not (W[0] == W[1] == W[2] and W[3] == W[4] == W[5]):
        return None
    wp, wr = W[0], W[3]
    B, p0 = m.base[:3, :3], m.base[:3, 3]
    n = B[:, 2]
    d = float(n @ (T[:3, 3] - p0))
    u_r = -T[:3, 2]
    phi_r = math.atan2(float(np.linalg.norm(np.cross(u_r, n))), float(u_r @ n))
    phi0 = math.acos(min(1.0, max(-1.0, d / L)))
    phi = phi_r
    if phi0 != phi_r and wp > 0.0:
        lo, hi = min(phi0, phi_r), max(phi0, phi_r)
        c0, s0 = math.cos(phi0), math.sin(phi0)  # quadratic models' minimiser
        cp = max(0.0, wp * (2.0 * L * L * s0 * s0 - (2.0 * L * L * c0 - 2.0 * d * L) * c0))
        phi = (cp * phi0 + 2.0 * wr * phi_r) / (cp + 2.0 * wr)

        def derivatives(x: float) -> tuple[float, float]:
            c, s_ = math.cos(x), math.sin(x)
            dc = 2.0 * L * L * c - 2.0 * d * L
            return (wp * (-dc * s_) + 2.0 * wr * (x - phi_r),
                    wp * (2.0 * L * L * s_ * s_ - dc * c) + 2.0 * wr)

        phi = _bracketed_newton(derivatives, lo, hi, phi)
    R = T[:3, :3]
    if phi != phi_r:
        k = np.cross(u_r, n)
        if np.linalg.norm(k) < 1e-12:  # along the normal: tilt as the start does
            sa, ca, sb, cb = math.sin(start[2]), math.cos(start[2]), math.sin(start[3]), \
                math.cos(start[3])
            h = B @ np.array([sb, -sa * cb, ca * cb])
            h = h - (h @ n) * n
            if np.linalg.norm(h) < 1e-12:
                h = _any_orthogonal(n)
            R = _rot(np.cross(u_r, h) / np.linalg.norm(np.cross(u_r, h)), abs(phi - phi_r)) @ R
        else:
            R = _rot(k / np.linalg.norm(k), phi_r - phi) @ R
    tip = T[:3, 3] + L * R[:, 2]
    tip = tip - float(n @ (tip - p0)) * n
    M = B.T @ (R * np.array([1.0, -1.0, -1.0]))  # R_tip = R Rx(pi); M = Rx(a) Ry(b) Rz(c)
    e1 = np.array([math.atan2(-M[1, 2], M[2, 2]),
                   math.atan2(M[0, 2], math.hypot(M[1, 2], M[2, 2])),
                   math.atan2(-M[0, 1], M[0, 0])])
    e2 = np.array([e1[0] + math.pi, math.pi - e1[1], e1[2] + math.pi])
    ref = start[2:5]
    e1 = e1 + 2 * math.pi * np.round((ref - e1) / (2 * math.pi))
    e2 = e2 + 2 * math.pi * np.round((ref - e2) / (2 * math.pi))
    abc = e1 if np.sum((e1 - ref) ** 2) <= np.sum((e2 - ref) ** 2) else e2
    return np.r_[B[:, 0] @ (tip - p0), B[:, 1] @ (tip - p0), abc]


def np_planar_arm(pivot: Any, normal: Any, length: float, zero_direction: Any) -> NpChain:
    n = np.asarray(normal, float)
    d = np.asarray(zero_direction, float)
    Rh = np.empty((3, 3))
    Rh[:, 2] = [-1.0, 0.0, 0.0]
    Rh[:, 1] = [0.0, 0.0, 1.0]
    Rh[:, 0] = np.cross(Rh[:, 1], Rh[:, 2])
    chain = NpChain(_tangent_frame(pivot, n, d), [("revolute", np.array([0.0, 0, 1]), _pose())],
                    _pose(Rh, [length, 0.0, 0.0]), length_scale=length)
    chain.place = lambda T, W, start: np_planar_arm_place(chain, length, T, W, start)
    return chain


def np_planar_arm_place(m: NpChain, L: float, T: np.ndarray, W: np.ndarray,
                        start: np.ndarray) -> np.ndarray | None:
    """The arm's weighted optimum (docs/theory.md, section 4): on the short arc between the
    angle of the handle's position and that of its orientation, where
    -a cos(x - tp) + wr acos(c + b cos(x - to))^2 is least."""
    if not (W[0] == W[1] == W[2] and W[3] == W[4] == W[5]):
        return None
    wp, wr = W[0], W[3]
    B, p0 = m.base[:3, :3], m.base[:3, 3]
    d, t2, n = B[:, 0], B[:, 1], B[:, 2]
    v = T[:3, 3] - p0
    tp = math.atan2(float(v @ t2), float(v @ d))
    a = 2.0 * wp * L * math.hypot(float(v @ d), float(v @ t2))
    M = m.forward(np.zeros(1))[:3, :3] @ T[:3, :3].T
    nMn = float(n @ M @ n)
    K = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    A_, B_ = np.trace(M) - nMn, float(np.trace(K @ M))
    b, to, c = 0.5 * math.hypot(A_, B_), math.atan2(B_, A_), 0.5 * (nMn - 1.0)
    span = math.remainder(to - tp, 2 * math.pi)
    if not a > 0.0 or span == 0.0:
        x = to
    elif not (wr > 0.0 and b > 0.0):
        x = tp
    else:
        sgn = 1.0 if span > 0 else -1.0
        lo, hi, u = 0.0, abs(span), abs(span) * 2.0 * wr * b / (a + 2.0 * wr * b)

        def derivatives(t: float) -> tuple[float, float]:
            xx = tp + sgn * t
            y = min(1.0, max(-1.0, c + b * math.cos(xx - to)))
            s1 = math.sqrt(max(0.0, 1.0 - y * y))
            ang = math.atan2(s1, y)
            h = ang / s1 if ang > 1e-8 else 1.0 + ang * ang / 6.0
            dh = (ang * y - s1) / s1 ** 3 if ang > 1e-4 else -1.0 / 3.0
            y1, y2 = -b * math.sin(xx - to), -b * math.cos(xx - to)
            return (sgn * (a * math.sin(xx - tp) - 2.0 * wr * h * y1),
                    a * math.cos(xx - tp) - 2.0 * wr * (dh * y1 * y1 + h * y2))

        u = _bracketed_newton(derivatives, lo, hi, u)
        x = tp + sgn * u
    return np.array([x + 2 * math.pi * round((start[0] - x) / (2 * math.pi))])


def np_serial5() -> NpChain:
    joints = [("prismatic" if i < 2 else "revolute", np.eye(3)[i % 3], _pose()) for i in range(5)]
    return NpChain(np.eye(4), joints, _pose(None, [0.3, 0, 0.2]), length_scale=0.1)


def np_warm_start(m: NpChain, theta: np.ndarray, theta_prev: np.ndarray) -> np.ndarray:
    """theta moved on by its last change if that is within a tenth of the step cap."""
    cap = np.array([0.5 if t == "revolute" else 0.5 * m.length_scale for t in m.types])
    change = theta - theta_prev
    return theta + change if np.all(np.abs(change) <= 0.1 * cap) else theta


def np_track(m: NpChain, target: np.ndarray, theta0: np.ndarray, W: np.ndarray,
             iterations: int) -> tuple[np.ndarray, int, bool]:
    """Weighted, damped Gauss-Newton placement (eqs. 18-20) with the core's step rules,
    stopped after `iterations` iterations or at the core's tolerances. Returns theta, the
    iterations done and whether a tolerance was met."""
    if m.place is not None:
        placed = m.place(target, W, theta0)
        if placed is not None:
            return placed, 0, True
    if iterations == 0:  # the core placed in closed form: Gauss-Newton to the same optimum
        iterations = 50
    theta = np.clip(theta0, m.lower, m.upper)
    cap = np.array([0.5 if t == "revolute" else 0.5 * m.length_scale for t in m.types])
    n = m.dof

    def evaluate(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        T, J = m.forward_jacobian(th)
        e = pose_error(target, T)
        We = W * e
        return J, J.T @ We, float(e @ We)

    def cost_at(th: np.ndarray) -> float:
        e = pose_error(target, m.forward(th))
        return float(e @ (W * e))

    J, g, cost = evaluate(theta)
    done, converged = 0, False
    for it in range(iterations):
        if np.abs(g).max() <= 1e-14:
            converged = True
            break
        H = J.T @ (W[:, None] * J)
        H[np.diag_indices(n)] += 1e-12 * (np.trace(H) / n) + 1e-300
        delta = np.linalg.solve(H, g)
        ratio = np.abs(delta) / cap
        scale = min(1.0, 1.0 / ratio.max()) if ratio.max() > 1.0 else 1.0
        delta = delta * scale
        done = it + 1
        slope0 = float(g @ delta)
        if scale == 1.0 and (np.abs(delta) / cap).max() < 1e-4:
            trial = np.clip(theta + delta, m.lower, m.upper)
            tJ, tg, tcost = evaluate(trial)
            slope1 = float(tg @ delta)
            if slope0 > 0.0 and slope1 < 0.0:
                trial = np.clip(theta + (slope0 / (slope0 - slope1)) * delta, m.lower, m.upper)
                tJ, tg, tcost = evaluate(trial)
            elif slope0 > 0.0 and 0.1 * slope0 <= slope1 <= 0.8 * slope0:
                # linear convergence: secant extrapolation along delta, kept if it helped
                x = np.clip(theta + (slope0 / (slope0 - slope1)) * delta, m.lower, m.upper)
                xJ, xg, xcost = evaluate(x)
                if abs(float(xg @ delta)) < slope1:
                    trial, tJ, tg, tcost = x, xJ, xg, xcost
        else:
            alpha, accepted = 1.0, False
            for _ in range(10):
                trial = np.clip(theta + alpha * delta, m.lower, m.upper)
                if cost_at(trial) <= cost:
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                converged = True
                break
            tJ, tg, tcost = evaluate(trial)
        moved = np.abs(trial - theta).max()
        theta, J, g, cost = trial, tJ, tg, tcost
        if moved <= 1e-12:
            converged = True
            break
    return theta, done, converged or bool(np.abs(g).max() <= 1e-14)


class NpController:
    """The cycle of controller.cpp in NumPy, configured from a core Controller's model."""

    def __init__(self, controller: Any, device: NpDevice, mechanism: NpChain):
        md = controller.model
        self.dev, self.mech = device, mechanism
        self.kp, self.kv = np.asarray(md["kp"]), np.asarray(md["kv"])
        self.w_a = np.asarray(md["w_a"])
        L = md["length_scale"]
        U = np.array([1.0, 1.0, 1.0, L * L, L * L, L * L])
        self.w_e = np.asarray(md["w_e"]) + 1e-6 * U
        self.w_e_star = np.asarray(md["w_e_star"]) + 1e-6 * U
        self.L = L
        self.under_actuated = bool(md["under_actuated_term"])
        self.relative = md["error_velocity"] == "relative"
        self.ramp_cycles = int(md["ramp_cycles"])
        self.max_force, self.max_torque = md["max_force"], md["max_torque"]
        self.theta = mechanism.home.copy()
        self.theta_star = mechanism.home.copy()
        self.theta_prev = self.theta.copy()
        self.theta_star_prev = self.theta.copy()
        # [this cycle's placement converged, it and the one before converged]
        self.settled = [False, False]
        self.settled_star = [False, False]
        self.first = True
        self.ramp_count = 0

    def _rate(self, J: np.ndarray, W: np.ndarray, v: np.ndarray) -> np.ndarray:
        if not self.relative:
            return -v
        WJ = W[:, None] * J
        theta_dot = symmetric_pinv(J.T @ WJ) @ (WJ.T @ v)
        return J @ theta_dot - v

    def step(self, q: np.ndarray, dq: np.ndarray, iterations: int,
             iterations_star: int) -> np.ndarray:
        """One cycle; iterations: the placements' iteration budgets. Returns the torques."""
        dev, mech = self.dev, self.mech
        T_R, J_R = dev.forward_jacobian(q)
        v_R = J_R @ dq
        # warm start: the last placement moved on by its last change, if both converged
        start = (np_warm_start(mech, self.theta, self.theta_prev)
                 if not self.first and self.settled[1] else self.theta)
        theta, _, converged = np_track(mech, T_R, start, self.w_e, iterations)
        self.settled = [converged, converged and self.settled[0] and not self.first]
        self.theta_prev = theta if self.first else self.theta
        self.theta = theta
        T_V, J_V = mech.forward_jacobian(self.theta)
        e = pose_error(T_V, T_R)
        F = self.kp * e + self.kv * self._rate(J_V, self.w_e, v_R)
        WJ_A = self.w_a[:, None] * J_V
        H_Ap = symmetric_pinv(J_V.T @ WJ_A)
        f = F - WJ_A @ (H_Ap @ (J_V.T @ F))
        if self.under_actuated:
            if self.first:
                self.theta_star = self.theta.copy()
            start = (np_warm_start(mech, self.theta_star, self.theta_star_prev)
                     if not self.first and self.settled_star[1] else self.theta_star)
            theta, _, converged = np_track(mech, T_R, start, self.w_e_star, iterations_star)
            self.settled_star = [converged,
                                 converged and self.settled_star[0] and not self.first]
            self.theta_star_prev = theta if self.first else self.theta_star
            self.theta_star = theta
            T_s, J_s = mech.forward_jacobian(self.theta_star)
            e_s = pose_error(T_s, T_R)
            Fs = self.kp * e_s + self.kv * self._rate(J_s, self.w_e_star, v_R)
            # P at the nearest placement, or at the un-powered one where the nearest is
            # singular and that one is not (docs/theory.md, section 6)
            sw = np.sqrt(self.w_a)[:, None]

            def rank(J: np.ndarray) -> int:
                return int(np.linalg.matrix_rank(sw * J, tol=1e-10 * max(np.abs(sw * J).max(),
                                                                         1e-300)))

            rank_v = rank(J_V)
            if rank_v < min(int((self.w_a > 0).sum()), mech.dof):
                rank_s = rank(J_s)
                if rank_s > rank_v:
                    WJ_s = self.w_a[:, None] * J_s
                    f = f + WJ_s @ (symmetric_pinv(J_s.T @ WJ_s) @ (J_s.T @ Fs))
                    Fs = None
            if Fs is not None:
                f = f + WJ_A @ (H_Ap @ (J_V.T @ Fs))
        else:
            self.theta_star = self.theta.copy()
        self.first = False
        passive = ~dev.actuated
        if passive.any():
            Jp = J_R[:, passive].copy()
            Jp[3:] *= self.L
            y = symmetric_pinv(Jp.T @ Jp) @ (J_R[:, passive].T @ f)
            delta = Jp @ y
            delta[3:] *= self.L
            f = f - delta
        scale = 1.0
        fn, mn = np.linalg.norm(f[:3]), np.linalg.norm(f[3:])
        if fn > self.max_force:
            scale = min(scale, self.max_force / fn)
        if mn > self.max_torque:
            scale = min(scale, self.max_torque / mn)
        ramp = min(1.0, (self.ramp_count + 1) / self.ramp_cycles)
        if self.ramp_count < self.ramp_cycles:
            self.ramp_count += 1
        f = f * (scale * ramp)
        tau = J_R.T @ f
        tau[passive] = 0.0
        a = np.abs(tau)
        over = dev.actuated & (a > dev.torque_limit)
        if over.any():
            tau = tau * (dev.torque_limit[over] / a[over]).min()
        return tau


# ---------------------------------------------------------------------------------------
# measurements


def harness_path() -> Path | None:
    """The installed per-cycle harness, or $VIRTMECH_CYCLE_BENCH, or one on PATH."""
    env = os.environ.get("VIRTMECH_CYCLE_BENCH")
    if env:
        return Path(env)
    exe = "virtmech_cycle_bench" + (".exe" if os.name == "nt" else "")
    here = Path(__file__).resolve().parent / "bin" / exe
    if here.is_file():
        return here
    found = shutil.which(exe)
    return Path(found) if found else None


def run_harness(cycles: int, cases: list[str], cpu: int | None = None) -> dict[str, Any]:
    """Runs the C++ harness and returns its JSON report."""
    exe = harness_path()
    if exe is None:
        raise FileNotFoundError(
            "virtmech_cycle_bench not found: it is installed with the package (virtmech/bin); "
            "set VIRTMECH_CYCLE_BENCH to a build's bench/virtmech_cycle_bench")
    cmd = [str(exe), "--json", "--cycles", str(cycles), "--warmup", str(WARMUP)]
    for c in cases:
        cmd += ["--case", c]
    if cpu is not None:
        cmd += ["--cpu", str(cpu)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.strip()}")
    return json.loads(proc.stdout)


def _timer_overhead_ns() -> float:
    clock = time.perf_counter_ns
    d = np.empty(20000)
    for i in range(d.size):
        t0 = clock()
        d[i] = clock() - t0
    return float(np.median(d))


def python_step(case: Case, cycles: int) -> dict[str, Any]:
    """Times Controller.step from Python over the trajectory (after WARMUP untimed cycles);
    returns the per-call median [µs], the median of the call's time over the cycle's own
    (its `computation_time_us`, cycle by cycle: the binding's overhead), and the torques and
    iteration counts of every cycle."""
    c = case.controller
    c.reset()
    period = c.model["period_s"]
    q_w, dq_w = case.joint_state(np.arange(WARMUP), period)
    for k in range(WARMUP):
        c.step(q_w[k], dq_w[k])
    q, dq = case.joint_state(np.arange(WARMUP, WARMUP + cycles), period)
    clock = time.perf_counter_ns
    ns = np.empty(cycles)
    own_us = np.empty(cycles)
    tau = np.empty((cycles, q.shape[1]))
    its = np.empty((cycles, 2), dtype=int)
    step = c.step
    for k in range(cycles):
        qk, dqk = q[k], dq[k]
        t0 = clock()
        out = step(qk, dqk)
        ns[k] = clock() - t0
        own_us[k] = out.computation_time_us
        tau[k] = out.torque
        its[k] = out.iterations, out.iterations_star
    call_us = (ns - _timer_overhead_ns()) * 1e-3
    return {"median_us": float(np.median(call_us)),
            "overhead_us": float(np.median(call_us - own_us)), "own_us": own_us, "torque": tau,
            "iterations": its, "q": q, "dq": dq}


def numpy_baseline(case: Case, q_warm: np.ndarray, dq_warm: np.ndarray, its_warm: np.ndarray,
                   q: np.ndarray, dq: np.ndarray, its: np.ndarray) -> dict[str, Any]:
    """Runs the NumPy cycle: untimed through the warm-up states, then timed per cycle.
    Returns the median [µs] and the torques."""
    npc = NpController(case.controller, case.numpy_device, case.numpy_mechanism)
    for k in range(q_warm.shape[0]):
        npc.step(q_warm[k], dq_warm[k], int(its_warm[k, 0]), int(its_warm[k, 1]))
    clock = time.perf_counter_ns
    ns = np.empty(q.shape[0])
    tau = np.empty_like(q)
    for k in range(q.shape[0]):
        t0 = clock()
        tau[k] = npc.step(q[k], dq[k], int(its[k, 0]), int(its[k, 1]))
        ns[k] = clock() - t0
    return {"median_us": float(np.median(ns)) * 1e-3, "torque": tau}


def _first_cycles(case: Case, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, dq and the core's iteration counts over the first `count` cycles from reset."""
    c = case.controller
    c.reset()
    q, dq = case.joint_state(np.arange(count), c.model["period_s"])
    its = np.empty((count, 2), dtype=int)
    for k in range(count):
        out = c.step(q[k], dq[k])
        its[k] = out.iterations, out.iterations_star
    return q, dq, its


def compare_numpy(name: str, cycles: int = 200) -> dict[str, Any]:
    """Runs the core and the NumPy baseline from reset over `cycles` cycles of the case and
    returns both torque histories and iteration counts (for the equivalence check)."""
    case = make_case(name)
    q, dq, its = _first_cycles(case, cycles)
    c = case.controller
    c.reset()
    tau_core = np.array([c.step(q[k], dq[k]).torque for k in range(cycles)])
    npc = NpController(c, case.numpy_device, case.numpy_mechanism)
    tau_np = np.array([npc.step(q[k], dq[k], int(its[k, 0]), int(its[k, 1]))
                       for k in range(cycles)])
    return {"torque_core": tau_core, "torque_numpy": tau_np, "iterations": its}


def simulation_figures(scenarios: list[str] | None = None,
                       repeats: int = 3) -> tuple[list[dict[str, Any]], str]:
    """Real-time factor of each shipped scenario, if the simulation is installed: simulated
    seconds per wall second of the closed loop (`SimResult.wall_time_s`, median of `repeats`
    runs); `setup_and_run_wall_time_s` adds building the MJCF and solving the start pose.
    Returns the figures and a note."""
    try:
        from virtmech import scenarios as vs
        from virtmech import sim as vsim
    except Exception as exc:  # the simulation is optional
        return [], f"simulation not available ({type(exc).__name__}: {exc})"
    if not hasattr(vs, "names") or not hasattr(vs, "load") or not hasattr(vsim, "run"):
        return [], "simulation not available (needs scenarios.names/load and sim.run)"
    out: list[dict[str, Any]] = []
    notes: list[str] = []
    for name in scenarios if scenarios is not None else list(vs.names()):
        try:
            scenario = vs.load(name)
            runs = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                result = vsim.run(scenario, seed=0, progress=False)
                total = time.perf_counter() - t0
                runs.append((float(result.wall_time_s), total))
            sim_s = float(result.sim_time_s)
            wall_s = float(np.median([r[0] for r in runs]))
            total_s = float(np.median([r[1] for r in runs]))
        except Exception as exc:
            notes.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        out.append({"scenario": name, "realtime_factor": sim_s / wall_s,
                    "sim_time_s": sim_s, "wall_time_s": wall_s,
                    "setup_and_run_wall_time_s": total_s,
                    "engine": result.info["physics"].get("engine", "python"),
                    "runs": repeats})
    return out, "; ".join(notes)


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info: dict[str, Any] = {"cpu": cpu, "logical_cpus": os.cpu_count(),
                            "platform": platform.platform(), "python": platform.python_version(),
                            "numpy": np.__version__}
    try:
        info["load_average"] = list(os.getloadavg())
    except (AttributeError, OSError):
        pass
    return info


def collect(cycles: int = DEFAULT_CYCLES, python_cycles: int = DEFAULT_PYTHON_CYCLES,
            numpy_cycles: int = DEFAULT_NUMPY_CYCLES, cases: list[str] | None = None,
            simulation: bool = True, cpu: int | None = None) -> dict[str, Any]:
    """Runs every measurement and returns the report (the --json object)."""
    import virtmech as vm

    names = list(cases) if cases else list(CASES)
    report: dict[str, Any] = {"virtmech_version": vm.__version__, "machine": machine()}
    harness = run_harness(cycles, names, cpu)
    report["machine"]["harness"] = harness["machine"]
    report["cycles"] = harness["cycles"]
    report["sizeof"] = harness["sizeof"]
    report["allocation_counter"] = harness["allocation_counter"]
    by_name = {c["name"]: c for c in harness["cases"]}
    out_cases = []
    for name in names:
        h = by_name[name]
        case = make_case(name)
        py = python_step(case, python_cycles)
        # the NumPy baseline replays the same cycles with the core's iteration counts
        q_w, dq_w, its_w = _first_cycles(case, WARMUP)
        m = min(numpy_cycles, python_cycles)
        nb = numpy_baseline(case, q_w, dq_w, its_w, py["q"][:m], py["dq"][:m],
                            py["iterations"][:m])
        diff = float(np.abs(nb["torque"] - py["torque"][:m]).max())
        # side by side: the C++ cycle's own time over the very cycles NumPy ran (a case's
        # cost varies along its trajectory, so medians over other spans would not compare)
        cpp_same = float(np.median(py["own_us"][:m]))
        out_cases.append({
            "name": name,
            "median_us": h["median_us"], "p99_us": h["p99_us"], "p999_us": h["p999_us"],
            "max_us": h["max_us"], "mean_us": h["mean_us"], "cycles": h["cycles"],
            "allocations": int(h["allocations"]),
            "mean_iterations": h["mean_iterations"] + h["mean_iterations_star"],
            "numpy_median_us": nb["median_us"],
            "speedup_vs_numpy": nb["median_us"] / cpp_same if cpp_same > 0 else None,
            "cpp_median_numpy_cycles_us": cpp_same,
            "numpy_cycles": m,
            "numpy_max_torque_difference": diff,
            "python_step_median_us": py["median_us"],
            "python_overhead_us": py["overhead_us"],
            "python_cycles": python_cycles,
        })
    report["cases"] = out_cases
    if simulation:
        report["simulation"], note = simulation_figures()
    else:
        report["simulation"], note = [], "simulation skipped (--no-sim)"
    if note:
        report["simulation_note"] = note
    return report


def format_table(r: dict[str, Any]) -> str:
    """The report as a readable table."""
    m = r["machine"]
    lines = [
        f"virtmech {r['virtmech_version']} benchmark: {r['cycles']} C++ cycles per case",
        f"machine: {m['cpu']}, {m['logical_cpus']} logical CPUs, {m.get('platform', '')}, "
        f"Python {m.get('python')}, NumPy {m.get('numpy')}",
        f"load average: {m.get('load_average')}; compiler: {m['harness'].get('compiler')}; "
        f"timer overhead {m['harness'].get('timer_overhead_ns')} ns (in the C++ figures)",
        "sizeof: " + ", ".join(f"{k} {v} B" for k, v in r["sizeof"].items()),
        "",
        f"{'case':<21}{'median':>8}{'p99':>8}{'p99.9':>8}{'max':>8}{'allocs':>7}"
        f"{'NumPy':>10}{'speedup':>9}{'Python':>8}{'overhead':>9}",
        f"{'':<21}{'[us]':>8}{'[us]':>8}{'[us]':>8}{'[us]':>8}{'':>7}"
        f"{'[us]':>10}{'[x]':>9}{'[us]':>8}{'[us]':>9}",
    ]
    for c in r["cases"]:
        sp = c["speedup_vs_numpy"]
        lines.append(
            f"{c['name']:<21}{c['median_us']:>8.3f}{c['p99_us']:>8.3f}{c['p999_us']:>8.3f}"
            f"{c['max_us']:>8.1f}{c['allocations']:>7d}{c['numpy_median_us']:>10.1f}"
            f"{(sp if sp is not None else float('nan')):>9.0f}{c['python_step_median_us']:>8.3f}"
            f"{c['python_overhead_us']:>9.3f}")
    lines.append("")
    if r["simulation"]:
        lines.append(f"{'simulation scenario':<40}{'real-time factor':>18}")
        for s in r["simulation"]:
            lines.append(f"{s['scenario']:<40}{s['realtime_factor']:>17.1f}x")
    if r.get("simulation_note"):
        lines.append(f"simulation: {r['simulation_note']}")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    """Entry point of `virtmech bench [--json]`; returns the exit status."""
    p = argparse.ArgumentParser(prog="virtmech bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--cycles", type=int, default=DEFAULT_CYCLES,
                   help=f"timed C++ cycles per case (default {DEFAULT_CYCLES})")
    p.add_argument("--python-cycles", type=int, default=DEFAULT_PYTHON_CYCLES,
                   help=f"timed Python step calls per case (default {DEFAULT_PYTHON_CYCLES})")
    p.add_argument("--numpy-cycles", type=int, default=DEFAULT_NUMPY_CYCLES,
                   help=f"timed NumPy baseline cycles per case (default {DEFAULT_NUMPY_CYCLES})")
    p.add_argument("--case", action="append", choices=CASES, help="only this case (repeatable)")
    p.add_argument("--no-sim", action="store_true", help="skip the simulation figures")
    p.add_argument("--cpu", type=int, default=None, help="pin the C++ harness to this CPU")
    a = p.parse_args(argv)
    for opt in ("cycles", "python_cycles", "numpy_cycles"):
        if getattr(a, opt) < 1:
            p.error(f"--{opt.replace('_', '-')}: expected >= 1, got {getattr(a, opt)}")
    try:
        r = collect(a.cycles, a.python_cycles, a.numpy_cycles, a.case, not a.no_sim, a.cpu)
    except (FileNotFoundError, RuntimeError) as exc:
        print(f"virtmech bench: {exc}", file=sys.stderr)
        return 1
    print(json.dumps(r, indent=2) if a.json else format_table(r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
