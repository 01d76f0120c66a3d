"""Closed-form placements that search the stylus's direction are the global optimum from
any warm start: a LineGuide's (Newton on the sphere of directions, stopped early where a
convexity certificate shows the warm start's end global) and a SurfaceProbe's on a sphere
(one angle).

The warm starts are random joint values (ends in the wrong basin included) and the
reference is independent: the cost reduced to the stylus direction u on the unit sphere
(the tip's offset along its set and the roll about the stylus drop out exactly),

    f(u) = w_p dist(p_R - L u, set)^2 + w_r angle(u, u_R)^2,  u_R = -R_R z,

minimised by a dense Fibonacci grid of directions, each of its local minima on the grid
polished by SciPy (two minima of nearly equal cost, such as the two directions that put the
tip on a line, are both polished)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

import virtmech as vm

L = 0.1
POINT = np.array([0.01, -0.02, 0.03])
E = np.array([1.0, 0.2, -0.1]) / np.linalg.norm([1.0, 0.2, -0.1])
NORMAL = np.cross(E, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(E, [0.0, 0.0, 1.0]))
CENTRE, RADIUS = POINT - 0.05 * NORMAL, 0.05  # a sphere whose top is POINT
U = np.array([1, 1, 1, L * L, L * L, L * L])
WEIGHTS = {  # the controller's defaults on the Omni, a fully actuated device's, a mix
    "nearest": np.array([1, 1, 1, 0, 0, 0]) + 1e-6 * U,
    "unpowered": np.array([0, 0, 0, L * L, L * L, L * L]) + 1e-6 * U,
    "full": (1 + 1e-6) * U,
    "mixed": np.array([2.0, 2.0, 2.0, 0.3 * L * L, 0.3 * L * L, 0.3 * L * L]),
}


def line_offset(q):
    """The offsets of the points q (rows) from the line POINT + s E."""
    d = q - POINT
    return d - np.outer(d @ E, E)


def sphere_offset(q, unilateral):
    """The offsets of the points q (rows) from the sphere (from outside it, unilateral)."""
    d = q - CENTRE
    n = np.linalg.norm(d, axis=1)
    gap = n - RADIUS
    if unilateral:
        gap = np.minimum(gap, 0.0)
    return (gap / n)[:, None] * d


SETS = {
    "LineGuide": (lambda: vm.LineGuide(POINT, E, L, NORMAL), line_offset),
    "SurfaceProbe/sphere": (
        lambda: vm.SurfaceProbe(vm.Sphere(CENTRE, RADIUS, E), L),
        lambda q: sphere_offset(q, False)),
    "SurfaceProbe/sphere/unilateral": (
        lambda: vm.SurfaceProbe(vm.Sphere(CENTRE, RADIUS, E), L, unilateral=True),
        lambda q: sphere_offset(q, True)),
}


def fibonacci_sphere(n):
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5**0.5) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


GRID = fibonacci_sphere(20000)  # neighbours about 1.5 degrees apart
_distance, _index = cKDTree(GRID).query(GRID, k=9)
NEIGHBOURS = _index[:, 1:]  # each point's eight nearest
SPACING = float(_distance[:, 1:].max())  # every direction lies about this near a grid point


def residuals(offset, u, p_R, u_R, w_p, w_r):
    """sqrt(w_p) times the tip's offset from its set, sqrt(w_r) times the angle, per row."""
    u = np.atleast_2d(u)
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    angle = np.arctan2(np.linalg.norm(np.cross(u, u_R), axis=1), u @ u_R)
    return np.column_stack([np.sqrt(w_p) * offset(p_R - L * u), np.sqrt(w_r) * angle])


def reference_minimum(offset, p_R, u_R, w_p, w_r):
    values = (residuals(offset, GRID, p_R, u_R, w_p, w_r) ** 2).sum(axis=1)
    best = float(values.min())
    # The grid's strict local minima (a plateau's points need no polish) that may hold the
    # global one: the grid point nearest a minimiser lies within SPACING of it, so above the
    # minimum by at most half of f's largest curvature times SPACING^2 (the curvature at most
    # 2 w_r from the angle, 2 w_p L (L + |r|) from the tip, |r| <= |p_R - POINT| + L), with
    # a factor of four to spare.
    curvature = 2.0 * w_r + 2.0 * w_p * L * (2.0 * L + np.linalg.norm(p_R - POINT))
    local = np.flatnonzero((values < values[NEIGHBOURS].min(axis=1))
                           & (values <= best + 2.0 * curvature * SPACING**2))
    chosen = [int(np.argmin(values))]  # and the lowest of each group 0.3 rad apart
    for i in local[np.argsort(values[local])]:
        if len(chosen) < 4 and np.linalg.norm(GRID[chosen] - GRID[i], axis=1).min() > 0.3:
            chosen.append(int(i))
    for i in chosen:
        g = GRID[i]  # polished in its tangent plane: u = g + a t1 + b t2, normalised
        t1 = np.cross(g, [1.0, 0.0, 0.0] if abs(g[0]) < 0.9 else [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        tangent = np.column_stack([t1, np.cross(g, t1)])
        r = least_squares(
            lambda x, g=g, t=tangent: residuals(offset, g + t @ x, p_R, u_R, w_p, w_r)[0],
            np.zeros(2), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        best = min(best, float((r.fun**2).sum()))
    return best


def cost(m, T, W, theta):
    e = vm.pose_error(T, m.forward(theta))
    return float(e @ (W * e))


def random_start(m, rng):
    """Joint values anywhere: slides within 0.1 (0 to 0.05 for a lift-off), angles any."""
    x = rng.uniform(-np.pi, np.pi, m.dof)
    for i, kind in enumerate(m.joint_types[: m.dof - 3]):
        if kind == "prismatic":
            x[i] = rng.uniform(-0.1, 0.1)
    return np.clip(x, np.where(np.isfinite(m.lower), m.lower, -10),
                   np.where(np.isfinite(m.upper), m.upper, 10))


@pytest.mark.parametrize("name", sorted(SETS))
@pytest.mark.parametrize("weights", sorted(WEIGHTS))
def test_the_placement_is_global_from_any_warm_start(name, weights):
    make, offset = SETS[name]
    m = make()
    W = WEIGHTS[weights]
    w_p, w_r = W[0], W[3]
    rng = np.random.default_rng(23)
    for _ in range(12):
        R = vm.so3_exp(rng.normal(size=3))
        # the handle within the stylus's reach of the set, at its edge and beyond
        p_R = POINT + rng.uniform(-0.05, 0.05) * E + rng.normal(scale=0.07, size=3)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p_R
        c_ref = reference_minimum(offset, p_R, -R[:, 2], w_p, w_r)
        for _ in range(3):  # warm starts anywhere
            r = vm.track(m, T, random_start(m, rng), W)
            assert r.iterations == 0 and r.converged
            c = cost(m, T, W, r.theta)
            assert c <= c_ref * (1.0 + 1e-9) + 1e-15, (c, c_ref)


@pytest.mark.parametrize("name", sorted(SETS))
def test_a_placement_followed_along_a_path_stays_global(name):
    """The servo loop's case: each placement warm-started from the last, the handle swept
    across the set and out of reach and back (a line guide's optimum jumps between the two
    directions that put the tip on the line)."""
    make, offset = SETS[name]
    m = make()
    W = WEIGHTS["nearest"]
    theta = m.home
    R0 = vm.so3_exp(np.array([0.3, -0.2, 0.1]))
    for k in range(30):
        s = k / 29.0
        p_R = POINT + 0.03 * np.sin(3 * np.pi * s) * E + (0.02 + 0.12 * s) * NORMAL
        R = vm.so3_exp(np.array([0.0, 0.0, 2 * np.pi * s])) @ R0
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p_R
        r = vm.track(m, T, theta, W)
        c_ref = reference_minimum(offset, p_R, -R[:, 2], W[0], W[3])
        assert cost(m, T, W, r.theta) <= c_ref * (1.0 + 1e-9) + 1e-15, k
        theta = r.theta


@pytest.mark.parametrize("name", sorted(SETS))
@pytest.mark.parametrize("weights", sorted(WEIGHTS))
def test_the_handle_at_the_sphere_centre_is_placed(name, weights):
    """The handle at the sphere's centre (every stylus direction puts the tip equally far
    from the sphere, so the rotation term alone decides), and for the line guide at the
    same point: placed without Gauss-Newton, at the global optimum."""
    make, offset = SETS[name]
    m = make()
    W = WEIGHTS[weights]
    rng = np.random.default_rng(5)
    for _ in range(4):
        R = vm.so3_exp(rng.normal(size=3))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, CENTRE
        c_ref = reference_minimum(offset, CENTRE, -R[:, 2], W[0], W[3])
        r = vm.track(m, T, random_start(m, rng), W)
        assert r.iterations == 0 and r.converged
        assert cost(m, T, W, r.theta) <= c_ref * (1.0 + 1e-9) + 1e-15
