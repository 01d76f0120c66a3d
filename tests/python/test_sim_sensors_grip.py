"""Sensor model, grip statics and the hand's intent timeline."""

from __future__ import annotations

import math

import numpy as np
import pytest

import virtmech as vm
from reference.hand import CycleIntent, hand_wrench
from reference.sensors import Sensors
from virtmech.sim.grip import finger_forces
from virtmech.sim.human import HandImpedance, min_jerk
from virtmech.sim.sensors import SensorSettings


def test_encoder_quantisation_is_15000_counts_per_revolution_by_default():
    s = Sensors(SensorSettings(), 3, 1e-3, np.random.default_rng(0))
    step = 2 * math.pi / 15000
    q, _ = s.read(np.array([0.1234567, -0.5, 1.0]))
    np.testing.assert_allclose(q / step, np.round(q / step), atol=1e-9)
    assert np.abs(q - [0.1234567, -0.5, 1.0]).max() <= step / 2 + 1e-15


def test_delay_returns_the_sample_of_k_cycles_ago():
    s = Sensors(SensorSettings(counts_per_rev=0, delay_cycles=3), 1, 1e-3, np.random.default_rng(0))
    out = [s.read(np.array([float(k)]))[0][0] for k in range(10)]
    assert out[3:] == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]


def test_dropouts_hold_the_previous_sample():
    s = Sensors(
        SensorSettings(counts_per_rev=0, dropout_probability=0.5), 1, 1e-3, np.random.default_rng(1)
    )
    out = np.array([s.read(np.array([float(k)]))[0][0] for k in range(400)])
    held = np.diff(out) == 0
    assert 0.35 < held.mean() < 0.65  # about half the samples were lost
    assert np.all(np.diff(out) >= 0)  # never a made-up value: old ones only


def test_velocity_from_filtered_differences_converges_to_the_true_rate():
    s = Sensors(SensorSettings(), 1, 1e-3, np.random.default_rng(0))
    for k in range(300):
        _, dq = s.read(np.array([0.5 * k * 1e-3]))
    assert abs(dq[0] - 0.5) < 0.02


def test_noise_has_the_stated_deviation():
    s = Sensors(SensorSettings(counts_per_rev=0, noise_rad=1e-3), 1, 1e-3, np.random.default_rng(2))
    x = np.array([s.read(np.zeros(1))[0][0] for _ in range(4000)])
    assert 0.9e-3 < x.std() < 1.1e-3


def _pose(rng):
    T = np.eye(4)
    T[:3, :3] = vm.so3_exp(rng.normal(size=3))
    T[:3, 3] = rng.normal(size=3) * 0.1
    return T


def test_finger_forces_balance_the_device_force_and_moment():
    rng = np.random.default_rng(7)
    for _ in range(200):
        T = _pose(rng)
        z = T[:3, 2]
        W = rng.normal(size=6)
        W[3:] -= (W[3:] @ z) * z  # a moment the two contacts can carry
        p1, F1, p2, F2, m_axial = finger_forces(T, W, (-0.015, -0.05))
        p = T[:3, 3]
        np.testing.assert_allclose(F1 + F2 + W[:3], 0, atol=1e-12)
        M = np.cross(p1 - p, F1) + np.cross(p2 - p, F2) + W[3:]
        np.testing.assert_allclose(M, 0, atol=1e-12)
        assert abs(m_axial) < 1e-12


def test_finger_forces_oppose_each_other_like_a_bent_pencil():
    """A force across the stylus at the handle origin, no moment (a passive gimbal): both
    fingers behind the origin push opposite ways, the nearer one harder."""
    rng = np.random.default_rng(8)
    for _ in range(100):
        T = _pose(rng)
        z = T[:3, 2]
        f = rng.normal(size=3)
        f -= (f @ z) * z
        _, F1, _, F2, _ = finger_forces(T, np.concatenate([f, np.zeros(3)]), (-0.015, -0.05))
        assert F1 @ F2 < 0
        assert F1 @ f < 0 < F2 @ f
        assert np.linalg.norm(F1) > np.linalg.norm(F2)


def test_min_jerk_scaling():
    assert min_jerk(-1) == 0 and min_jerk(0) == 0 and min_jerk(1) == 1 and min_jerk(2) == 1
    assert min_jerk(0.5) == pytest.approx(0.5)


def test_twist_rotates_the_hand_anchor_about_the_plane_normal():
    arm = vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1)
    T0 = arm.forward([0.2])
    seg = [
        {"action": "twist", "start_s": 0.1, "duration_s": 0.5, "angle_deg": 30.0, "axis": "normal"}
    ]
    intent = CycleIntent(seg, HandImpedance(), arm, T0, 1e-3)
    for k in range(800):
        target = intent.update(k * 1e-3, T0)
    R = target.R @ T0[:3, :3].T
    np.testing.assert_allclose(vm.so3_log(R), [0, 0, math.radians(30)], atol=1e-12)
    assert target.k_t == 0.0  # a twist leaves the translation passive by default
    # a handle at the anchor, at rest, feels no hand wrench
    T = T0.copy()
    T[:3, :3] = target.R
    assert np.abs(hand_wrench(target, T, np.zeros(6))).max() < 1e-12


def test_follow_moves_the_anchor_along_the_mechanism_and_holds_the_orientation():
    arm = vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1)
    T0 = arm.forward([0.2])
    seg = [
        {
            "action": "follow",
            "start_s": 0.0,
            "duration_s": 1.0,
            "theta": [0.2, 0.7],
            "orientation": "hold",
        }
    ]
    intent = CycleIntent(seg, HandImpedance(), arm, T0, 1e-3)
    for k in range(1101):
        target = intent.update(k * 1e-3, T0)
    np.testing.assert_allclose(target.p, arm.forward([0.7])[:3, 3], atol=1e-12)
    np.testing.assert_allclose(target.R, T0[:3, :3], atol=1e-12)


def test_follow_offsets_and_a_push_in_handle_axes():
    arm = vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1)
    T0 = arm.forward([0.0])
    seg = [
        {
            "action": "follow",
            "start_s": 0.0,
            "duration_s": 1.0,
            "offsets": [[0.01, 0.0, 0.0], [0.01, 0.02, 0.0]],
        },
        {
            "action": "push",
            "start_s": 1.0,
            "duration_s": 1.0,
            "force": [0.0, 0.0, 2.0],
            "force_frame": "handle",
            "ramp_s": 0.1,
        },
    ]
    intent = CycleIntent(seg, HandImpedance(), arm, T0, 1e-3)
    targets = [intent.update(k * 1e-3, T0) for k in range(2001)]
    # halfway along the path's length (min-jerk: s(0.5) = 0.5) it is 15 mm along: at the
    # second waypoint's leg, 5 mm up
    np.testing.assert_allclose(targets[500].p - T0[:3, 3], [0.01, 0.005, 0.0], atol=1e-12)
    np.testing.assert_allclose(targets[1000].p - T0[:3, 3], [0.01, 0.02, 0.0], atol=1e-12)
    # the push acts along the stylus (handle z), fully on between the ramps, then stops
    np.testing.assert_allclose(targets[1500].force, 2.0 * T0[:3, 2], atol=1e-12)
    assert np.linalg.norm(targets[2000].force) < 1e-12
    assert targets[1500].segment == 1
