"""Any serial-chain device simulates: a seven-joint arm described in its scenario file, and
the Omni with other joints actuated (a fully actuated variant). Passive joints get exactly
zero torque; actuated ones are driven within their limits."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm

pytest.importorskip("mujoco")

from virtmech.scenarios import load  # noqa: E402
from virtmech.sim import run  # noqa: E402


def torques(r, n):
    return np.column_stack([r.col(f"tau{i}") for i in range(n)])


def test_seven_joint_arm_scenario_renders_contact_with_a_passive_wrist():
    r = run(load("arm7-contact").with_overrides(duration_s=1.6))
    assert r.info["device"]["type"] == "Device" and len(r.info["device"]["joints"]) == 7
    tau = torques(r, 7)
    assert np.all(tau[:, 5:] == 0.0)  # the passive wrist: exactly nothing
    assert np.abs(tau[:, :5]).max() > 0.05  # the motors push back once the tip is in
    limits = np.array([2.0, 2.0, 1.0, 2.0, 0.5])  # the scenario file's torque_limit
    assert np.all(np.abs(tau[:, :5]) <= limits + 1e-12)
    # pressed 6 mm past the plane at 1.4 s: the plane pushes back along +z with about
    # Kp x depth (the Omni-like default Kp = 500 N/m), from the tip height the log holds
    k = np.searchsorted(r.t, 1.5)
    depth = -r.col("dist_signed")[k]
    assert 0.001 < depth < 0.01
    assert r.col("fz")[k] == pytest.approx(500.0 * depth, rel=0.1)


def test_seven_joint_arm_places_its_probe_on_every_cycle():
    """The whole arm7-contact run: Gauss-Newton places the probe (its weights are not
    isotropic per block) and converges on every cycle (156 did not before it took the
    error's own derivative, docs/theory.md "Which optimum")."""
    r = run(load("arm7-contact"))
    status = r.col("status").astype(int)
    assert np.count_nonzero(status & vm.status.NOT_CONVERGED) == 0
    assert r.col("iterations").max() > 0  # (Gauss-Newton did run)


@pytest.mark.parametrize(
    "actuated", [[True] * 6, [True, True, True, True, False, False]], ids=["full", "yaw"]
)
def test_omni_with_other_joints_actuated(actuated):
    s = load("omni-fig11").with_overrides(duration_s=0.6)
    d = dict(s["device"], actuated=actuated, gimbal_torque_limit=0.05)
    r = run(s.with_overrides(device=d))
    tau = torques(r, 6)
    passive = ~np.asarray(actuated)
    assert np.all(tau[:, passive] == 0.0)
    gimbal = np.flatnonzero(np.asarray(actuated)[3:]) + 3
    assert np.abs(tau[:, gimbal]).max() > 1e-4  # the gimbal motors act
    assert np.abs(tau[:, gimbal]).max() <= 0.05 + 1e-12
    # the same Omni: its chain and joint map, only the motors differ
    omni = vm.PhantomOmni()
    np.testing.assert_array_equal(r.info["device"]["coupling"], omni.coupling)


def test_omni_default_actuation_is_the_real_device():
    s = load("omni-fig11").with_overrides(duration_s=0.05)
    assert s["device"]["actuated"] == [True, True, True, False, False, False]
    assert run(s).info["device"]["type"] == "PhantomOmni"
