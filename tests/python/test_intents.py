"""The hand's intents for measuring renderings (docs/scenarios.md, "[[intent]]"): a pure
wrench, a moment on a push, constant-speed paths, sine and chirp oscillations, release and
taking hold again, each checked against an independent reference (closed forms, a model
built without the hand, the Python reference loop), and the scenario errors of their keys."""

from __future__ import annotations

import math

import numpy as np
import pytest

import virtmech as vm

mujoco = pytest.importorskip("mujoco")

from virtmech.builder import make_device  # noqa: E402
from virtmech.scenarios import ScenarioError, json_schema, load, validate  # noqa: E402
from virtmech.sim import inner, run  # noqa: E402
from virtmech.sim import model as simmodel  # noqa: E402
from virtmech.sim.human import PLAN_INDEX, HandImpedance, Intent, plan_slice  # noqa: E402
from virtmech.sim.model import HandBody  # noqa: E402

G = 9.81
T = 1e-3


def mj(x):
    """The minimum-jerk ramp 10 x^3 - 15 x^4 + 6 x^5 on [0, 1] (the test's own)."""
    x = np.clip(x, 0.0, 1.0)
    return 10 * x**3 - 15 * x**4 + 6 * x**5


def slider(intent, *, axis=(1.0, 0.0, 0.0), gravity=False, duration=0.05):
    """A one-joint slider without friction, damping or armature, its controller's gains zero
    (no torque): a handle free along `axis`. Its moving mass is the sum of the model's
    bodies (link with stylus, 0.01 kg; the hand, 0.2 kg)."""
    return validate(
        {
            "name": "slider",
            "duration_s": duration,
            "device": {
                "type": "Device",
                "actuated": [True],
                "torque_limit": [1.0],
                "joints": [{"type": "prismatic", "axis": list(axis), "lower": -1, "upper": 1}],
                "joint_friction": 0.0,
                "joint_damping": 0.0,
                "armature": 0.0,
            },
            "mechanism": {"type": "LineGuide", "point": [0, 0, 0], "direction": list(axis)},
            "controller": {"kp": [0.0] * 6, "kv": [0.0] * 6},
            "physics": {"gravity": gravity, "gravity_compensation": False},
            "sensors": {"counts_per_rev": 0},
            "initial": {"q": [0.0]},
            "intent": intent,
        }
    )


# ---- a pure wrench ----------------------------------------------------------------------


def test_a_pure_force_accelerates_a_free_handle_by_F_over_its_mass():
    F = 0.5
    r = run(slider([{"action": "wrench", "start_s": 0.0, "duration_s": 0.0,
                     "force": [F, 0.0, 0.0], "ramp_s": 0.0}]))  # fmt: skip
    mass = 0.01 + 0.2  # stylus (the slider's one link) and hand
    t = r.t
    # no impedance: the hand's wrench is the force alone, whatever the handle does
    np.testing.assert_array_equal(r.cols("fhx", "fhy", "fhz", "mhx", "mhy", "mhz"),
                                  np.tile([F, 0, 0, 0, 0, 0], (len(t), 1)))  # fmt: skip
    np.testing.assert_allclose(r.col("vx"), F / mass * t, rtol=1e-9, atol=1e-15)
    # semi-implicit Euler over 4 steps a cycle: x_k = a dt^2 n (n + 1) / 2 after n steps
    n, dt = t / 2.5e-4, 2.5e-4
    np.testing.assert_allclose(r.col("px"), F / mass * dt * dt * n * (n + 1) / 2, rtol=1e-9)


def test_a_pure_moment_pushes_no_force_and_the_given_moment_ramped():
    M = np.array([0.0, 0.004, -0.002])
    seg = {"action": "wrench", "start_s": 0.0, "duration_s": 0.2, "moment": M.tolist(),
           "ramp_s": 0.05}  # fmt: skip
    s = load("omni-fig10").with_overrides(duration_s=0.3, intent=[seg])
    r = run(s)
    t = r.t
    np.testing.assert_array_equal(r.cols("fhx", "fhy", "fhz"), 0.0)
    g = np.where(t <= 0.2, np.minimum(mj(t / 0.05), mj((0.2 - t) / 0.05)), 0.0)
    np.testing.assert_allclose(r.cols("mhx", "mhy", "mhz"), g[:, None] * M, atol=1e-15)
    assert np.ptp(r.col("sx")) > 1e-3  # the stylus turned: the gimbal is free
    # in handle axes: the moment turns with the handle
    s2 = s.with_overrides(intent=[{**seg, "force_frame": "handle"}])
    r2 = run(s2)
    k = int(np.argmin(np.abs(r2.t - 0.1)))
    dev = make_device(s2.data["device"])
    R_h = np.asarray(dev.forward(r2.cols(*[f"q{i}" for i in range(6)])[k]))[:3, :3]
    np.testing.assert_allclose(r2.cols("mhx", "mhy", "mhz")[k], R_h @ M, atol=1e-12)


def test_a_moment_on_a_hold_is_added_to_the_impedance():
    M = [0.0, 0.0, 0.003]
    seg = {"action": "hold", "start_s": 0.0, "duration_s": 0.1, "moment": M, "ramp_s": 0.0}
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    P = Intent([seg], HandImpedance(), arm, arm.forward([0.2]), T).plan(0, 50, arm.forward([0.2]))
    np.testing.assert_array_equal(P[:, plan_slice("mx", 3)], np.tile(M, (50, 1)))
    assert (P[:, PLAN_INDEX["k_t"]] > 0).all() and (P[:, PLAN_INDEX["b_r"]] > 0).all()


# ---- constant speed -----------------------------------------------------------------------


@pytest.mark.parametrize("a, b", [(0.2, 1.0), (1.0, 0.2)])
def test_constant_speed_along_a_mechanism_path(a, b):
    R, V, ramp = 0.1, 0.2, 0.02
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], R)
    seg = {"action": "follow", "start_s": 0.0, "theta": [a, b], "profile": "constant",
           "speed_m_s": V, "ramp_s": ramp, "orientation": "path"}  # fmt: skip
    T0 = arm.forward([a])
    intent = Intent([seg], HandImpedance(), arm, T0, T)
    L = R * 0.8
    D = L / V + ramp  # the documented duration: path / speed + ramp_s
    assert intent.durations[0] == pytest.approx(D, rel=1e-11)
    N = int(round(D / T)) + 20
    P = intent.plan(0, N, T0)
    p, v = P[:, plan_slice("ax", 3)], P[:, plan_slice("vx", 3)]
    t = np.arange(N) * T
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), R, atol=1e-12)  # on the circle
    np.testing.assert_allclose(p[:, 2], 0.0, atol=1e-15)
    phi = np.unwrap(np.arctan2(p[:, 1], p[:, 0]))
    cruise = (t > ramp + 1e-9) & (t < D - ramp - 1e-9)
    c = np.flatnonzero(cruise)
    arc_speed = R * np.diff(phi)[c[:-1]] / T * np.sign(b - a)  # between two cruise samples
    np.testing.assert_allclose(arc_speed, V, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(v[cruise], axis=1), V, atol=1e-9)
    # v is the exact derivative: tangent to the circle, the way the anchor goes
    np.testing.assert_allclose(np.einsum("ij,ij->i", v, p), 0.0, atol=1e-12)
    assert (np.einsum("ij,ij->i", v[1:][cruise[1:]], np.diff(p, axis=0)[cruise[1:]]) > 0).all()
    # it starts from rest, ends at theta = 1.0 at rest, and the speed ramp is smooth
    assert np.linalg.norm(v[0]) == 0.0 and np.linalg.norm(v[-1]) == 0.0
    np.testing.assert_allclose(p[-1], np.asarray(arm.forward([b]))[:3, 3], atol=1e-12)
    assert np.abs(np.diff(np.linalg.norm(v, axis=1))).max() < 2 * V / ramp * T
    # the orientation turns with the path
    R_end = P[-1, plan_slice("R00", 9)].reshape(3, 3)
    np.testing.assert_allclose(R_end, np.asarray(arm.forward([b]))[:3, :3], atol=1e-9)


def test_constant_speed_along_offsets():
    V, ramp = 0.05, 0.01
    offs = [[0.01, 0.0, 0.0], [0.01, 0.01, 0.0]]
    seg = {"action": "follow", "start_s": 0.0, "offsets": offs, "profile": "constant",
           "speed_m_s": V, "ramp_s": ramp}  # fmt: skip
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    T0 = arm.forward([0.3])
    intent = Intent([seg], HandImpedance(), arm, T0, T)
    D = 0.02 / V + ramp
    N = int(round(D / T)) + 5
    P = intent.plan(0, N, T0)
    p = P[:, plan_slice("ax", 3)] - np.asarray(T0)[:3, 3]
    v = P[:, plan_slice("vx", 3)]
    t = np.arange(N) * T
    # on the polyline: x in [0, 0.01] with y = 0, or x = 0.01
    on_first, on_second = np.abs(p[:, 1]) < 1e-15, np.abs(p[:, 0] - 0.01) < 1e-15
    assert (on_first | on_second).all()
    cruise = (t > ramp + 1e-9) & (t < D - ramp - 1e-9)
    np.testing.assert_allclose(np.linalg.norm(v[cruise], axis=1), V, atol=1e-12)
    same_piece = (on_first[:-1] & on_first[1:]) | (on_second[:-1] & on_second[1:])
    c = cruise[:-1] & cruise[1:] & same_piece
    np.testing.assert_allclose(np.linalg.norm(np.diff(p, axis=0), axis=1)[c] / T, V, atol=1e-9)
    np.testing.assert_allclose(p[-1], [0.01, 0.01, 0.0], atol=1e-15)


def test_constant_speed_duration_and_speed_errors():
    base = load("planar3r-fig9")
    seg = {"action": "follow", "start_s": 0.0, "theta": [0.0, 0.1], "profile": "constant",
           "speed_m_s": 0.05}  # fmt: skip
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.duration_s: value 1 not allowed"):
        base.with_overrides(intent=[{**seg, "duration_s": 1.0}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.speed_m_s: missing required"):
        base.with_overrides(intent=[{k: v for k, v in seg.items() if k != "speed_m_s"}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.duration_s: missing required"):
        base.with_overrides(intent=[{**seg, "profile": "min_jerk"}])
    # a path along a mechanism of more than one joint: reported when the run starts
    probe = load("omni-contact").with_overrides(duration_s=0.01, intent=[seg])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.theta: expected a one-joint"):
        run(probe)
    # a path too short for its ramps at that speed: reported when the run starts
    fast = base.with_overrides(duration_s=0.01, intent=[{**seg, "speed_m_s": 5.0}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.speed_m_s: value 5 is out of range"):
        run(fast)
    # named by its place in the file, not in time
    late = {"action": "hold", "start_s": 0.005, "duration_s": 0.0}
    with pytest.raises(ScenarioError, match=r"intent\[1\]\.speed_m_s: value 5"):
        run(fast.with_overrides(intent=[late, {**seg, "speed_m_s": 5.0}]))


# ---- sine and chirp -----------------------------------------------------------------------


def _oscillate(seg, n=400):
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    T0 = np.asarray(arm.forward([0.3]))
    P = Intent([seg], HandImpedance(), arm, T0, T).plan(0, n, T0)
    return P, T0, np.arange(n) * T


def test_sine_and_chirp_anchor_positions_are_the_closed_forms():
    A, f, D = 0.004, 7.0, 0.3
    P, T0, t = _oscillate({"action": "sine", "start_s": 0.0, "duration_s": D,
                           "amplitude_m": A, "frequency_hz": f, "ramp_s": 0.0})  # fmt: skip
    x = np.where(t <= D, A * np.sin(2 * math.pi * f * t), 0.0)
    np.testing.assert_allclose(P[:, plan_slice("ax", 3)] - T0[:3, 3], x[:, None] * [0, 0, 1],
                               atol=1e-15)  # fmt: skip
    # the anchor's velocity is the exact derivative
    dx = np.where(t <= D, A * 2 * math.pi * f * np.cos(2 * math.pi * f * t), 0.0)
    np.testing.assert_allclose(P[:, plan_slice("vx", 3)], dx[:, None] * [0, 0, 1], atol=1e-13)
    f0, f1 = 2.0, 30.0
    seg = {"action": "chirp", "start_s": 0.0, "duration_s": D, "amplitude_m": A,
           "f0_hz": f0, "f1_hz": f1, "ramp_s": 0.0, "axis": [1.0, 1.0, 0.0]}  # fmt: skip
    P, T0, t = _oscillate(seg)
    x = np.where(t <= D, A * np.sin(2 * math.pi * (f0 * t + (f1 - f0) * t * t / (2 * D))), 0.0)
    n = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    np.testing.assert_allclose(P[:, plan_slice("ax", 3)] - T0[:3, 3], x[:, None] * n, atol=1e-15)
    # exact derivative: against central differences of the closed form
    v = P[:, plan_slice("vx", 3)] @ n

    def xc(s):
        return A * np.sin(2 * math.pi * (f0 * s + (f1 - f0) * s * s / (2 * D)))

    inside, h = t < D - 2e-3, 1e-6
    np.testing.assert_allclose(
        v[inside], (xc(t[inside] + h) - xc(t[inside] - h)) / (2 * h), atol=1e-6
    )


def test_a_rotational_sine_with_ramps_turns_the_anchor_about_its_axis():
    A, f, D, ramp = 20.0, 5.0, 0.3, 0.05
    P, T0, t = _oscillate({"action": "sine", "start_s": 0.0, "duration_s": D,
                           "amplitude_deg": A, "frequency_hz": f, "ramp_s": ramp,
                           "axis": "stylus"})  # fmt: skip
    g = np.where(t <= D, np.minimum(mj(t / ramp), mj((D - t) / ramp)), 0.0)
    angle = math.radians(A) * g * np.sin(2 * math.pi * f * t)
    z = T0[:3, 2]
    R = P[:, plan_slice("R00", 9)].reshape(-1, 3, 3)
    for k in range(0, len(t), 7):
        rel = vm.so3_log(R[k] @ T0[:3, :3].T)
        np.testing.assert_allclose(rel, angle[k] * z, atol=1e-12)
    np.testing.assert_allclose(P[:, plan_slice("ax", 3)], np.tile(T0[:3, 3], (len(t), 1)))
    w = P[:, plan_slice("wx", 3)] @ z  # exact rate, about the stylus

    def angle_at(s):
        g = np.where(s <= D, np.minimum(mj(s / ramp), mj((D - s) / ramp)), 0.0)
        return math.radians(A) * g * np.sin(2 * math.pi * f * s)

    h = 1e-7
    np.testing.assert_allclose(w, (angle_at(t + h) - angle_at(t - h)) / (2 * h), atol=1e-6)


def test_oscillation_errors_name_the_key():
    base = load("planar3r-fig9")
    seg = {"action": "sine", "start_s": 0.0, "duration_s": 0.2, "frequency_hz": 5.0}
    with pytest.raises(ScenarioError, match=r"intent\[0\]: expected exactly one of .*neither"):
        base.with_overrides(intent=[seg])
    with pytest.raises(ScenarioError, match=r"intent\[0\]: expected exactly one of .*both"):
        base.with_overrides(intent=[{**seg, "amplitude_m": 0.01, "amplitude_deg": 5.0}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.frequency_hz: value 900 .* 500 Hz"):
        base.with_overrides(intent=[{**seg, "amplitude_m": 0.01, "frequency_hz": 900.0}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.f1_hz: missing required"):
        base.with_overrides(intent=[{"action": "chirp", "start_s": 0.0, "duration_s": 0.2,
                                     "amplitude_m": 0.01, "f0_hz": 1.0}])  # fmt: skip
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.orientation: value 'passive' not"):
        base.with_overrides(intent=[{**seg, "amplitude_deg": 5.0, "orientation": "passive"}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.duration_s: value 0 .* > 0"):
        base.with_overrides(intent=[{**seg, "amplitude_m": 0.01, "duration_s": 0.0}])


def test_wrench_and_release_errors_name_the_key():
    base = load("planar3r-fig9")
    with pytest.raises(ScenarioError, match=r"intent\[0\]: missing required .*'force'"):
        base.with_overrides(intent=[{"action": "wrench", "start_s": 0.0, "duration_s": 0.1}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.stiffness: unknown key"):
        base.with_overrides(intent=[{"action": "wrench", "start_s": 0.0, "duration_s": 0.1,
                                     "force": [1, 0, 0], "stiffness": 100.0}])  # fmt: skip
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.force: unknown key"):
        base.with_overrides(intent=[{"action": "release", "start_s": 0.0, "force": [1, 0, 0]}])
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.moment: expected"):
        base.with_overrides(intent=[{"action": "hold", "start_s": 0.0, "duration_s": 0.1,
                                     "moment": [1, 0]}])  # fmt: skip
    with pytest.raises(ScenarioError, match=r"intent\[0\]\.profile: .*'min_jerk', 'constant'"):
        base.with_overrides(intent=[{"action": "follow", "start_s": 0.0, "duration_s": 0.1,
                                     "theta": [0, 1], "profile": "linear"}])  # fmt: skip


def test_the_json_schema_has_the_new_actions_and_keys():
    text = str(json_schema())
    for key in ("wrench", "release", "sine", "chirp", "speed_m_s", "profile", "moment",
                "amplitude_m", "amplitude_deg", "frequency_hz", "f0_hz", "f1_hz"):  # fmt: skip
        assert repr(key) in text, key


# ---- release ------------------------------------------------------------------------------


def test_a_released_handle_falls_as_without_the_hand_and_taking_hold_brings_its_mass_back():
    # a vertical slider under gravity, not compensated: with the hand on it (its weight
    # carried by the arm), the link's weight accelerates link and hand; released, the link
    # falls freely; holding again (a zero wrench: the hand's mass, no impedance), as before
    zero = {"force": [0.0, 0.0, 0.0], "ramp_s": 0.0}
    r = run(slider([{"action": "wrench", "start_s": 0.0, "duration_s": 0.0, **zero},
                    {"action": "release", "start_s": 0.02},
                    {"action": "wrench", "start_s": 0.04, "duration_s": 0.0, **zero}],
                   axis=(0.0, 0.0, 1.0), gravity=True, duration=0.06))  # fmt: skip
    t, vz = r.t, r.col("vz")
    a = np.diff(vz) / T
    held = -G * 0.01 / 0.21
    np.testing.assert_allclose(a[t[:-1] < 0.02 - 1e-9], held, rtol=1e-9)
    released = (t[:-1] > 0.02 - 1e-9) & (t[:-1] < 0.04 - 1e-9)
    np.testing.assert_allclose(a[released], -G, rtol=1e-9)
    np.testing.assert_allclose(a[t[:-1] > 0.04 - 1e-9], held, rtol=1e-9)
    np.testing.assert_array_equal(r.cols("fhx", "fhy", "fhz", "mhx", "mhy", "mhz"), 0.0)


def test_release_from_the_start_is_a_model_built_without_the_hand(monkeypatch):
    s = load("omni-fig10").with_overrides(
        duration_s=0.3, intent=[{"action": "release", "start_s": 0.0}]
    )
    a = run(s)
    build = simmodel.build_mjcf

    def without_hand(*args, **kw):
        return build(*args, **{**kw, "hand": HandBody(0.0, 0.0)})

    monkeypatch.setattr(simmodel, "build_mjcf", without_hand)
    b = run(s)
    assert "hand" in a.info["mjcf"] and 'name="hand"' not in b.info["mjcf"]
    np.testing.assert_allclose(a.log, b.log, rtol=0, atol=1e-12)
    # the device moved the handle (the controller pulls it onto the circle)
    assert np.ptp(a.col("px")) > 1e-3 and np.abs(a.col("fx")).max() > 0.05


def test_taking_hold_again_starts_the_anchor_from_the_handle():
    s = load("omni-fig10").with_overrides(
        duration_s=0.3,
        intent=[
            {"action": "hold", "start_s": 0.0, "duration_s": 0.0},
            {"action": "release", "start_s": 0.05},
            {"action": "hold", "start_s": 0.15, "duration_s": 0.0},
        ],
    )
    r = run(s)
    k = int(round(0.15 / T))
    np.testing.assert_allclose(r.cols("ax", "ay", "az")[k], r.cols("px", "py", "pz")[k],
                               atol=1e-15)  # fmt: skip
    released = (r.t >= 0.05 - 1e-9) & (r.t < 0.15 - 1e-9)
    np.testing.assert_array_equal(r.cols("fhx", "fhy", "fhz", "mhx", "mhy", "mhz")[released], 0.0)
    # holding again: the first wrench is the damping against the handle's own velocity only
    b = s.data["human"]["damping"]
    np.testing.assert_allclose(r.cols("fhx", "fhy", "fhz")[k], -b * r.cols("vx", "vy", "vz")[k],
                               atol=1e-12)  # fmt: skip
    assert np.abs(r.cols("fhx", "fhy", "fhz")[k + 50 :]).max() > 1e-3


def test_taking_hold_again_restores_the_models_constants(monkeypatch):
    models = []
    compile_model = simmodel.compile_model

    def keep(built):
        models.append(compile_model(built))
        return models[-1]

    monkeypatch.setattr(simmodel, "compile_model", keep)
    hold = {"action": "hold", "start_s": 0.0, "duration_s": 0.0}
    s = load("omni-fig10").with_overrides(duration_s=0.06, intent=[hold])
    run(s)  # never released: the compiled constants
    run(s.with_overrides(intent=[hold, {"action": "release", "start_s": 0.02},
                                 {**hold, "start_s": 0.04}]))  # fmt: skip
    run(s.with_overrides(intent=[hold, {"action": "release", "start_s": 0.02}]))  # ends so
    compiled, again, ended = models
    for m in (again, ended):  # the loop, destroyed, has restored the hand of the last
        for name in ("body_mass", "body_inertia", "body_subtreemass", "dof_M0",
                     "dof_invweight0", "body_invweight0", "tendon_invweight0",
                     "actuator_acc0"):  # fmt: skip
            np.testing.assert_allclose(getattr(m, name), getattr(compiled, name), rtol=1e-12,
                                       atol=0, err_msg=name)  # fmt: skip


# ---- the C++ loop and the Python reference --------------------------------------------------


NEW_INTENTS = [
    {"action": "wrench", "start_s": 0.0, "duration_s": 0.1, "force": [0.3, 0.0, 0.1],
     "moment": [0.0, 0.002, 0.001], "force_frame": "handle", "ramp_s": 0.03},
    {"action": "sine", "start_s": 0.1, "duration_s": 0.1, "amplitude_m": 0.003,
     "frequency_hz": 15.0, "ramp_s": 0.02, "moment": [0.001, 0.0, 0.0]},
    {"action": "release", "start_s": 0.2},
    {"action": "chirp", "start_s": 0.3, "duration_s": 0.1, "amplitude_deg": 8.0,
     "f0_hz": 3.0, "f1_hz": 20.0, "axis": "stylus", "ramp_s": 0.02},
    {"action": "follow", "start_s": 0.4, "theta": [0.5, 0.6], "profile": "constant",
     "speed_m_s": 0.1, "ramp_s": 0.02},
]  # fmt: skip


def test_compiled_loop_gives_the_python_reference_log_with_the_new_intents(monkeypatch):
    from reference.sim_loop import PyServoLoop

    s = load("omni-fig11").with_overrides(duration_s=0.5, intent=NEW_INTENTS)
    a = run(s)
    monkeypatch.setattr(inner, "ServoLoop", PyServoLoop)
    b = run(s)
    diff = np.abs(a.log - b.log)
    diff[np.isnan(a.log) & np.isnan(b.log)] = 0.0
    assert diff.max() < 1e-9, a.columns[int(np.argmax(diff.max(axis=0)))]
    # every intent acted: moment, release (no hand wrench), oscillation
    mh = a.cols("mhx", "mhy", "mhz")
    assert np.abs(mh[a.t < 0.1]).max() > 1e-3
    released = (a.t >= 0.2 - 1e-9) & (a.t < 0.3 - 1e-9)
    assert not a.cols("fhx", "fhy", "fhz", "mhx", "mhy", "mhz")[released].any()
    assert np.abs(a.cols("fhx", "fhy", "fhz")[a.t > 0.4]).max() > 1e-3


def test_after_a_release_the_handle_moves_as_on_a_model_built_without_the_hand():
    # the run's state some cycles after the hand let go, stepped on a model built without
    # the hand body with the motor torques the run logged: the same motion
    s = load("omni-fig10").with_overrides(
        duration_s=0.2,
        intent=[{"action": "hold", "start_s": 0.0, "duration_s": 0.0},
                {"action": "release", "start_s": 0.05}],
    )  # fmt: skip
    r = run(s)
    S = s.data
    device = make_device(S["device"])
    nsub = int(round(S["physics"]["rate_hz"] * T))
    built = simmodel.build_mjcf(
        device,
        params=simmodel.device_physics(S["device"]),
        hand=HandBody(0.0, 0.0),
        gravity=simmodel.world_gravity(device),
        timestep=T / nsub,
    )
    m = simmodel.compile_model(built)
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "hand") == -1
    d = mujoco.MjData(m)
    C, c0 = built.coupling.C, built.coupling.c0
    n = device.dof
    q, dq = r.cols(*[f"q{i}" for i in range(n)]), r.cols(*[f"dq{i}" for i in range(n)])
    tau = r.cols(*[f"tau_motor{i}" for i in range(n)])
    act = np.flatnonzero(np.asarray(device.actuated, dtype=bool))
    k0 = int(round(0.08 / T))
    d.qpos[:], d.qvel[:] = C @ q[k0] + c0, C @ dq[k0]
    for k in range(k0, k0 + 100):
        d.ctrl[:] = tau[k, act]
        for _ in range(nsub):
            mujoco.mj_step(m, d)
        np.testing.assert_allclose(np.linalg.solve(C, d.qpos - c0), q[k + 1], atol=1e-9)
    assert np.ptp(q[k0 : k0 + 100, 0]) > 1e-3  # it moved


def test_a_push_the_physics_cannot_integrate_ends_the_run_with_a_clear_error(
    tmp_path, monkeypatch, capsys
):
    # a hand pushing with 1e6 N (past the format's bound, so set behind its back): MuJoCo's
    # state diverges and is reset; the run stops with a message naming the scenario and
    # when, instead of logging the reset state
    from virtmech import builder
    from virtmech.sim.run_loop import SimulationUnstable

    s = load("omni-fig10").with_overrides(duration_s=1.5)
    s.data["intent"][0]["force"] = [1e6, 0.0, 0.0]
    with pytest.raises(SimulationUnstable, match=r"unstable between t = 0\.000 and 1\.000 s"):
        run(s)
    from virtmech.cli import main

    # the format refuses the force itself, naming the key
    out = tmp_path / "o"
    assert main(["run", "omni-fig10", "--set", "intent.0.force=[1e6,0,0]", "--out", str(out),
                 "--quiet", "--duration", "0.5"]) == 2
    assert not out.exists()
    # and an unstable run is a user's mistake on the command line too (exit 2)
    build = builder.build

    def diverging(scenario, seed=None, **kw):  # (kw: preflight's simulated=False)
        scenario.data["intent"][0]["force"] = [1e6, 0.0, 0.0]
        return build(scenario, seed, **kw)

    monkeypatch.setattr(builder, "build", diverging)
    capsys.readouterr()
    assert main(["run", "omni-fig10", "--out", str(out), "--quiet", "--duration", "0.5"]) == 2
    assert "the simulation became unstable between t = 0.000" in capsys.readouterr().err
