"""vm.CartesianDevice: the SDK's pose as coordinates (position, then the x-y-z gimbal angles
of the SDK's rotation), its exact Jacobian, the SDK's velocities and the wrench of the
coordinate torques, each model's actuation and limits, and the scenario format's device.
References: SciPy's intrinsic x-y-z Euler rotations and central differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import virtmech as vm
import virtmech.scenarios as sc

MODELS = ("omega.3", "omega.6", "omega.7", "sigma.7", "falcon")


def _sdk_rotation(abc) -> np.ndarray:
    """R = Rx(a) Ry(b) Rz(c): SciPy's intrinsic rotations about x, then y, then z."""
    return Rotation.from_euler("XYZ", abc).as_matrix()


def _draw(device, rng) -> np.ndarray:
    return rng.uniform(device.lower, device.upper)


def test_the_models_are_the_five_named_and_in_the_scenario_format():
    assert vm.CartesianDevice.MODELS == MODELS
    sensed = {m: vm.CartesianDevice(m).orientation_sensed for m in MODELS}
    assert sensed == {"omega.3": False, "omega.6": True, "omega.7": True, "sigma.7": True,
                      "falcon": False}
    driven = {m: vm.CartesianDevice(m).torque_actuated for m in MODELS}
    assert [m for m, t in driven.items() if t] == ["sigma.7"]
    d = vm.CartesianDevice("omega.6")
    assert list(d.actuated) == [True, True, True, False, False, False]
    assert d.joint_types == ["prismatic"] * 3 + ["revolute"] * 3
    assert (d.max_force, vm.CartesianDevice("falcon").max_force) == (12.0, 8.0)
    assert vm.CartesianDevice("sigma.7").max_torque == 0.2
    assert d.to_dict()["type"] == "CartesianDevice" and d.to_dict()["model"] == "omega.6"


@pytest.mark.parametrize("model", MODELS)
def test_pose_and_jacobian_against_scipy_and_central_differences(model):
    d = vm.CartesianDevice(model)
    H = vm.so3_exp(d.handle_rotation)  # a rotation vector
    rng = np.random.default_rng(11)
    h = 1e-6
    for _ in range(40):
        q = _draw(d, rng)
        T = d.forward(q)
        R = (_sdk_rotation(q[3:]) if d.dof == 6 else np.eye(3)) @ H
        np.testing.assert_allclose(T[:3, :3], R, atol=1e-14)
        np.testing.assert_array_equal(T[:3, 3], q[:3])
        J = d.jacobian(q)
        for i in range(d.dof):
            e = np.zeros(d.dof)
            e[i] = h
            Tp, Tm = d.forward(q + e), d.forward(q - e)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
            np.testing.assert_allclose(J[:, i], np.concatenate([v, w]), atol=1e-8)


@pytest.mark.parametrize("model", MODELS)
def test_sdk_readings_round_trip_and_velocities_give_the_twist(model):
    d = vm.CartesianDevice(model)
    rng = np.random.default_rng(2)
    for _ in range(30):
        q = _draw(d, rng)
        R = _sdk_rotation(q[3:]) if d.dof == 6 else _sdk_rotation([0.3, -0.2, 0.1])
        np.testing.assert_allclose(d.coordinates(q[:3], R), q, atol=1e-12)
        p, R2 = d.sdk_pose(q)
        np.testing.assert_array_equal(p, q[:3])
        np.testing.assert_allclose(R2, R if d.dof == 6 else np.eye(3), atol=1e-14)
        v, w = rng.normal(size=3), rng.normal(size=3)
        twist = d.jacobian(q) @ d.rates(q, v, w)
        np.testing.assert_allclose(twist[:3], v, atol=1e-12)
        if d.dof == 6:
            np.testing.assert_allclose(twist[3:], w, atol=1e-12)
        # the wrench of the coordinate torques J^T w is w (no moment where no orientation)
        wrench = rng.normal(size=6)
        if d.dof == 3:
            wrench[3:] = 0.0
        np.testing.assert_allclose(d.wrench(q, d.jacobian(q).T @ wrench), wrench, atol=1e-12)


def test_the_omega6_renders_no_torque_and_the_sigma7_its_handle_wrench():
    probe = vm.Probe([0.0, 0.0, -0.04], [0.0, 0.0, 1.0], 0.05, [1.0, 0.0, 0.0])
    q6 = np.array([0.01, -0.02, -0.005, 0.2, -0.3, 0.4])
    for model in ("omega.6", "sigma.7"):
        d = vm.CartesianDevice(model)
        c = vm.Controller(d, probe, ramp_time_s=1e-3)  # one cycle: full force at once
        out = c.step(q6, np.zeros(6), 0.0)
        w = d.wrench(q6, out.torque)
        assert np.linalg.norm(w[:3]) > 1.0
        np.testing.assert_allclose(w[:3], out.wrench[:3], atol=1e-12)
        if model == "omega.6":
            assert np.all(out.torque[3:] == 0.0) and np.all(w[3:] == 0.0)
        else:
            np.testing.assert_allclose(w[3:], out.wrench[3:], atol=1e-12)


def test_an_unknown_model_names_the_key_and_the_models():
    with pytest.raises(ValueError, match=r"^model: .*'sigma\.7'.*'omega\.9'"):
        vm.CartesianDevice("omega.9")
    raw = sc.load("falcon-contact").raw
    with pytest.raises(sc.ScenarioError) as e:
        sc.validate({**raw, "device": {"type": "CartesianDevice", "model": "omega.9"}}, "x.toml")
    assert "device.model" in str(e.value) and "'omega.9'" in str(e.value)
    assert "'falcon'" in str(e.value)


def test_a_bad_model_on_the_command_line_exits_2_naming_the_key(tmp_path, capsys):
    from virtmech.cli import main

    path = tmp_path / "bad.toml"
    text = sc.path_of("omega6-fig9").read_text().replace('model = "omega.6"', 'model = "omega6"')
    path.write_text(text)
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "device.model" in err and "'omega6'" in err and "Traceback" not in err


@pytest.mark.parametrize("name", ["omega6-fig9", "falcon-contact"])
def test_the_scenario_builds_the_device_of_its_model(name):
    from virtmech.builder import build

    rig = build(name, simulated=False)
    model = sc.load(name).data["device"]["model"]
    assert isinstance(rig.device, vm.CartesianDevice) and rig.device.model == model
