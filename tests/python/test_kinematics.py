"""Forward kinematics and Jacobians of every mechanism and device, through Python."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
from conftest import numeric_jacobian, random_within, six_dof_arm

n = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)

MECHANISMS = {
    "PlanarArm": lambda: vm.PlanarArm([0.1, -0.2, 0.3], n, 0.12),
    "Probe": lambda: vm.Probe([0.0, 0.01, -0.05], n, 0.1),
    "PointPivot": lambda: vm.PointPivot([0.0, 0.0, 0.0], [0, 1, 0], 0.08),
    "LineGuide": lambda: vm.LineGuide([0.02, 0, 0], [1, 0, 0], 0.09, normal=[0, 1, 0]),
    "SerialChain": lambda: vm.SerialChain(
        [
            vm.Joint("prismatic", [1, 1, 0]),
            vm.Joint("revolute", [0, 0, 1], [0.1, 0, 0]),
            vm.Joint("revolute", [0, 1, 0], [0, 0.05, 0]),
        ],
        handle=np.array([[1, 0, 0, 0.05], [0, 1, 0, 0.02], [0, 0, 1, 0.01], [0, 0, 0, 1.0]]),
    ),
}
DEVICES = {
    "PhantomOmni": vm.PhantomOmni,
    "PhantomOmniOffsets": lambda: vm.PhantomOmni(
        gimbal_offset=[0.3, -0.2, 1.0], gimbal_sign=[-1, 1, -1]
    ),
    "Planar3R": lambda: vm.Planar3R(0.2, 0.15),
    "Arm6R": six_dof_arm,
}


@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_mechanism_jacobian_matches_central_differences(name, rng):
    m = MECHANISMS[name]()
    for _ in range(30):
        x = random_within(rng, m.lower, m.upper, 1.2)
        J = m.jacobian(x)
        assert J.shape == (6, m.dof)
        np.testing.assert_allclose(J, numeric_jacobian(m.forward, x), atol=1e-7)


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_device_jacobian_matches_central_differences(name, rng):
    d = DEVICES[name]()
    for _ in range(30):
        q = random_within(rng, d.lower, d.upper, 1.5)
        np.testing.assert_allclose(d.jacobian(q), numeric_jacobian(d.forward, q), atol=1e-7)


def test_planar_arm_is_equation_2():
    L = 0.1
    arm = vm.PlanarArm([0, 0, 0], [0, 0, 1], L, [1, 0, 0])
    for th in np.linspace(-3, 3, 25):
        T = arm.forward([th])
        np.testing.assert_allclose(T[:3, 3], [L * np.cos(th), L * np.sin(th), 0], atol=1e-15)
        # orientation theta about the normal, relative to theta = 0
        w = vm.so3_log(T[:3, :3] @ arm.forward([0.0])[:3, :3].T)
        np.testing.assert_allclose(w, [0, 0, th], atol=1e-12)
        # stylus from the handle to the pivot (the probe tip rests at the pivot)
        np.testing.assert_allclose(T[:3, 2], -T[:3, 3] / L, atol=1e-15)


def test_omni_gimbal_centre_is_the_published_formula(rng):
    omni = vm.PhantomOmni()
    l1, l2 = omni.l1, omni.l2
    assert l1 == pytest.approx(0.13335) and l2 == pytest.approx(0.13335)
    for _ in range(200):
        q = random_within(rng, omni.lower, omni.upper)
        t1, t2, t3 = q[:3]
        expected = [
            -np.sin(t1) * (l1 * np.cos(t2) + l2 * np.sin(t3)),
            l1 * np.sin(t2) - l2 * np.cos(t3) + l2,
            -l1 + np.cos(t1) * (l1 * np.cos(t2) + l2 * np.sin(t3)),
        ]
        np.testing.assert_allclose(omni.forward(q)[:3, 3], expected, atol=1e-14)


def test_omni_actuation_and_limits():
    omni = vm.PhantomOmni()
    assert omni.dof == 6
    assert omni.actuated.tolist() == [True, True, True, False, False, False]
    assert omni.max_force == pytest.approx(3.3)
    np.testing.assert_allclose(omni.lower[:3], [-0.98, 0.0, -0.81])
    np.testing.assert_allclose(omni.upper[:3], [0.98, 1.75, 1.25])
    assert np.all(omni.torque_limit[3:] == 0.0)


def test_gimbal_offset_and_sign_map_driver_angles():
    plain, mapped = (
        vm.PhantomOmni(),
        vm.PhantomOmni(gimbal_offset=[0.3, -0.2, 1.0], gimbal_sign=[-1, 1, -1]),
    )
    q = np.array([0.1, 0.4, 0.2, 0.25, 0.5, -0.3])
    driver = q.copy()
    driver[3:] = np.array([-1, 1, -1]) * q[3:] + [0.3, -0.2, 1.0]
    np.testing.assert_allclose(mapped.forward(driver), plain.forward(q), atol=1e-15)


@pytest.mark.parametrize(
    "make",
    [
        vm.PhantomOmni,
        lambda: vm.Probe([0, 0, -0.05], [0, 0, 1], 0.1),
        lambda: vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1),
    ],
)
def test_forward_many_is_forward_row_by_row(make):
    kin = make()
    rng = np.random.default_rng(4)
    X = np.array([random_within(rng, kin.lower, kin.upper) for _ in range(9)])
    poses = kin.forward_many(X)
    assert poses.shape == (9, 4, 4)
    for x, T in zip(X, poses):
        np.testing.assert_array_equal(T, kin.forward(x))
    assert kin.forward_many(np.zeros((0, kin.dof))).shape == (0, 4, 4)
    with pytest.raises(ValueError, match=rf"X: expected an array of shape \(m, {kin.dof}\)"):
        kin.forward_many(np.zeros((3, kin.dof + 1)))
