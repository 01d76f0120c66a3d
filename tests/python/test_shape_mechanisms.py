"""Mechanisms on a geometry: SurfaceProbe, CurveGuide, HandlePath.

Every expected value is a closed form of the geometry set up around the handle (a depth
along a known normal, a tangent from the curve's own derivative); the Jacobians are checked
against finite differences of the mechanisms' own forward kinematics and the placements
against SciPy's minimiser."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

import virtmech as vm
from conftest import numeric_jacobian

KP = vm.PhantomOmni().stiffness  # [N/m] the default translational stiffness
L = 0.1  # [m] stylus length
DEPTH = 0.002  # [m]


def cartesian_device() -> vm.Device:
    """A fully actuated PPPRRR device: its joints are the handle's position and XYZ angles."""
    joints = [vm.Joint("prismatic", a) for a in np.eye(3)]
    joints += [vm.Joint("revolute", a) for a in np.eye(3)]
    return vm.Device(joints, [True] * 6, stiffness=KP, damping=1.0, max_force=100.0)


def cartesian_q(T: np.ndarray) -> np.ndarray:
    R = T[:3, :3]
    b = np.arcsin(np.clip(R[0, 2], -1, 1))
    return np.r_[T[:3, 3], np.arctan2(-R[1, 2], R[2, 2]), b, np.arctan2(-R[0, 1], R[0, 0])]


def rotation_taking(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation matrix taking the unit vector a to the unit vector b."""
    v = np.cross(a, b)
    s, c = np.linalg.norm(v), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0, 1.0, 0])
        return vm.so3_exp(np.pi * axis / np.linalg.norm(axis))
    return vm.so3_exp(v / s * np.arctan2(s, c))


def patch(R=None, t=None) -> vm.NurbsSurface:
    """A rational bicubic patch about 12 cm x 9 cm, curved in both directions (a bump and a
    saddle), rigidly moved by (R, t) (NURBS are invariant under rigid motions)."""
    nu, nv = 5, 4
    P = np.zeros((nu, nv, 3))
    for i in range(nu):
        for j in range(nv):
            x, y = 0.03 * i - 0.06, 0.03 * j - 0.045
            P[i, j] = [x, y, 0.012 * np.cos(2.0 * x / 0.06) * np.cos(y / 0.045) + 0.2 * x * y]
    W = 1.0 + 0.25 * np.add.outer(np.sin(np.arange(nu)), np.cos(np.arange(nv))) ** 2
    R = np.eye(3) if R is None else R
    P = P @ R.T + (0.0 if t is None else t)
    return vm.NurbsSurface(P, W, [0, 0, 0, 0, 0.5, 1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3, 3)


def letter_curve(R=None, t=None) -> vm.NurbsCurve:
    """A rational cubic 'S' about 8 cm tall in the local xy-plane, rigidly moved."""
    P = np.array(
        [[0.03, 0.04, 0], [-0.01, 0.045, 0], [-0.03, 0.02, 0], [0.0, 0.0, 0.005],
         [0.03, -0.02, 0], [0.01, -0.045, 0], [-0.03, -0.04, 0]]
    )
    w = np.array([1.0, 1.3, 0.8, 1.0, 1.2, 0.9, 1.0])
    knots = [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1]
    R = np.eye(3) if R is None else R
    return vm.NurbsCurve(P @ R.T + (0.0 if t is None else t), w, knots, 3)


def handle_at(tip: np.ndarray, stylus: np.ndarray, length: float = L) -> np.ndarray:
    """A handle pose whose stylus (local z, toward the tip) points along `stylus`, its tip at
    `tip`."""
    T = np.eye(4)
    T[:3, :3] = rotation_taking(np.array([0.0, 0, 1]), stylus)
    T[:3, 3] = tip - length * stylus
    return T


# --- kinematics --------------------------------------------------------------------------


def shapes():
    return {
        "nurbs": patch(),
        "sphere": vm.Sphere([0.01, -0.02, 0.03], 0.05, axis=[0, 1, 0]),
        "cylinder": vm.Cylinder([0, 0, 0], [1, 1, 0], 0.04),
        "plane": vm.Plane([0, 0, 0.01], [0.2, 0.1, 1]),
    }


@pytest.mark.parametrize("name", ["nurbs", "sphere", "cylinder", "plane"])
@pytest.mark.parametrize("unilateral", [False, True])
def test_surface_probe_jacobian_is_the_derivative_of_its_pose(name, unilateral, rng):
    m = vm.SurfaceProbe(shapes()[name], L, unilateral=unilateral)
    assert m.dof == (6 if unilateral else 5)
    assert m.contact_joint == (2 if unilateral else -1)
    for _ in range(5):
        x = np.asarray(m.home) + 0.15 * rng.standard_normal(m.dof)
        if unilateral:
            x[2] = abs(x[2]) * 0.1
        J = np.asarray(m.jacobian(x))
        assert np.abs(J - numeric_jacobian(m.forward, x)).max() < 1e-7


def test_surface_probe_pose_is_the_tip_on_the_surface_with_the_stylus_over_it(rng):
    """At wrist angles 0 the tip is S(u, v) (+ h n), the stylus along -n, the handle L back."""
    for s in shapes().values():
        for unilateral in (False, True):
            m = vm.SurfaceProbe(s, L, unilateral=unilateral)
            x = np.array(m.home, dtype=float)
            x[:2] += 0.1 * rng.standard_normal(2)
            h = 0.004 if unilateral else 0.0
            if unilateral:
                x[2] = h
            n = s.normal(x[0], x[1])
            T = m.forward(x)
            tip = T[:3, 3] + L * T[:3, 2]
            np.testing.assert_allclose(tip, s.evaluate(x[0], x[1]) + h * n, atol=1e-12)
            np.testing.assert_allclose(T[:3, 2], -n, atol=1e-12)


@pytest.mark.parametrize("kind", ["guide", "path"])
def test_curve_mechanisms_jacobian_and_pose(kind, rng):
    C = letter_curve()
    m = vm.CurveGuide(C, L) if kind == "guide" else vm.HandlePath(C)
    for _ in range(5):
        x = np.asarray(m.home) + 0.2 * rng.standard_normal(4)
        x[0] = np.clip(x[0], 0.0, 1.0)
        J = np.asarray(m.jacobian(x))
        assert np.abs(J - numeric_jacobian(m.forward, x)).max() < 1e-7
        T = m.forward(x)
        point = T[:3, 3] + (L * T[:3, 2] if kind == "guide" else 0.0)
        np.testing.assert_allclose(point, C.evaluate(x[0]), atol=1e-12)
    assert m.lower[0] == 0.0 and m.upper[0] == 1.0  # the path's ends are stops


def test_sphere_longitude_is_unbounded_latitude_stops_at_the_poles():
    m = vm.SurfaceProbe(vm.Sphere([0, 0, 0], 0.05), L)
    assert np.isinf(m.lower[0]) and np.isinf(m.upper[0])
    assert m.lower[1] == pytest.approx(-np.pi / 2) and m.upper[1] == pytest.approx(np.pi / 2)
    nurbs = vm.SurfaceProbe(patch(), L)
    assert (nurbs.lower[0], nurbs.upper[0], nurbs.lower[1], nurbs.upper[1]) == (0, 1, 0, 1)


def test_placement_equals_scipys_minimum_of_the_weighted_pose_error(rng):
    """vm.track on a NURBS SurfaceProbe reaches the minimum SciPy finds from the same start."""
    m = vm.SurfaceProbe(patch(), L)
    W = np.array([1, 1, 1, L * L, L * L, L * L])
    for _ in range(4):
        x0 = np.asarray(m.home) + np.r_[0.1 * rng.standard_normal(2), 0.2 * rng.standard_normal(3)]
        target = m.forward(x0)
        target[:3, 3] += 0.01 * rng.standard_normal(3)

        def cost(x, target=target):
            e = vm.pose_error(target, m.forward(x))
            return float(e @ (W * e))

        ref = minimize(cost, x0, method="L-BFGS-B", bounds=list(zip(m.lower, m.upper)),
                       options={"ftol": 1e-16, "gtol": 1e-13, "maxiter": 2000})
        res = vm.track(m, target, x0, W, max_iterations=200)
        assert cost(res.theta) <= ref.fun * (1 + 1e-6) + 1e-16


def newton_weights(kind: str) -> np.ndarray:
    """The three weightings of the Newton placements' tests: an under-actuated device's
    nearest and unpowered placements (the secondary weight 1e-6 on the rest) and both."""
    eps = 1e-6 * np.array([1, 1, 1, L * L, L * L, L * L])
    return {"nearest": np.array([1.0, 1, 1, 0, 0, 0]) + eps,
            "unpowered": np.array([0, 0, 0, L * L, L * L, L * L]) + eps,
            "full": np.array([1.0, 1, 1, L * L, L * L, L * L])}[kind]


def weighted_cost(m, W):
    def cost(x, target):
        e = vm.pose_error(target, m.forward(x))
        return float(e @ (W * e))
    return cost


def assert_newton_optimum(m, W, target, x0, theta):
    """theta, placed from x0 without Gauss-Newton iterations, is a local optimum: never above
    Gauss-Newton's end from x0 nor SciPy's local minimum from x0, and a fixed point of
    Gauss-Newton (to 1e-9 in the metric the cost sees)."""
    cost = weighted_cost(m, W)
    gn = vm.track(m, target, x0, W, closed_form=False, max_iterations=500)
    assert cost(theta, target) <= cost(gn.theta, target) * (1 + 1e-9) + 1e-15
    fixed = vm.track(m, target, theta, W, closed_form=False, max_iterations=500)
    d = np.sqrt(W) * vm.pose_error(m.forward(theta), m.forward(fixed.theta))
    assert np.abs(d).max() <= 1e-9, d
    ref = minimize(cost, x0, args=(target,), method="L-BFGS-B",
                   bounds=list(zip(m.lower, m.upper)),
                   options={"ftol": 1e-16, "gtol": 1e-13, "maxiter": 2000})
    assert cost(theta, target) <= ref.fun * (1 + 1e-6) + 1e-16


@pytest.mark.parametrize("weights", ["nearest", "unpowered", "full"])
def test_curve_guide_newton_reaches_the_gauss_newton_optimum(rng, weights):
    """A CurveGuide with weights isotropic per block is placed by Newton's method with exact
    second derivatives (no Gauss-Newton iterations). It ends at a local optimum, a fixed
    point of Gauss-Newton (to 1e-9 in the metric the cost sees), and from a warm start near
    the optimum never above Gauss-Newton's end from that start nor SciPy's local minimum
    (from far starts two local methods may end in different basins, either the lower)."""
    m = vm.CurveGuide(letter_curve(), L, normal=[0, 0, 1])
    W = newton_weights(weights)
    closed = 0
    for _ in range(12):
        x_star = np.r_[rng.uniform(0.1, 0.9), 0.6 * rng.standard_normal(3)]
        target = m.forward(x_star)
        target[:3, :3] = vm.so3_exp(0.3 * rng.standard_normal(3)) @ target[:3, :3]
        target[:3, 3] += 0.01 * rng.standard_normal(3)
        x0 = x_star + np.r_[0.01, 0.05, 0.05, 0.05] * rng.standard_normal(4)
        cf = vm.track(m, target, x0, W)
        if cf.iterations > 0:
            continue  # Newton declined (a stop, or no convergence): Gauss-Newton placed it
        closed += 1
        assert_newton_optimum(m, W, target, x0, cf.theta)
    assert closed >= 10, closed  # Newton places nearly every such pose


def pressed_pose(m, W, rng, depth_min, depth_max):
    """A handle pose for a SurfaceProbe on patch(): a random placement's, turned by about
    0.2 rad about the tip, moved about 2 mm and pressed depth_min to depth_max in along the
    normal; the last cycle's solution x0 (Gauss-Newton's there), then the handle moved by
    0.3 mm and 0.01 rad. (target, x0, the normal)"""
    x_star = np.zeros(m.dof)
    x_star[:2] = rng.uniform(0.25, 0.75, 2)
    x_star[-3:] = 0.5 * rng.standard_normal(3)
    target = m.forward(x_star)
    turn = vm.so3_exp(0.2 * rng.standard_normal(3))
    tip = target[:3, 3] + L * target[:3, 2]
    target[:3, :3] = turn @ target[:3, :3]
    target[:3, 3] = tip - L * target[:3, 2]
    n = patch().normal(*x_star[:2])
    target[:3, 3] += 0.002 * rng.standard_normal(3)
    target[:3, 3] -= (depth_min + (depth_max - depth_min) * rng.uniform()) * n
    x0 = vm.track(m, target, x_star, W, closed_form=False, max_iterations=500).theta
    target[:3, :3] = vm.so3_exp(0.01 * rng.standard_normal(3)) @ target[:3, :3]
    target[:3, 3] += 0.0003 * rng.standard_normal(3)
    return target, x0, n


@pytest.mark.parametrize("unilateral", [False, True])
@pytest.mark.parametrize("weights", ["nearest", "unpowered", "full"])
def test_surface_probe_newton_reaches_the_gauss_newton_optimum(rng, weights, unilateral):
    """A SurfaceProbe on a NURBS patch, the tip in contact, weights isotropic per block: placed
    by Newton's method on the tip's parameters and the stylus direction (no Gauss-Newton
    iterations) from the last cycle's solution, the handle moved a little since. It ends at
    a local optimum, a fixed point of Gauss-Newton, never above Gauss-Newton's end from the
    same start nor SciPy's local minimum; one-sided, where the handle lifts the tip off it
    is the handle's own pose (the pose error zero), the tip above the surface."""
    m = vm.SurfaceProbe(patch(), L, unilateral=unilateral)
    W = newton_weights(weights)
    closed = lifted = 0
    for k in range(16):
        # pressed 3 to 8 mm in (every fourth lifted 5 mm off, below)
        target, x0, n = pressed_pose(m, W, rng, 0.003, 0.008)
        if k % 4 == 3:
            target[:3, 3] += 0.013 * n
        cf = vm.track(m, target, x0, W)
        if cf.iterations > 0:
            continue  # Newton declined: Gauss-Newton placed it
        closed += 1
        if unilateral and cf.theta[2] > 0.0:
            lifted += 1
            assert np.abs(vm.pose_error(target, m.forward(cf.theta))).max() <= 1e-12
        assert_newton_optimum(m, W, target, x0, cf.theta)
    # Newton places nearly every pose in contact, and the four lifted ones are lifted
    assert closed >= 14, closed
    assert lifted == (4 if unilateral else 0), lifted


@pytest.mark.parametrize("unilateral", [False, True])
def test_surface_probe_newton_follows_the_narrow_valley_of_the_nearest_placement(unilateral):
    """The nearest placement of an under-actuated device (the rotation weighted 1e-6) with
    the handle pressed 1 to 8 mm into the patch: the tip may sit anywhere on the circle
    where the stylus reaches the surface, so the cost is a narrow, curved valley along it
    that a full Newton step leaves (the Maratos effect). With the second-order correction
    Newton still places nearly every such pose from the last cycle's solution, at the
    Gauss-Newton optimum."""
    rng = np.random.default_rng(20261126)
    m = vm.SurfaceProbe(patch(), L, unilateral=unilateral)
    W = newton_weights("nearest")
    declined, poses = 0, 128
    for k in range(poses):
        target, x0, _ = pressed_pose(m, W, rng, 0.001, 0.008)
        cf = vm.track(m, target, x0, W)
        if cf.iterations > 0:
            declined += 1
        elif k % 8 == 0:
            assert_newton_optimum(m, W, target, x0, cf.theta)
    # (with it: none of these 128 either side; without: 10 and 14)
    assert declined <= poses // 32, declined


def test_surface_probe_on_a_cylinder_keeps_the_starts_turn():
    """u wraps on a cylinder (unbounded on the mechanism): lifted off (from a start 1.4 rad
    away) or in contact, the placement stays on the start's turn, at the handle's own pose
    and the tip's closed-form height when lifted."""
    m = vm.SurfaceProbe(vm.Cylinder([0, 0, 0], [0, 0, 1], 0.04), L, unilateral=True)
    W = np.array([1.0, 1, 1, L * L, L * L, L * L])
    for turns in (-3, 0, 2):
        x = np.array([3.0 + 2 * np.pi * turns, 0.01, 0.0, 0.1, -0.2, 0.3])
        T = m.forward(x)
        for depth in (-0.005, 0.003):  # pulled 5 mm off, pressed 3 mm in, along the stylus
            target = T.copy()
            target[:3, 3] += depth * T[:3, 2]
            start = x.copy()
            start[2] = 0.002 if depth < 0 else 0.0
            if depth < 0:
                start[0] -= 1.4
            res = vm.track(m, target, start, W)
            assert res.iterations == 0  # placed without Gauss-Newton
            assert abs(res.theta[0] - x[0]) < 0.5, (turns, depth, res.theta[0])
            if depth < 0:  # the tip's height: its distance from the axis less the radius
                tip = target[:3, 3] + L * target[:3, 2]
                assert res.theta[2] == pytest.approx(np.hypot(tip[0], tip[1]) - 0.04, abs=1e-12)
                assert np.abs(vm.pose_error(target, m.forward(res.theta))).max() <= 1e-12
            else:
                assert res.theta[2] == 0.0
    # lifted above u = pi / 2 from a start at u = 3.0: the projection walks the long way
    # round (to -3 pi / 2, the same point), and the placement takes it on the start's turn
    x = np.array([np.pi / 2, 0.01, 0.0, 0.0, 0.0, 0.0])
    target = m.forward(x)
    target[:3, 3] -= 0.01 * target[:3, 2]
    res = vm.track(m, target, np.r_[3.0, 0.01, 0.002, 0.0, 0.0, 0.0], W)
    assert res.iterations == 0 and res.theta[2] > 0.0
    assert res.theta[0] == pytest.approx(np.pi / 2, abs=1e-9)


def test_bad_arguments_name_the_parameter():
    with pytest.raises(ValueError, match="length"):
        vm.SurfaceProbe(vm.Sphere([0, 0, 0], 0.05), -0.1)
    with pytest.raises(ValueError, match="normal"):
        vm.CurveGuide(letter_curve(), L, normal=[0, 0, 0])
    with pytest.raises(ValueError, match="length_scale"):
        vm.HandlePath(letter_curve(), length_scale=0.0)
    with pytest.raises(TypeError):
        vm.SurfaceProbe(None, L)


def test_to_dict_rebuilds_the_same_mechanism():
    for m in (vm.SurfaceProbe(patch(), L, unilateral=True),
              vm.SurfaceProbe(vm.Sphere([0, 0, 0], 0.05, axis=[1, 0, 0]), 0.08),
              vm.CurveGuide(letter_curve(), L, normal=[0, 1, 0]), vm.HandlePath(letter_curve())):
        d = m.to_dict()
        assert d["type"] == m.type
        shape = d.get("surface") or d.get("curve")
        cls = getattr(vm, shape.pop("type"))
        rebuilt_shape = cls(**shape)
        x = np.asarray(m.home) + 0.05
        other = (vm.SurfaceProbe(rebuilt_shape, d["length"], d["unilateral"])
                 if d["type"] == "SurfaceProbe" else
                 vm.CurveGuide(rebuilt_shape, d["length"], d["normal"])
                 if d["type"] == "CurveGuide" else
                 vm.HandlePath(rebuilt_shape, d["normal"], d["length_scale"]))
        np.testing.assert_allclose(other.forward(x), m.forward(x), atol=1e-15)


# --- rendering: fully actuated device and the Omni ----------------------------------------


def omni_poses():
    """Omni joint values and their handle poses at a few places of its workspace."""
    omni = vm.PhantomOmni()
    qs = [np.asarray(omni.home, float), np.array([0.3, 0.2, -0.1, 0.2, 0.6, -0.3]),
          np.array([-0.4, 0.5, 0.2, -0.3, 0.3, 0.5])]
    return omni, [(q, omni.forward(q)) for q in qs]


def surface_contact(kind: str, T: np.ndarray, depth: float):
    """A surface whose outward normal at the contact is -z of the handle pose T, the tip
    (L along the stylus) `depth` inside it (negative: above it)."""
    z = T[:3, 2]
    tip = T[:3, 3] + L * z
    if kind == "sphere":
        r = 0.05
        return vm.Sphere(tip + (r - depth) * z, r, axis=np.cross(z, [0.3, 1, 0.2]))
    # the patch's point at (0.4, 0.6) with its normal taken to the contact, rigidly
    base = patch()
    u0, v0 = 0.4, 0.6
    R = rotation_taking(base.normal(u0, v0), -z)
    return patch(R, tip - depth * z - R @ base.evaluate(u0, v0))


def render(device, q, mechanism, dq=None):
    c = vm.Controller(device, mechanism, ramp_time_s=1e-3)
    dq = np.zeros(device.dof) if dq is None else dq
    return c.step(q, dq)


@pytest.mark.parametrize("kind", ["sphere", "nurbs"])
@pytest.mark.parametrize("unilateral", [False, True])
def test_surface_probe_pushed_in_renders_kp_times_depth_on_a_fully_actuated_device(
        kind, unilateral, rng):
    dev = cartesian_device()
    for _ in range(3):
        T = np.eye(4)
        T[:3, :3] = vm.so3_exp(0.5 * rng.standard_normal(3))
        T[:3, 3] = 0.05 * rng.standard_normal(3)
        q = cartesian_q(T)
        s = surface_contact(kind, T, DEPTH)
        out = render(dev, q, vm.SurfaceProbe(s, L, unilateral=unilateral))
        n = -T[:3, 2]
        f = np.asarray(out.wrench[:3])
        assert f @ n == pytest.approx(KP * DEPTH, rel=0.05)
        assert np.linalg.norm(f - (f @ n) * n) <= 1e-6  # nothing along the surface
        # the placement's tip lies on the surface
        P = np.asarray(out.mechanism_pose)
        tip = P[:3, 3] + L * P[:3, 2]
        _, point = s.closest_point(tip)
        assert np.linalg.norm(tip - point) < 1e-9
        if unilateral:
            assert out.active[2]
            lifted = render(dev, q, vm.SurfaceProbe(surface_contact(kind, T, -DEPTH), L, True))
            assert np.abs(lifted.wrench).max() <= 1e-9
            assert not lifted.active[2]


@pytest.mark.parametrize("kind", ["sphere", "nurbs"])
def test_surface_probe_on_the_omni(kind):
    """On the Omni (gimbal passive) the same 2 mm give Kp 0.002 along the normal through eq.
    26's range term; lifted 2 mm (unilateral) nothing."""
    omni, poses = omni_poses()
    for q, T in poses:
        n = -T[:3, 2]
        for unilateral in (False, True):
            s = surface_contact(kind, T, DEPTH)
            out = render(omni, q, vm.SurfaceProbe(s, L, unilateral))
            f = np.asarray(out.wrench[:3])
            assert f @ n == pytest.approx(KP * DEPTH, rel=0.05), (q, unilateral)
            assert np.linalg.norm(f - (f @ n) * n) <= 1e-6
            # both placements hold the tip on the surface (the un-powered one with the
            # handle's stylus: where the user's tip is rendered)
            for P in (np.asarray(out.mechanism_pose), np.asarray(out.mechanism_pose_star)):
                tip = P[:3, 3] + L * P[:3, 2]
                assert np.linalg.norm(tip - s.closest_point(tip)[1]) < 1e-9
        lifted = render(omni, q, vm.SurfaceProbe(surface_contact(kind, T, -DEPTH), L, True))
        assert np.abs(lifted.wrench).max() <= 1e-9


@pytest.mark.parametrize("kind", ["sphere", "nurbs"])
def test_sliding_along_the_surface_meets_no_force_along_it(kind):
    """The handle moving along the surface's tangent plane at 0.2 m/s, tip on the surface or
    2 mm in: the force along the surface is at most 1e-6 N (Kv = 1 N s/m would give 0.2 N
    if the motion were resisted)."""
    dev = cartesian_device()
    omni, poses = omni_poses()
    for depth in (0.0, DEPTH):
        for device, (q, T) in [(dev, (cartesian_q(p[1]), p[1])) for p in poses] + [
                (omni, p) for p in poses]:
            s = surface_contact(kind, T, depth)
            n = -T[:3, 2]
            J = np.asarray(device.jacobian(q))
            for direction in (np.cross(n, [1.0, 0, 0]), np.cross(n, [0, 1.0, 0])):
                v = 0.2 * direction / np.linalg.norm(direction)
                dq = np.linalg.lstsq(J[:3], v, rcond=None)[0]
                if device is dev:
                    dq = np.linalg.lstsq(J, np.r_[v, 0, 0, 0], rcond=None)[0]
                out = render(device, q, vm.SurfaceProbe(s, L), dq)
                f = np.asarray(out.wrench[:3])
                assert np.linalg.norm(f - (f @ n) * n) <= 1e-6, (device.name, depth)


@pytest.mark.parametrize("omni", [False, True])
def test_curve_guide_no_force_along_the_tangent_kp_across(omni, rng):
    """The tip 2 mm off the curve across its tangent: Kp 0.002 back toward it, nothing along
    the tangent, also while moving along the tangent."""
    if omni:
        device, poses = omni_poses()
    else:
        device = cartesian_device()
        poses = []
        for _ in range(3):
            T = np.eye(4)
            T[:3, :3] = vm.so3_exp(0.4 * rng.standard_normal(3))
            T[:3, 3] = 0.05 * rng.standard_normal(3)
            poses.append((cartesian_q(T), T))
    base = letter_curve()
    for q, T in poses:
        for u0 in (0.2, 0.55, 0.8):
            z = T[:3, 2]
            tip = T[:3, 3] + L * z
            # move the curve so that C(u0) sits DEPTH from the tip across the tangent
            R = rotation_taking(np.array([0, 0, 1.0]), -z)
            t_local = base.tangent(u0)
            across = np.cross(R @ t_local, z)
            across /= np.linalg.norm(across)
            C = letter_curve(R, tip + DEPTH * across - R @ base.evaluate(u0))
            J = np.asarray(device.jacobian(q))
            for speed in (0.0, 0.1):
                v = speed * C.tangent(u0)
                dq = np.linalg.lstsq(J[:3] if omni else J, v if omni else np.r_[v, 0, 0, 0],
                                     rcond=None)[0]
                out = render(device, q, vm.CurveGuide(C, L, normal=-z), dq)
                f = np.asarray(out.wrench[:3])
                # the tangent where the tip is held with the stylus as it is (the un-powered
                # placement; the nearest one on a fully actuated device, where they agree)
                tangent = C.tangent(out.theta_star[0])
                assert abs(f @ tangent) <= 1e-6, (u0, speed, f @ tangent)
                if speed == 0.0:
                    # the Omni's passive stylus turns freely: the tip is held with Kp. A fully
                    # actuated device's pose spring (weights U) shares the error between the
                    # tip's position and the stylus's turn: min (d - L a)^2 + L^2 a^2 at
                    # a = d / 2L leaves Kp d / 2, a pure force at the tip
                    expected = KP * DEPTH * (1.0 if omni else 0.5)
                    assert f @ across == pytest.approx(expected, rel=0.05)
                    if not omni:
                        tip = T[:3, 3] + L * z
                        moment_at_tip = out.wrench[3:] - np.cross(tip - T[:3, 3], f)
                        assert np.abs(moment_at_tip).max() <= 1e-4  # of L f = 0.12 N m
            # pushed along the stylus, across the curve too: Kp on either device
            C2 = letter_curve(R, tip - DEPTH * z - R @ base.evaluate(u0))
            out = render(device, q, vm.CurveGuide(C2, L, normal=-z))
            assert -out.wrench[:3] @ z == pytest.approx(KP * DEPTH, rel=0.05)


def test_handle_path_holds_the_handle_on_the_curve(rng):
    dev = cartesian_device()
    C = letter_curve(t=np.array([0.0, 0.0, 0.05]))
    m = vm.HandlePath(C)
    for u0 in (0.15, 0.5, 0.9):
        tangent = C.tangent(u0)
        across = np.cross(tangent, [0.2, 0.3, 1.0])
        across /= np.linalg.norm(across)
        T = np.eye(4)
        T[:3, :3] = vm.so3_exp(0.3 * rng.standard_normal(3))
        T[:3, 3] = C.evaluate(u0) - DEPTH * across
        q = cartesian_q(T)
        out = render(dev, q, m)
        f = np.asarray(out.wrench[:3])
        assert f @ across == pytest.approx(KP * DEPTH, rel=0.05)
        assert abs(f @ tangent) <= 1e-6
        assert np.abs(out.wrench[3:]).max() <= 1e-6  # orientation free: no moment
