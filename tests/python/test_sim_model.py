"""MJCF device models: the MuJoCo models agree with the core's kinematics, motors and
limits are where the core says, and the physical parameters are those documented."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm

mujoco = pytest.importorskip("mujoco")

from virtmech.sim.model import (  # noqa: E402
    DeviceModel,
    HandBody,
    apparent_mass,
    build_mjcf,
    compile_model,
)


def _base() -> np.ndarray:
    B = np.eye(4)
    B[:3, :3] = vm.so3_exp([0.3, -0.2, 0.9])
    B[:3, 3] = [0.1, -0.2, 0.3]
    return B


def _arm7() -> vm.Device:
    """A 7-joint arm (revolute and prismatic, twisted axes), joints 5 and 6 passive."""
    J = []
    axes = [[0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 0.6, 0.8]]
    for k, a in enumerate(axes):
        o = np.eye(4)
        o[:3, 3] = [0.0, 0.0, 0.08] if k else [0.0, 0.0, 0.0]
        o[:3, :3] = vm.so3_exp([0.1 * k, -0.05 * k, 0.2])
        J.append(
            vm.Joint("prismatic" if k == 3 else "revolute", a, o, -0.05 if k == 3 else -2.5,
                     0.05 if k == 3 else 2.5)
        )
    H = np.eye(4)
    H[:3, 3] = [0.0, 0.02, 0.05]
    return vm.Device(J, [True] * 5 + [False] * 2, handle=H, base=_base(),
                     torque_limit=[2.0, 2.0, 1.5, 20.0, 1.0, 0.0, 0.0])


DEVICES = {
    "omni": lambda: vm.PhantomOmni(),
    "omni-offsets": lambda: vm.PhantomOmni(
        gimbal_offset=[0.3, -0.2, 0.1], gimbal_sign=[-1.0, 1.0, -1.0]
    ),
    "planar3r": lambda: vm.Planar3R(link1=0.25, link2=0.15, base=_base()),
    "arm7": _arm7,
    "omega6": lambda: vm.CartesianDevice("omega.6"),
    "sigma7": lambda: vm.CartesianDevice("sigma.7", handle_rotation=[0.4, 2.0, -0.3]),
    "falcon": lambda: vm.CartesianDevice("falcon"),
}


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_mjcf_handle_matches_core_kinematics(name):
    device = DEVICES[name]()
    built = build_mjcf(device)
    model = compile_model(built)
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "handle")
    rng = np.random.default_rng(3)
    lo = np.where(np.isfinite(device.lower), device.lower, -np.pi)
    hi = np.where(np.isfinite(device.upper), device.upper, np.pi)
    for _ in range(300):
        q = rng.uniform(lo - 0.3, hi + 0.3)  # also outside the limits: pure kinematics
        data.qpos[:] = built.coupling.to_chain(q)
        mujoco.mj_kinematics(model, data)
        T = device.forward(q)
        assert np.abs(data.site_xpos[site] - T[:3, 3]).max() < 1e-9
        assert np.abs(data.site_xmat[site].reshape(3, 3) - T[:3, :3]).max() < 1e-9
        # and the sensor map back to device joints is exact
        assert np.abs(built.coupling.to_device(data.qpos) - q).max() < 1e-12


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_motors_drive_the_device_joints_with_their_torque_limits(name):
    device = DEVICES[name]()
    built = build_mjcf(device)
    model = compile_model(built)
    data = mujoco.MjData(model)
    act = np.flatnonzero(device.actuated)
    assert model.nu == len(act)  # passive joints have no motor
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 1], device.torque_limit[act])
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 0], -device.torque_limit[act])
    # a device-joint torque tau (in the limits) arrives as chain forces Cinv^T tau: the same
    # power at every joint velocity
    rng = np.random.default_rng(5)
    tau = np.zeros(device.dof)
    tau[act] = rng.uniform(-1, 1, len(act)) * device.torque_limit[act] * 0.9
    data.ctrl[:] = tau[act]
    data.qpos[:] = built.coupling.to_chain(device.home)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator, built.coupling.Cinv.T @ tau, atol=1e-12)
    # beyond the limit the motor saturates
    data.ctrl[:] = 10 * device.torque_limit[act]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.actuator_force, device.torque_limit[act])


def test_omni_elbow_motor_drives_the_absolute_elbow():
    """The parallelogram: the elbow motor's torque acts on shoulder and serial elbow alike."""
    omni = vm.PhantomOmni()
    built = build_mjcf(omni)
    model = compile_model(built)
    data = mujoco.MjData(model)
    data.ctrl[:] = [0.0, 0.0, 0.2]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator[:3], [0.0, 0.2, 0.2], atol=1e-12)


def test_passive_joints_have_friction_and_damping_and_no_motor():
    omni = vm.PhantomOmni()
    p = DeviceModel()
    model = compile_model(build_mjcf(omni, params=p))
    for i in (3, 4, 5):
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"s{i}")
        assert model.dof_frictionloss[j] == p.passive_friction > 0
        assert model.dof_damping[j] == p.passive_damping > 0


def test_omni_apparent_tip_mass_is_near_the_reference_45_g():
    """The Omni's apparent tip inertia is commonly given as about 45 g (check); the model
    gives 25..60 g in every direction over a few postures (the hand's own mass excluded)."""
    omni = vm.PhantomOmni()
    built = build_mjcf(omni, hand=HandBody(1e-6, 1e-9))
    model = compile_model(built)
    data = mujoco.MjData(model)
    for q in (
        omni.home,
        np.array([0.0, 0.41, 0.08, -1.51, 0.43, 1.48]),
        np.array([0.3, 0.7, 0.3, -1.3, 0.9, 1.0]),
    ):
        eig = np.linalg.eigvalsh(apparent_mass(model, data, omni, built.coupling, q))
        assert 0.025 < eig.min() and eig.max() < 0.060, eig


def test_gravity_is_along_minus_y_for_the_omni_and_the_hand_weight_is_carried():
    from virtmech.scenarios import load
    from virtmech.sim import run

    s = load("omni-fig9").with_overrides(duration_s=0.05)
    r = run(s)
    assert r.info["physics"]["gravity"] == [0.0, -9.81, 0.0]
    assert 'gravcomp="1"' in r.info["mjcf"]
