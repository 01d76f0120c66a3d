"""The control laws (eqs. 11 and 26) and the safety layer, through the Python API."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

import virtmech as vm
from conftest import random_within, six_dof_arm


def planar3r_ik(l1, l2, x, y, phi):
    c = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    q1 = np.arccos(np.clip(c, -1, 1))
    q0 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(q1), l1 + l2 * np.cos(q1))
    return np.array([q0, q1, phi - q0 - q1])


def ik(device, T, q0, steps=20):
    """Joint values of a fully actuated device whose handle is at T, by continuation from
    q0 along the straight path (in pose-error space) from the handle's pose there."""
    T0 = device.forward(q0)
    e0 = vm.pose_error(T, T0)
    q = np.asarray(q0, dtype=float)
    for s in np.linspace(0, 1, steps + 1)[1:]:
        Ts = np.eye(4)
        Ts[:3, 3] = T0[:3, 3] + s * e0[:3]
        Ts[:3, :3] = vm.so3_exp(s * e0[3:]) @ T0[:3, :3]
        q = least_squares(
            lambda x, Ts=Ts: vm.pose_error(Ts, device.forward(x)),
            q,
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
        ).x
    assert np.linalg.norm(vm.pose_error(T, device.forward(q))) < 1e-10
    return q


@pytest.fixture
def omni():
    return vm.PhantomOmni()


def test_passive_joint_torques_are_exactly_zero(omni, rng):
    mechanisms = [
        vm.Probe([0, -0.05, 0], [0, 1, 0], 0.1),
        vm.PlanarArm([0, 0, -0.1], [0, 0, 1], 0.05),
        vm.PointPivot([0, -0.05, -0.1], [0, 1, 0], 0.1),
        vm.LineGuide([0, -0.05, -0.05], [1, 0, 0], 0.1, normal=[0, 1, 0]),
    ]
    for m in mechanisms:
        c = vm.Controller(omni, m, ramp_time_s=1e-3, passivity="off")  # unrelated poses: the laws
        for _ in range(200):
            out = c.step(random_within(rng, omni.lower, omni.upper), rng.normal(size=6))
            assert not out.fault
            assert np.all(out.torque[3:] == 0.0)
            assert np.any(out.torque[:3] != 0.0)
            assert np.isfinite(out.torque).all()


class PlanarScene:
    """Planar3R and the circle of radius R about `pivot` in its plane (paper Figs. 4, 8)."""

    l1 = l2 = 0.2
    R = 0.1
    pivot = np.array([0.25, 0.0, 0.0])

    def __init__(self, **settings):
        self.robot = vm.Planar3R(self.l1, self.l2, torque_limit=50.0, max_force=100.0)
        self.arm = vm.PlanarArm(self.pivot, [0, 0, 1], self.R, [1, 0, 0])
        self.controller = vm.Controller(self.robot, self.arm, ramp_time_s=1e-3, **settings)

    def q(self, r, alpha, beta):
        """Handle at angle alpha, radius r about the pivot; stylus as the arm's at beta."""
        p = self.pivot + r * np.array([np.cos(alpha), np.sin(alpha), 0])
        return planar3r_ik(self.l1, self.l2, p[0], p[1], beta + np.pi)

    def point(self, angle):
        return self.pivot + self.R * np.array([np.cos(angle), np.sin(angle), 0])


@pytest.mark.parametrize("alpha", [-0.8, 0.1, 1.0])
@pytest.mark.parametrize("delta", [-0.4, 0.25])
@pytest.mark.parametrize("radius_offset", [0.0, 0.01, -0.01])
def test_under_actuated_wrench_pulls_toward_mechanism_at_handle_angle(alpha, delta, radius_offset):
    """Section V: W_e* on the un-powered joint places the mechanism at the handle's own
    angle; the wrench pulls the handle toward that point of the circle."""
    s = PlanarScene()
    out = s.controller.step(s.q(s.R + radius_offset, alpha, alpha + delta), np.zeros(3))
    assert out.theta_star[0] == pytest.approx(alpha + delta, abs=1e-6)
    assert out.theta[0] == pytest.approx(alpha, abs=1e-4)  # nearest: the handle's position
    f = out.wrench[:3]
    to_target = s.point(alpha + delta) - out.handle_pose[:3, 3]
    assert f @ to_target > 0.8 * np.linalg.norm(f) * np.linalg.norm(to_target)
    assert out.torque[2] == 0.0
    # the applied force is the two filtered parts, and it has no moment about the normal
    assert abs(out.wrench[5]) < 1e-12


def test_null_space_law_leaves_handle_angle_free():
    """Fig. 9: with eq. 9/11 alone, a handle on the circle but twisted feels no force."""
    s = PlanarScene(law="null_space")
    for delta in [-0.6, 0.3, 1.2]:
        out = s.controller.step(s.q(s.R, 0.2, 0.2 + delta), np.zeros(3))
        assert np.linalg.norm(out.wrench) < 1e-9
    # ... while leaving the circle is resisted with the stiffness Kp
    out = s.controller.step(s.q(s.R + 0.002, 0.2, 0.7), np.zeros(3))
    radial = np.array([np.cos(0.2), np.sin(0.2), 0])
    # (the secondary weight, 1e-6, tilts the nearest placement by a part in 1e6)
    np.testing.assert_allclose(out.wrench[:3], -500.0 * 0.002 * radial, rtol=1e-5, atol=1e-8)


def test_fully_actuated_device_free_along_mechanism_stiff_across():
    arm6 = six_dof_arm()
    q0 = np.array([0.2, -0.4, 0.9, 0.3, 0.7, -0.2])
    T0 = arm6.forward(q0)
    L = 0.08
    mech = vm.PlanarArm(T0[:3, 3] + L * T0[:3, 2], T0[:3, 1], L, -T0[:3, 2])
    c = vm.Controller(arm6, mech, ramp_time_s=1e-3)
    assert c.model["law"] == "auto" and not c.model["under_actuated_term"]
    np.testing.assert_allclose(c.model["kp"], [800] * 3 + [800 * L * L] * 3)
    assert np.linalg.norm(c.step(q0, np.zeros(6)).wrench) < 1e-9
    for th in [0.05, -0.3, -0.7]:  # (+0.4 would stretch the arm out of reach)
        q = ik(arm6, mech.forward([th]), q0)
        assert np.linalg.norm(c.step(q, np.zeros(6)).wrench) < 1e-7
        # moving along the mechanism meets no damping either
        dq = np.linalg.lstsq(arm6.jacobian(q), mech.jacobian([th])[:, 0] * 0.5, rcond=None)[0]
        assert np.linalg.norm(c.step(q, dq).wrench) < 1e-7
    c.reset()  # (the last pose is beyond a joint's range: a fault, whose ramp-in takes 50 ms)
    kp = c.model["kp"]
    radial, normal = -T0[:3, 2], T0[:3, 1]
    d = 1e-3
    for push, expected in [
        (("t", radial), np.r_[-kp[0] * d * radial, 0, 0, 0]),
        (("t", normal), np.r_[-kp[0] * d * normal, 0, 0, 0]),
        (("r", radial), np.r_[0, 0, 0, -kp[3] * d * radial]),
    ]:
        T = T0.copy()
        if push[0] == "t":
            T[:3, 3] += d * push[1]
        else:
            T[:3, :3] = vm.so3_exp(d * push[1]) @ T0[:3, :3]
        out = c.step(ik(arm6, T, q0), np.zeros(6))
        np.testing.assert_allclose(out.wrench, expected, atol=1e-3 * np.linalg.norm(expected))


def test_damping_opposes_leaving_the_mechanism_only():
    s = PlanarScene()
    q = s.q(s.R, 0.3, 0.3)
    J = s.robot.jacobian(q)
    t = np.array([-np.sin(0.3), np.cos(0.3), 0])
    r = np.array([np.cos(0.3), np.sin(0.3), 0])
    # a velocity straight out of the circle is damped with Kv
    dq_out = np.linalg.lstsq(J[[0, 1, 5]], np.r_[0.1 * r[:2], 0.0], rcond=None)[0]
    out = s.controller.step(q, dq_out)
    np.testing.assert_allclose(out.wrench[:3] @ r, -2.0 * 0.1, rtol=1e-6)
    # moving along the circle with the handle turning with it meets nothing
    dq_along = np.linalg.lstsq(J[[0, 1, 5]], np.r_[0.1 * t[:2], 0.1 / s.R], rcond=None)[0]
    out = s.controller.step(q, dq_along)
    assert np.linalg.norm(out.wrench) < 1e-9


def test_fuzzed_inputs_never_give_nonfinite_or_over_limit_torques(omni, rng):
    c = vm.Controller(omni, vm.Probe([0, -0.05, 0], [0, 1, 0], 0.1), ramp_time_s=1e-3)
    specials = [np.nan, np.inf, -np.inf, 1e300, -1e300, 1e12, 0.0, 40.0]
    for k in range(5000):
        q, dq = rng.normal(scale=2.0, size=6), rng.normal(scale=20.0, size=6)
        if k % 2:
            (q if k % 4 == 1 else dq)[rng.integers(6)] = specials[rng.integers(len(specials))]
        out = c.step(q, dq)
        assert np.isfinite(out.torque).all() and np.isfinite(out.wrench).all()
        assert np.all(np.abs(out.torque) <= omni.torque_limit * (1 + 1e-12))
        assert np.linalg.norm(out.wrench[:3]) <= omni.max_force * (1 + 1e-12)
        if not (np.isfinite(q).all() and np.isfinite(dq).all()):
            assert out.fault and "fault_nonfinite_input" in out.status_names
            assert np.all(out.torque == 0.0)


def test_ramp_in_bounds_first_cycles(omni):
    c = vm.Controller(omni, vm.PlanarArm([0, 0, -0.05], [0, 0, 1], 0.05), ramp_time_s=0.05)
    n = c.model["ramp_cycles"]
    assert n == 50
    q = np.array([0.3, 0.9, 0.6, 0.0, 0.5, 0.0])  # far from the circle: saturating force
    forces = [np.linalg.norm(c.step(q, np.zeros(6)).wrench[:3]) for _ in range(80)]
    for k, f in enumerate(forces, start=1):
        assert f <= omni.max_force * min(1.0, k / n) * (1 + 1e-12)
    assert forces[-1] == pytest.approx(omni.max_force)


def test_outputs_are_complete_and_consistent(omni):
    arm = vm.PlanarArm([0, 0, -0.1], [0, 0, 1], 0.05)
    c = vm.Controller(omni, arm, ramp_time_s=1e-3)
    q = np.array([0.1, 0.5, 0.2, 0.1, 0.6, 0.0])
    out = c.step(q, np.zeros(6))
    np.testing.assert_allclose(out.handle_pose, omni.forward(q), atol=1e-15)
    np.testing.assert_allclose(out.mechanism_pose, arm.forward(out.theta), atol=1e-15)
    np.testing.assert_allclose(
        out.error, vm.pose_error(out.mechanism_pose, out.handle_pose), atol=1e-15
    )
    commanded = out.wrench_null + out.wrench_range + out.wrench_passivity
    applied = (commanded - out.wrench_unrendered) * out.limit_scale * out.ramp
    np.testing.assert_allclose(out.wrench, applied, atol=1e-12)
    np.testing.assert_allclose(out.torque, omni.jacobian(q).T @ out.wrench, atol=1e-12)
    assert out.computation_time_us > 0.0
    assert c.last.status == out.status


def test_bad_arguments_name_parameter_value_and_expectation(omni):
    arm = vm.PlanarArm([0, 0, -0.1], [0, 0, 1], 0.05)
    cases = [
        (lambda: vm.PlanarArm([0, 0], [0, 0, 1], 0.1), ValueError, r"pivot.*shape \(3,\).*\(2,\)"),
        (lambda: vm.PlanarArm([0, 0, 0], [0, 0, 2], 0.1), ValueError, r"normal.*unit.*2"),
        (lambda: vm.PlanarArm([0, 0, 0], [0, 0, 0], 0.1), ValueError, r"normal"),
        (lambda: vm.PlanarArm([0, 0, 0], [0, 0, 1], -1.0), ValueError, r"length.*> 0.*-1"),
        (lambda: vm.Probe([0, 0, 0], [0, 0, 1], 0.0), ValueError, r"length.*> 0.*0"),
        (lambda: vm.Controller(omni, arm, kp=[1, 2, 3]), ValueError, r"kp.*\(6,\).*\(3,\)"),
        (lambda: vm.Controller(omni, arm, kv=[1, 1, 1, 1, 1, -2]), ValueError, r"kv.*>= 0.*-2"),
        (lambda: vm.Controller(omni, arm, period_s=0.0), ValueError, r"period_s.*> 0"),
        (lambda: vm.Controller(omni, arm, law="pd"), ValueError, r"law.*'pd'"),
        (
            lambda: vm.Controller(omni, arm).step(np.zeros(5), np.zeros(6)),
            ValueError,
            r"q.*\(6,\).*\(5,\)",
        ),
        (lambda: vm.Planar3R(link1=-0.2), ValueError, r"link1.*-0.2"),
        (lambda: vm.Joint("helical"), ValueError, r"type.*helical"),
        (lambda: vm.PlanarArm("abc", [0, 0, 1], 0.1), TypeError, r"pivot"),
    ]
    for make, exc, pattern in cases:
        with pytest.raises(exc, match=pattern):
            make()
