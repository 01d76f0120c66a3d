"""Active constraints: joint limits and unilateral contact rendered with Kp, Kv; eq. 26's
range force at singular probe poses; implausible joint values as a fault.

Expected values are closed forms of the geometry (circle chords, tip heights), never the
controller's own output."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm

# [N/m] the Omni's default translational stiffness (also given to the Cartesian test device)
KP = vm.PhantomOmni().stiffness
KV = 1.0  # [N·s/m]
L = 0.1  # [m] probe length


def cartesian_device(max_force: float = 100.0) -> vm.Device:
    """A fully actuated PPPRRR device: its joints are the handle's position and XYZ angles."""
    joints = [vm.Joint("prismatic", a) for a in np.eye(3)]
    joints += [vm.Joint("revolute", a) for a in np.eye(3)]
    return vm.Device(joints, [True] * 6, stiffness=KP, damping=KV, max_force=max_force)


def xyz_angles(R: np.ndarray) -> np.ndarray:
    """a, b, c with R = Rx(a) Ry(b) Rz(c)."""
    b = np.arcsin(np.clip(R[0, 2], -1, 1))
    return np.array([np.arctan2(-R[1, 2], R[2, 2]), b, np.arctan2(-R[0, 1], R[0, 0])])


def cartesian_q(T: np.ndarray) -> np.ndarray:
    return np.r_[T[:3, 3], xyz_angles(T[:3, :3])]


def rot(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, float)
    return vm.so3_exp(axis / np.linalg.norm(axis) * angle)


# --- joint limits -------------------------------------------------------------------------


def limited_arm(R: float) -> vm.SerialChain:
    """One revolute joint about z with limits +-0.5 rad, the handle at radius R."""
    handle = np.eye(4)
    handle[0, 3] = R
    return vm.SerialChain(
        [vm.Joint("revolute", [0, 0, 1], lower=-0.5, upper=0.5)], handle=handle, length_scale=R
    )


def test_a_revolute_limit_is_rendered_with_the_constraint_stiffness():
    """One revolute joint with limits +-0.5 rad (a circle of radius R about z): beyond the
    limit the wrench along the circle points back inside with at least 0.9 Kp times the
    tangential error; inside, nothing."""
    R = 0.1
    c = vm.Controller(cartesian_device(), limited_arm(R), ramp_time_s=1e-3)
    for sign in (1.0, -1.0):
        for a in (0.6, 0.8):
            a = sign * a
            q = np.array([R * np.cos(a), R * np.sin(a), 0, 0, 0, a])
            out = c.step(q, np.zeros(6))
            tangent = np.array([-np.sin(a), np.cos(a), 0.0])
            limit = sign * 0.5
            chord = R * np.array([np.cos(limit) - np.cos(a), np.sin(limit) - np.sin(a), 0.0])
            tangential_error = abs(chord @ tangent)
            f_t = out.wrench[:3] @ tangent
            assert -sign * f_t >= 0.9 * KP * tangential_error, (a, f_t)
            assert out.active[0] and "fault" not in " ".join(out.status_names)
        for a in (0.4, 0.0, -0.45):
            q = np.array([R * np.cos(a), R * np.sin(a), 0, 0, 0, a])
            out = c.step(q, np.zeros(6))
            assert np.abs(out.wrench).max() <= 1e-9, (a, out.wrench)
            assert not out.active[0]


def test_a_limit_pushes_but_never_pulls():
    """Leaving a limit fast, damping would pull the handle back onto it: the limit lets go."""
    R = 0.1
    c = vm.Controller(cartesian_device(), limited_arm(R), ramp_time_s=1e-3)
    a, w = 0.501, -2.0  # 1 mrad past the limit, moving back inside at 2 rad/s
    q = np.array([R * np.cos(a), R * np.sin(a), 0, 0, 0, a])
    dq = np.array([-R * np.sin(a) * w, R * np.cos(a) * w, 0, 0, 0, w])
    out = c.step(q, dq)
    tangent = np.array([-np.sin(a), np.cos(a), 0.0])
    b = out.theta[0]  # the placement: on the limit
    twist = np.r_[R * np.array([-np.sin(b), np.cos(b), 0.0]), 0, 0, 1]  # the joint's motion
    assert out.wrench @ twist <= 1e-12  # no power toward the limit
    # held, damping would pull with Kv |v| = 0.2 N toward the limit; released: nothing
    assert out.wrench[:3] @ tangent <= 1e-3 * KV * R * abs(w)
    assert not out.active[0]


# --- unilateral contact -------------------------------------------------------------------


def plane_through_tip(T: np.ndarray, depth: float, tilt: float):
    """A plane whose normal is tilted by `tilt` from the stylus's tip-to-handle direction,
    placed so that the probe's tip (L along the stylus) is `depth` behind it."""
    z = T[:3, 2]
    n = rot(np.cross(z, [0.3, 1.0, 0.2]), tilt) @ -z
    tip = T[:3, 3] + L * z
    return tip + depth * n, n


@pytest.mark.parametrize("tilt_deg", [0.0, 3.0])
def test_unilateral_contact_on_a_fully_actuated_device(tilt_deg):
    """(On a steeply tilted plane a fully actuated device's nearest placement also turns the
    stylus, trading position for orientation error: the push is then less than Kp x depth
    and a moment joins it, as with a rigid stylus.)"""
    dev = cartesian_device()
    rng = np.random.default_rng(3)
    for _ in range(5):
        T = np.eye(4)
        T[:3, :3] = vm.so3_exp(rng.normal(size=3))
        T[:3, 3] = rng.uniform(-0.1, 0.1, 3)
        q = cartesian_q(T)
        for depth in (0.005, -0.005):
            point, n = plane_through_tip(dev.forward(q), depth, np.radians(tilt_deg))
            probe = vm.Probe(point, n, L, unilateral=True)
            c = vm.Controller(dev, probe, ramp_time_s=1e-3)
            out = c.step(q, np.zeros(6))
            commanded = out.wrench_null + out.wrench_range  # before clamps
            if depth > 0:  # behind the plane: pushed out with Kp x depth along n
                assert commanded[:3] @ n == pytest.approx(KP * depth, rel=0.05)
                assert out.active[2]  # the lift-off joint is on its bound
            else:  # in front: the mechanism follows, no force from either term
                assert np.abs(out.wrench_null).max() <= 1e-9
                assert np.abs(out.wrench_range).max() <= 1e-9
                assert np.abs(out.wrench).max() <= 1e-9


OMNI_POSES = [
    np.array([0.0, 0.3, 0.0, 0.0, 0.5, 0.0]),
    np.array([0.2, 0.5, 0.3, 0.1, 0.7, 0.3]),
    np.array([-0.4, 0.9, -0.2, -0.3, 0.2, -1.0]),
]


@pytest.mark.parametrize("tilt_deg", [0.0, 3.0, 20.0])
def test_unilateral_contact_on_the_omni(tilt_deg):
    """The Omni cannot render moments; the plane's push comes through eq. 26 all the same."""
    omni = vm.PhantomOmni()
    for q in OMNI_POSES:
        for depth in (0.005, -0.005):
            point, n = plane_through_tip(omni.forward(q), depth, np.radians(tilt_deg))
            c = vm.Controller(omni, vm.Probe(point, n, L, unilateral=True), ramp_time_s=1e-3)
            out = c.step(q, np.zeros(6))
            commanded = out.wrench_null + out.wrench_range - out.wrench_unrendered
            if depth > 0:
                # the tip is `depth` behind along n: pushed back along n with Kp x depth
                assert commanded[:3] @ n == pytest.approx(KP * depth, rel=0.05), (q, tilt_deg)
            else:
                assert np.abs(out.wrench_null).max() <= 1e-9
                assert np.abs(out.wrench_range).max() <= 1e-9
                assert np.abs(out.wrench).max() <= 1e-9
            assert "not_converged" not in out.status_names
            assert np.all(out.torque[3:] == 0.0)


def test_unilateral_option_on_pivot_and_line():
    """PointPivot and LineGuide lift off along their normal the same way."""
    dev = cartesian_device()
    T = np.eye(4)
    T[:3, :3] = rot([1, 0, 0], np.pi)  # stylus straight down (-z)
    T[:3, 3] = [0.0, 0.0, L]  # tip at the origin
    q = cartesian_q(T)
    for depth in (0.004, -0.004):
        for mech in (
            vm.PointPivot([0, 0, depth], [0, 0, 1], L, unilateral=True),
            vm.LineGuide([0, 0, depth], [1, 0, 0], L, [0, 0, 1], unilateral=True),
        ):
            out = vm.Controller(dev, mech, ramp_time_s=1e-3).step(q, np.zeros(6))
            if depth > 0:
                assert out.wrench[2] == pytest.approx(KP * depth, rel=1e-6)
            else:
                assert np.abs(out.wrench).max() <= 1e-9


# --- eq. 26's range force at singular probe poses -----------------------------------------


@pytest.mark.parametrize("delta_deg", [0.5, 2.0, 5.0])
@pytest.mark.parametrize("tremble", [False, True])
def test_range_force_at_its_geometric_value_near_the_singular_pose(delta_deg, tremble):
    """Omni + Probe, the stylus turned by delta about the gimbal centre from the plane's
    normal, tip on the plane: eq. 26's force (range term and null-space term) is Kp (L cos
    delta - h) - Kv dh/dt along the normal on every cycle (h: the handle's height), and no
    cycle fails to converge. The handle held still, or trembling +-50 um along the normal
    (then it is a few um beyond the probe's reach half the time)."""
    omni = vm.PhantomOmni()
    q0 = np.array([0.1, 0.4, 0.2, 0.1, 0.6, 0.2])
    T0 = omni.forward(q0)
    z = T0[:3, 2]
    delta = np.radians(delta_deg)
    n = rot(np.cross(z, [0.2, 1.0, 0.4]), delta) @ -z
    point = T0[:3, 3] - L * n  # the perpendicular stylus would touch the plane here
    c = vm.Controller(omni, vm.Probe(point, n, L), ramp_time_s=1e-3)
    J0 = np.linalg.pinv(np.asarray(omni.jacobian(q0))[:3, :3])  # handle position -> motors
    for k in range(500):
        t = k * 1e-3
        w = 2 * np.pi * 7.0  # 7 Hz
        s, ds = 50e-6 * np.sin(w * t), 50e-6 * w * np.cos(w * t)
        if not tremble:
            s = ds = 0.0
        q = q0.copy()
        dq = np.zeros(6)
        q[:3] += J0 @ (s * n)
        dq[:3] = J0 @ (ds * n)
        out = c.step(q, dq)
        T = omni.forward(q)
        h = (T[:3, 3] - point) @ n
        cos_d = -T[:3, 2] @ n
        twist = np.asarray(omni.jacobian(q)) @ dq
        h_dot = twist[:3] @ n
        cos_d_dot = -np.cross(twist[3:], T[:3, 2]) @ n  # the arm turns the gimbal too
        expected = KP * (L * cos_d - h) + KV * (L * cos_d_dot - h_dot)
        # (near the singular pose the null-space term's soft rank renders a share of the
        # normal that the range term then leaves out: eq. 26's force is their sum)
        got = (out.wrench_range[:3] + out.wrench_null[:3]) @ n
        assert got == pytest.approx(expected, rel=1e-3, abs=1e-6), (k, got, expected)
        assert "not_converged" not in out.status_names


# --- implausible input --------------------------------------------------------------------


def test_joint_values_far_outside_the_range_are_a_fault_then_ramp_in():
    omni = vm.PhantomOmni()
    c = vm.Controller(omni, vm.PlanarArm([0, 0, -0.1], [0, 0, 1], 0.05), ramp_time_s=0.1)
    good = np.array([0.1, 0.5, 0.2, 0.0, 0.6, 0.0])
    for _ in range(200):
        out = c.step(good, np.zeros(6))
    assert out.ramp == 1.0 and np.abs(out.torque).max() > 0
    bad = good.copy()
    bad[0] = 50.0
    out = c.step(bad, np.zeros(6))
    assert "fault_out_of_range" in out.status_names and out.fault
    assert np.all(out.torque == 0.0) and np.all(out.wrench == 0.0)
    # a few degrees past a limit is not yet a fault (default margin 5 deg)
    edge = good.copy()
    edge[0] = omni.upper[0] + np.radians(4.0)
    assert not c.step(edge, np.zeros(6)).fault
    edge[0] = omni.upper[0] + np.radians(6.0)
    assert "fault_out_of_range" in c.step(edge, np.zeros(6)).status_names
    out = c.step(good, np.zeros(6))  # cleared: ramps in from zero
    assert not out.fault and 0.0 < out.ramp < 0.1


def test_range_margin_is_a_setting_checked_at_construction():
    omni = vm.PhantomOmni()
    mech = vm.PlanarArm([0, 0, -0.1], [0, 0, 1], 0.05)
    c = vm.Controller(omni, mech, range_margin_rad=0.0)
    assert np.allclose(c.model["q_max"], omni.upper) and np.allclose(c.model["q_min"], omni.lower)
    with pytest.raises(ValueError, match="range_margin_rad"):
        vm.Controller(omni, mech, range_margin_rad=-1.0)


def test_a_released_contact_lets_go_on_the_omni():
    """On the Omni the plane's push comes through eq. 26's range term. Leaving the plane
    faster than Kp depth / Kv, damping would pull the handle back: the contact lets go
    entirely (the spring too), as a lifted probe must."""
    omni = vm.PhantomOmni()
    q0 = np.array([0.1, 0.4, 0.2, 0.1, 0.6, 0.2])
    T0 = omni.forward(q0)
    n = -T0[:3, 2]  # the stylus along the normal, the tip `depth` behind the plane
    depth = 0.002
    probe = vm.Probe(T0[:3, 3] - L * n + depth * n, n, L, unilateral=True)
    to_motors = np.linalg.pinv(np.asarray(omni.jacobian(q0))[:3, :3])
    pushes = []
    for v in (0.0, 0.3, 0.6, 0.9, 0.99, 1.01, 1.5, 3.0):  # [m/s] out of the plane
        # the law alone: a fresh passivity observer has banked nothing to give back
        c = vm.Controller(omni, probe, ramp_time_s=1e-3, passivity="off")
        dq = np.zeros(6)
        dq[:3] = to_motors @ (v * n)
        f_n = c.step(q0, dq).wrench[:3] @ n
        expected = max(0.0, KP * depth - KV * v)  # a spring-damper that only pushes
        assert f_n == pytest.approx(expected, abs=1e-9), (v, f_n)
        pushes.append(f_n)
    assert all(a >= b - 1e-12 for a, b in zip(pushes, pushes[1:]))  # never rises as it leaves


def test_a_joint_fixed_by_equal_limits_holds_from_both_sides():
    R = 0.1
    handle = np.eye(4)
    handle[0, 3] = R
    fixed = vm.SerialChain(
        [vm.Joint("revolute", [0, 0, 1], lower=0.3, upper=0.3)], handle=handle, length_scale=R
    )
    c = vm.Controller(cartesian_device(), fixed, ramp_time_s=1e-3)
    for a in (0.5, 0.1):
        q = np.array([R * np.cos(a), R * np.sin(a), 0, 0, 0, a])
        out = c.step(q, np.zeros(6))
        tangent = np.array([-np.sin(a), np.cos(a), 0.0])
        chord = R * np.array([np.cos(0.3) - np.cos(a), np.sin(0.3) - np.sin(a), 0.0])
        f_t = out.wrench[:3] @ tangent
        assert np.sign(f_t) == np.sign(chord @ tangent)  # back toward 0.3
        assert abs(f_t) >= 0.9 * KP * abs(chord @ tangent), (a, f_t)
        assert out.active[0]


def test_a_faulted_cycle_reports_nothing_of_the_last_one():
    omni = vm.PhantomOmni()
    c = vm.Controller(omni, vm.Probe([0, -0.05, 0], [0, 1, 0], L), ramp_time_s=1e-3)
    out = vm.CycleOutput()
    q = np.array([0.1, 0.5, 0.2, 0.0, 0.6, 0.0])
    c.step(q, np.zeros(6), out=out)
    assert np.abs(out.error).max() > 0 and out.residual > 0
    bad = q.copy()
    bad[2] = np.nan
    c.step(bad, np.zeros(6), out=out)
    assert out.fault
    assert np.all(out.error == 0) and np.all(out.error_star == 0) and np.all(out.error_dot == 0)
    assert np.array_equal(out.handle_pose, np.eye(4))
    assert np.array_equal(out.mechanism_pose, np.eye(4))
    assert out.residual == 0 and out.iterations == 0 and not out.active.any()
    assert np.all(np.isfinite(out.theta)) and np.all(out.torque == 0)


def test_a_nonfinite_result_gives_home_placements_not_nan():
    dev = cartesian_device()
    c = vm.Controller(dev, vm.PointPivot([0, 0, 0], [0, 0, 1], L), ramp_time_s=1e-3)
    out = c.step(np.array([1e308, 0, 0, 0, 0, 0]), np.zeros(6))  # finite, absurd
    assert "fault_nonfinite_output" in out.status_names
    assert np.all(np.isfinite(out.theta)) and np.all(out.torque == 0)
