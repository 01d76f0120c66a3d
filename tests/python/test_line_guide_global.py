"""A LineGuide's closed-form placement is the global optimum from any warm start.

The placement descends from the last placement's stylus direction and stops early where a
certificate (a convexity bound on the caps that must hold every minimiser) shows that end
global; otherwise it tries every start. Here the warm starts are random joint values (ends
in the wrong basin included) and the reference is independent: the cost reduced to the
stylus direction u on the unit sphere (the tip's offset along the line and the roll about
the stylus drop out exactly),

    f(u) = w_p |(I - e e^T)(p_R - L u - point)|^2 + w_r angle(u, u_R)^2,  u_R = -R_R z,

minimised by a dense Fibonacci grid of directions, its best points polished by SciPy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

import virtmech as vm

L = 0.1
POINT = np.array([0.01, -0.02, 0.03])
E = np.array([1.0, 0.2, -0.1]) / np.linalg.norm([1.0, 0.2, -0.1])
NORMAL = np.cross(E, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(E, [0.0, 0.0, 1.0]))
U = np.array([1, 1, 1, L * L, L * L, L * L])
WEIGHTS = {  # the controller's defaults on the Omni, a fully actuated device's, a mix
    "nearest": np.array([1, 1, 1, 0, 0, 0]) + 1e-6 * U,
    "unpowered": np.array([0, 0, 0, L * L, L * L, L * L]) + 1e-6 * U,
    "full": (1 + 1e-6) * U,
    "mixed": np.array([2.0, 2.0, 2.0, 0.3 * L * L, 0.3 * L * L, 0.3 * L * L]),
}


def fibonacci_sphere(n):
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5**0.5) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


GRID = fibonacci_sphere(20000)  # neighbours about 1.5 degrees apart


def residuals(u, p_R, u_R, w_p, w_r):
    """sqrt(w_p) times the tip's offset from the line, sqrt(w_r) times the angle, per row."""
    u = np.atleast_2d(u)
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    d = p_R - L * u - POINT
    d -= np.outer(d @ E, E)
    angle = np.arctan2(np.linalg.norm(np.cross(u, u_R), axis=1), u @ u_R)
    return np.column_stack([np.sqrt(w_p) * d, np.sqrt(w_r) * angle])


def reference_minimum(p_R, u_R, w_p, w_r):
    values = (residuals(GRID, p_R, u_R, w_p, w_r) ** 2).sum(axis=1)
    best = float(values.min())
    for i in np.argsort(values)[:3]:
        g = GRID[i]  # polished in its tangent plane: u = g + a t1 + b t2, normalised
        t1 = np.cross(g, [1.0, 0.0, 0.0] if abs(g[0]) < 0.9 else [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(g, t1)
        tangent = np.column_stack([t1, t2])
        r = least_squares(lambda x, g=g, t=tangent: residuals(g + t @ x, p_R, u_R, w_p, w_r)[0],
                          np.zeros(2), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        best = min(best, float((r.fun**2).sum()))
    return best


def cost(m, T, W, theta):
    e = vm.pose_error(T, m.forward(theta))
    return float(e @ (W * e))


@pytest.mark.parametrize("weights", sorted(WEIGHTS))
def test_the_placement_is_global_from_any_warm_start(weights):
    m = vm.LineGuide(POINT, E, L, NORMAL)
    W = WEIGHTS[weights]
    w_p, w_r = W[0], W[3]
    rng = np.random.default_rng(23)
    for _ in range(40):
        R = vm.so3_exp(rng.normal(size=3))
        # the handle within the stylus's reach of the line, at its edge and beyond
        p_R = POINT + rng.uniform(-0.05, 0.05) * E + rng.normal(scale=0.07, size=3)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p_R
        c_ref = reference_minimum(p_R, -R[:, 2], w_p, w_r)
        for _ in range(3):  # warm starts anywhere: the along offset and the wrist's angles
            start = np.concatenate([[rng.uniform(-0.1, 0.1)], rng.uniform(-np.pi, np.pi, 3)])
            r = vm.track(m, T, start, W)
            assert r.iterations == 0 and r.converged
            c = cost(m, T, W, r.theta)
            assert c <= c_ref * (1.0 + 1e-9) + 1e-15, (c, c_ref)


def test_a_placement_followed_along_a_path_stays_global():
    """The servo loop's case: each placement warm-started from the last, the handle swept
    across the line and out of reach and back (the global optimum jumps between the two
    directions that put the tip on the line)."""
    m = vm.LineGuide(POINT, E, L, NORMAL)
    W = WEIGHTS["nearest"]
    theta = m.home
    R0 = vm.so3_exp(np.array([0.3, -0.2, 0.1]))
    for k in range(60):
        s = k / 59.0
        p_R = POINT + 0.03 * np.sin(3 * np.pi * s) * E + (0.02 + 0.12 * s) * NORMAL
        R = vm.so3_exp(np.array([0.0, 0.0, 2 * np.pi * s])) @ R0
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p_R
        r = vm.track(m, T, theta, W)
        c_ref = reference_minimum(p_R, -R[:, 2], W[0], W[3])
        assert cost(m, T, W, r.theta) <= c_ref * (1.0 + 1e-9) + 1e-15, k
        theta = r.theta
