"""virtmech.reach: the device's joint values for a handle pose (the start pose of a
simulated run), and the scenario's own start pose checked against the device."""

import numpy as np
import pytest

import virtmech as vm


def test_reach_returns_joints_whose_pose_is_the_target():
    # a pose the Omni is in at known joints: reach finds joints with that pose (the forward
    # kinematics, independent of the search, checks it), within the joint limits
    omni = vm.PhantomOmni()
    q_true = np.array([0.2, 0.5, 0.1, -1.2, 0.4, 0.7])
    T = omni.forward(q_true)
    seeds = [np.array([0.0, 0.4, 0.2, -1.5, 0.3, 1.5]), np.asarray(omni.home)]
    q, err, seed = vm.reach(omni, T, seeds, 0.08)
    assert np.abs(omni.forward(q) - T).max() < 1e-10
    assert np.abs(err).max() < 1e-10 and seed == 0
    assert np.all(q >= omni.lower) and np.all(q <= omni.upper)


def test_reach_keeps_the_nearest_when_the_target_is_out_of_reach():
    # the planar robot cannot leave its plane: the nearest pose keeps the in-plane part and
    # reports the out-of-plane error it cannot remove
    arm = vm.Planar3R()
    T = arm.forward(np.array([0.3, 1.2, -0.8]))
    T[2, 3] += 0.05  # 50 mm out of the plane
    q, err, _ = vm.reach(arm, T, [np.zeros(3), np.array([0.3, 1.5, -1.0])], 0.1)
    assert err[2] == pytest.approx(0.05, abs=1e-9)
    assert np.abs(err[:2]).max() < 1e-9


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"seeds": []}, "seeds: expected at least one"),
        ({"seeds": [np.zeros(3)]}, "seeds"),
        ({"length_scale": 0.0}, "length_scale"),
    ],
)
def test_reach_names_the_bad_argument(kwargs, message):
    omni = vm.PhantomOmni()
    args = {"seeds": [np.asarray(omni.home)], "length_scale": 0.1, **kwargs}
    with pytest.raises(ValueError, match=message):
        vm.reach(omni, np.eye(4), args["seeds"], args["length_scale"])


def test_a_start_pose_outside_the_joint_range_is_refused_naming_the_key():
    pytest.importorskip("mujoco")
    from virtmech.builder import preflight
    from virtmech.scenarios import ScenarioError, load

    s = load("omni-fig9").with_overrides(initial={"q": [0.0, 0.3, 0.2, 4.5, 0.3, 0.0]})
    with pytest.raises(ScenarioError, match=r"initial\.q\[3\]: 4\.5 is outside the device's "
                       r"joint range"):
        preflight(s)
