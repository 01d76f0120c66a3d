"""The ROS 2 node's joint map and its Cartesian force, without a middleware: the Touch drivers'
joints from OpenHaptics' as the reference's formulas say, checked against the public Omni
URDF's chain built here by hand (positions and, through virtual work, efforts), the map's
checks of its parameters, and the handle force that gives the commanded motor torques."""

from __future__ import annotations

import math

import numpy as np
import pytest

import virtmech as vm
from virtmech.ros2.joint_map import TOUCH_JOINTS, JointMap, default_map, touch_map
from virtmech.ros2.render import (
    TOUCH_FORCE_ROTATION,
    HandleWrench,
    VelocityEstimate,
    default_parameters,
    settings_from_parameters,
)

# ---------------------------------------------------------------------------------------
# the public Omni URDF (omni_description/urdf/omni.urdf of the Touch's ROS 2 driver),
# joint by joint: origin xyz [m], origin rpy [rad], axis


URDF_JOINTS = [
    ((0.0, 0.0, 0.09), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),  # waist
    ((-0.0075, 0.0, 0.035), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),  # shoulder
    ((0.0075, 0.134, 0.0), (-1.5, 0.0, 0.0), (1.0, 0.0, 0.0)),  # elbow
    ((0.0, 0.08, 0.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),  # yaw
    ((0.0, 0.0525, 0.0), (0.5, 0.0, 0.0), (1.0, 0.0, 0.0)),  # pitch
    ((0.0, -0.023, 0.0), (3.14159, 3.14159, 0.0), (0.0, 1.0, 0.0)),  # roll
]
#: the URDF's arm lengths: the elbow 0.134 m from the shoulder, the gimbal centre (the pitch
#: joint's origin) 0.08 + 0.0525 m from the elbow
L1, L2 = 0.134, 0.1325
#: the URDF's elbow turns by -1.5 rad where the Jarillo-Silva geometry has -pi/2: its angle
#: reads t3 - t2 + (1.5 - pi/2) for the same arm (the reference, "Public Omni descriptions")
ELBOW_URDF_OFFSET = 1.5 - math.pi / 2


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _axis_angle(axis, a: float) -> np.ndarray:
    k = np.asarray(axis, dtype=float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def urdf_gimbal_centre(r) -> np.ndarray:
    """The pitch joint's origin (where the gimbal's axes meet) in the URDF's base frame, at the
    URDF joint angles r (waist, shoulder, elbow, ...)."""
    R, p = np.eye(3), np.zeros(3)
    for (xyz, rpy, axis), a in list(zip(URDF_JOINTS, r))[:5]:
        p = p + R @ np.asarray(xyz)
        R = R @ _rpy(*rpy) @ _axis_angle(axis, a)
    return p


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The rotation R (det +1) and translation t with P ~ R Q + t, and the largest residual."""
    Pc, Qc = P - P.mean(0), Q - Q.mean(0)
    U, _, Vt = np.linalg.svd(Pc.T @ Qc)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    t = P.mean(0) - R @ Q.mean(0)
    return R, t, float(np.abs(P - (Q @ R.T + t)).max())


def random_q(rng, omni, count: int) -> np.ndarray:
    return rng.uniform(omni.lower, omni.upper, (count, 6))


# ---------------------------------------------------------------------------------------


def test_touch_map_is_the_drivers_formulas():
    """omni_state.cpp: waist = -t1, shoulder = t2, elbow = t3 - t2, yaw = pi - g1,
    pitch = -g2 - 3 pi / 4, roll = -g3 - pi; and back, exactly up to rounding."""
    m = touch_map()
    assert m.names == ("waist", "shoulder", "elbow", "yaw", "pitch", "roll")
    rng = np.random.default_rng(31)
    for t1, t2, t3, g1, g2, g3 in rng.uniform(-3, 3, (200, 6)):
        expected = [-t1, t2, t3 - t2, math.pi - g1, -g2 - 3 * math.pi / 4, -g3 - math.pi]
        r = m.driver_positions([t1, t2, t3, g1, g2, g3])
        np.testing.assert_allclose(r, expected, rtol=0, atol=1e-15)
        np.testing.assert_allclose(m.device_positions(expected), [t1, t2, t3, g1, g2, g3],
                                   rtol=0, atol=4e-15)


def test_touch_map_against_the_urdf_chain():
    """The driver's joint angles of a pose, through the public URDF's chain, put the gimbal
    centre where virtmech's Omni (with the URDF's arm lengths) puts it for the mapped joints,
    one rigid motion apart at every pose (a wrong sign or a missing elbow term would need a
    mirror or would not fit at all)."""
    m = touch_map()
    omni = vm.PhantomOmni(l1=L1, l2=L2)
    Q = random_q(np.random.default_rng(7), omni, 60)
    P_urdf, P_vm = [], []
    for q in Q:
        r = m.driver_positions(q)
        r[2] += ELBOW_URDF_OFFSET
        P_urdf.append(urdf_gimbal_centre(r))
        P_vm.append(omni.forward(q)[:3, 3])
    R, t, residual = kabsch(np.array(P_urdf), np.array(P_vm))
    assert residual < 1e-12
    assert np.linalg.det(R) == pytest.approx(1.0)
    # the URDF's base: z up (OpenHaptics' y), y toward the user (OpenHaptics' z): roll pi/2
    # then yaw pi, virtmech's origin at (0, 0.134, -0.0075) m (docs/ros2.md, "RViz")
    np.testing.assert_allclose(R, [[-1, 0, 0], [0, 0, 1], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(R, _rpy(math.pi / 2, 0.0, math.pi), atol=1e-12)
    np.testing.assert_allclose(t, [0.0, 0.134, -0.0075], atol=1e-12)


def test_touch_efforts_do_the_work_of_the_device_torques():
    """A force F at the gimbal centre: the driver's efforts from the device's torques J^T F
    (through the map's transpose) are the URDF's own J_urdf^T F, with J_urdf by central
    differences of the URDF chain: every sign of the efforts checked independently."""
    m = touch_map()
    omni = vm.PhantomOmni(l1=L1, l2=L2)
    R = np.array([[-1.0, 0, 0], [0, 0, 1], [0, 1, 0]])  # the URDF's axes (test above)
    rng = np.random.default_rng(11)
    h = 1e-6
    for q in random_q(rng, omni, 20):
        F = rng.normal(size=3)
        tau = omni.jacobian(q)[:3].T @ F
        efforts = m.driver_efforts(tau)
        r = m.driver_positions(q)
        r[2] += ELBOW_URDF_OFFSET
        J = np.zeros((3, 6))
        for j in range(6):
            d = np.zeros(6)
            d[j] = h
            J[:, j] = (urdf_gimbal_centre(r + d) - urdf_gimbal_centre(r - d)) / (2 * h)
        np.testing.assert_allclose(efforts, J.T @ (R @ F), rtol=0, atol=1e-8)


def test_touch_force_axes_are_the_drivers():
    """omni_state.cpp sends a force (fx, fy, fz) to OpenHaptics as (fx, fz, -fy): the node's
    force_feedback axes give back the force in OpenHaptics' axes that way."""
    R = np.array(TOUCH_FORCE_ROTATION)
    F_hd = np.array([0.3, -1.2, 2.5])
    fx, fy, fz = R @ F_hd
    np.testing.assert_array_equal([fx, fz, -fy], F_hd)


def test_handle_force_gives_the_commanded_motor_torques():
    """The force_feedback force, applied at the gimbal centre as OpenHaptics applies
    HD_CURRENT_FORCE, gives the three motors the commanded torques; the gimbal's none."""
    omni = vm.PhantomOmni()
    hw = HandleWrench(omni, np.array(TOUCH_FORCE_ROTATION))
    rng = np.random.default_rng(5)
    for q in random_q(rng, omni, 20):
        tau = np.concatenate([rng.normal(size=3) * 0.1, rng.normal(size=3)])
        w = hw(q, tau)
        assert np.all(w[3:] == 0.0)
        F_hd = np.array(TOUCH_FORCE_ROTATION).T @ w[:3]
        np.testing.assert_allclose(omni.jacobian(q)[:3, :3].T @ F_hd, tau[:3], atol=1e-12)


def test_default_maps():
    omni = vm.PhantomOmni()
    assert default_map(omni).names == TOUCH_JOINTS
    arm = vm.Planar3R()
    m = default_map(arm)
    assert m.names == ("joint1", "joint2", "joint3")
    np.testing.assert_array_equal(m.matrix, np.eye(3))
    # ros2_control's effort controller: the actuated joints, in order
    assert touch_map().effort_joints(omni.actuated) == [0, 1, 2]
    assert m.effort_joints(arm.actuated) == list(np.flatnonzero(arm.actuated))


@pytest.mark.parametrize(
    "change, message",
    [
        ({"joint_names": ["a", "b"]}, "joint_names: expected 6 names"),
        ({"joint_names": ["a", "a", "b", "c", "d", "e"]}, "joint_names: each name once, got a"),
        ({"joint_map": [1.0, 0.0]}, "joint_map: expected 36 numbers (a 6 x 6 matrix"),
        ({"joint_map": [0.0] * 36}, "joint_map: expected an invertible matrix"),
        ({"joint_offsets": [0.0] * 5}, "joint_offsets: expected 6 numbers, got 5"),
        ({"watchdog_s": -1.0}, "watchdog_s: expected a number > 0, got -1.0"),
        ({"watchdog_s": 0.0005}, "watchdog_s: expected more than the period (0.001 s)"),
        ({"watchdog_s": "soon"}, "watchdog_s: expected a number, got 'soon'"),
        ({"velocity_cutoff_hz": -3}, "velocity_cutoff_hz: expected a number >= 0, got -3"),
        ({"force_rotation": [1.0] * 9}, "force_rotation: expected a rotation matrix"),
        ({"use_message_velocity": "yes"}, "use_message_velocity: expected true or false"),
    ],
)
def test_bad_parameters_are_named(change, message):
    from virtmech.builder import build

    rig = build("omni-fig11", simulated=False)
    values = {**default_parameters(rig), **change}
    with pytest.raises(ValueError) as e:
        settings_from_parameters(values, rig.device)
    assert message in str(e.value)


def test_parameters_from_the_scenario():
    """The period and the velocity filter's cut-off default to the scenario's."""
    from virtmech import scenarios as sc
    from virtmech.builder import build

    s = sc.load("omni-fig11").with_keys(
        {"controller.period_s": 0.002, "sensors.velocity_cutoff_hz": 40.0}
    )
    rig = build(s, simulated=False)
    settings, jmap = settings_from_parameters(default_parameters(rig), rig.device)
    assert settings.period_s == 0.002
    assert settings.velocity_cutoff_hz == 40.0
    assert jmap.names == TOUCH_JOINTS


def test_velocity_estimate_is_the_simulations_filter():
    """At a fixed period, dq += alpha ((q - q_last) / T - dq) with alpha = T / (T + 1/(2 pi f)):
    the sensors' filtered difference, written out here."""
    T, fc = 1e-3, 100.0
    alpha = T / (T + 1.0 / (2 * math.pi * fc))
    est = VelocityEstimate(2, fc)
    rng = np.random.default_rng(3)
    q_prev, dq = None, np.zeros(2)
    for _ in range(50):
        q = rng.normal(size=2)
        got = est.update(q, T).copy()
        if q_prev is not None:
            dq = dq + alpha * ((q - q_prev) / T - dq)
        q_prev = q
        np.testing.assert_allclose(got, dq, rtol=1e-13, atol=1e-12)


def test_joint_map_checked_builds_the_inverse():
    A = np.array([[2.0, 1.0], [0.0, 1.0]])
    m = JointMap.checked(["a", "b"], A.ravel(), [0.5, -0.5], 2)
    q = np.array([0.3, -0.7])
    np.testing.assert_allclose(m.device_positions(m.driver_positions(q)), q, atol=1e-15)
    # virtual work: tau_q . dq == tau_r . dr for any motion
    tau = np.array([1.5, -2.0])
    dq = np.array([0.2, 0.9])
    assert m.driver_efforts(tau) @ (A @ dq) == pytest.approx(tau @ dq)


def test_a_sample_sent_again_gets_its_command_again():
    """A driver sending a joint state again (its stamp the last one's: the answer was lost) gets
    the command that answered it, without a second step of the controller; an older stamp is
    dropped and counted."""
    from virtmech.builder import build
    from virtmech.ros2.render import RenderLoop

    rig = build("omni-fig11", simulated=False)
    settings, jmap = settings_from_parameters(default_parameters(rig), rig.device)
    loop = RenderLoop(rig, settings, jmap)
    q = np.array([0.05, 0.45, -0.10, 0.20, 0.60, 0.10])
    r = jmap.driver_positions(q)
    t0 = 1_700_000_000 * 10**9
    for k in range(3):
        first = loop.on_joint_state(TOUCH_JOINTS, r + 1e-3 * k, [], t0 + k * 10**6, k * 10**6)
    assert np.abs(first.efforts).max() > 0  # a force: the comparison means something
    again = loop.on_joint_state(TOUCH_JOINTS, r + 1.0, [], t0 + 2 * 10**6, 50 * 10**6)
    np.testing.assert_array_equal(again.efforts, first.efforts)
    assert loop.messages == 3 and loop.stats()["repeated"] == 1
    assert loop.last_wall == pytest.approx(0.002)  # a repeat is no news: the last new sample's
    assert loop.on_joint_state(TOUCH_JOINTS, r, [], t0 + 10**6, 51 * 10**6) is None
    assert loop.out_of_order == 1 and loop.messages == 3


def test_a_sample_sent_again_after_the_watchdog_gets_zero():
    """The watchdog counts from the last new sample: a driver frozen on one sample (sending it
    again and again) is zeroed after watchdog_s, and a repeat after the zero gets zero too, not
    the force from before the silence; the next new sample ramps the force in again."""
    from virtmech.builder import build
    from virtmech.ros2.render import RenderLoop

    rig = build("omni-fig11", simulated=False)
    settings, jmap = settings_from_parameters(default_parameters(rig), rig.device)
    loop = RenderLoop(rig, settings, jmap)
    r = jmap.driver_positions(np.array([0.05, 0.45, -0.10, 0.20, 0.60, 0.10]))
    t0, ms = 1_700_000_000 * 10**9, 10**6
    for k in range(400):  # 0.4 s at 1 kHz: ramped in
        held = loop.on_joint_state(TOUCH_JOINTS, r, [], t0 + k * ms, k * ms)
    assert np.abs(held.efforts).max() > 0.1 and float(held.output.ramp) == 1.0
    wall = 399 * ms
    silence = int(settings.watchdog_s * 1e9) + ms
    for _ in range(5):  # the same sample, resent through the watchdog's time
        wall += silence // 5
        again = loop.on_joint_state(TOUCH_JOINTS, r, [], t0 + 399 * ms, wall)
        assert again is not None
    zero = loop.stale(wall)
    assert zero is not None and zero.zero and not np.any(zero.efforts)
    resent = loop.on_joint_state(TOUCH_JOINTS, r, [], t0 + 399 * ms, wall + ms)
    assert resent.zero and not np.any(resent.efforts) and not np.any(resent.torque)
    fresh = loop.on_joint_state(TOUCH_JOINTS, r, [], t0 + 399 * ms + silence, wall + 2 * ms)
    assert float(fresh.output.ramp) < 0.05  # ramping in again, from near zero
    assert np.abs(fresh.efforts).max() < 0.05 * np.abs(held.efforts).max()
