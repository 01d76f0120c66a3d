"""The C++ core against the NumPy reference cycle (tests/reference): the reference places the
mechanism on its own (Newton on the placement's stationarity condition, to its own
tolerance, from several starts), so where the core converges the two must give the same
torques and wrenches."""

from __future__ import annotations

import numpy as np
import pytest

import reference as ref
import virtmech as vm

#: [N·m], [N / N·m]: the agreement of two independent solutions of the same cycle at
#: convergence (the placements' optima agree to ~1e-12 in the joints).
TORQUE_TOL = 1e-9
WRENCH_TOL = 1e-8

OMNI_CENTER = np.array([0.0, 0.5, 0.3, 0.0, 0.8, 0.0])
OMNI_SPAN = np.array([0.5, 0.3, 0.3, 1.0, 0.6, 1.5])

MECHANISMS = {
    "omni+probe": lambda: vm.Probe([0.0, 0.01, 0.0], [0, 1, 0], 0.1),
    "omni+probe_lifted": lambda: vm.Probe([0.0, -0.03, 0.0], [0, 1, 0], 0.1),
    "omni+planar_arm": lambda: vm.PlanarArm([0.0, 0.0, -0.05], [0, 0, 1], 0.05, [1, 0, 0]),
}


@pytest.mark.parametrize("thorough", [False, pytest.param(True, marks=pytest.mark.slow)],
                         ids=["quick", "thorough"])
@pytest.mark.parametrize("name", list(MECHANISMS))
def test_core_gives_the_reference_cycle_at_convergence(name, thorough):
    # independent random joint states and velocities, every one a cycle of its own (no
    # torque ramp): the core's placements (closed forms) against the reference's global one;
    # 12 states, or 100 when thorough (marked slow, run by scripts/test.sh after the suite)
    rng = np.random.default_rng(sum(map(ord, name)) + (1 if thorough else 0))
    c = vm.Controller(vm.PhantomOmni(), MECHANISMS[name](), ramp_time_s=1e-3, passivity="off")
    device, mechanism = ref.case_models(name)
    npc = ref.NpController(c, device, mechanism, global_search=True)
    largest = 0.0
    for _ in range(100 if thorough else 12):
        q = OMNI_CENTER + OMNI_SPAN * rng.uniform(-1.0, 1.0, 6)
        dq = rng.normal(0.0, 0.3, 6)
        out = c.step(q, dq)
        tau = npc.step(q, dq)
        assert npc.converged
        assert not out.status & vm.status.NOT_CONVERGED
        tol = TORQUE_TOL if name != "omni+probe_lifted" else 1e-7
        np.testing.assert_allclose(out.torque, tau, rtol=0.0, atol=tol)
        np.testing.assert_allclose(out.wrench, npc.wrench, rtol=0.0, atol=10 * tol)
        largest = max(largest, np.abs(tau).max())
    assert largest > 0.1  # real forces, not zeros agreeing


@pytest.mark.parametrize("name", ["omni+probe", "omni+planar_arm"])
def test_core_follows_the_reference_along_a_motion(name):
    # a smooth motion from reset (torque ramp, warm starts): same torques every cycle
    from virtmech import bench

    case = bench.make_case(name, passivity="off")  # the reference is the laws
    c = case.controller
    c.reset()
    device, mechanism = ref.case_models(name)
    npc = ref.NpController(c, device, mechanism)
    q, dq = case.joint_state(np.arange(120), c.model["period_s"])
    for k in range(120):
        out = c.step(q[k], dq[k])
        np.testing.assert_allclose(out.torque, npc.step(q[k], dq[k]), rtol=0.0, atol=TORQUE_TOL)
    assert np.abs(out.torque).max() > 1e-3


def test_reference_kinematics_match_the_core():
    from virtmech import bench

    rng = np.random.default_rng(4)
    for name in bench.CASES:
        case = bench.make_case(name)
        dev, mech = case.controller.device, case.controller.mechanism
        np_dev, np_mech = ref.case_models(name)
        for _ in range(5):
            q = rng.uniform(-1.0, 1.0, dev.dof)
            T, J = np_dev.forward_jacobian(q)
            np.testing.assert_allclose(T, dev.forward(q), atol=1e-14)
            np.testing.assert_allclose(J, dev.jacobian(q), atol=1e-14)
            th = rng.uniform(-0.5, 0.5, mech.dof)
            T, J = np_mech.forward_jacobian(th)
            np.testing.assert_allclose(T, mech.forward(th), atol=1e-14)
            np.testing.assert_allclose(J, mech.jacobian(th), atol=1e-14)


def test_reference_placement_is_scipys_optimum():
    # the reference's own solver against SciPy's least squares on the same weighted error
    from scipy.optimize import least_squares

    rng = np.random.default_rng(7)
    _, mech = ref.case_models("omni+probe")
    W = np.array([1.0, 1.0, 1.0, 0.01, 0.01, 0.01])
    for _ in range(5):
        theta_true = rng.uniform(-0.4, 0.4, 5)
        T = mech.forward(theta_true)
        T[:3, 3] += rng.normal(0.0, 0.01, 3)  # a handle off the plane's reach
        theta, converged = ref.place(mech, T, W, mech.home, global_search=True)
        assert converged
        fit = least_squares(lambda th, T=T: np.sqrt(W) * ref.pose_error(T, mech.forward(th)),
                            theta_true, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        assert ref.weighted_cost(mech, T, W, theta) <= 2 * fit.cost * (1 + 1e-9) + 1e-24
