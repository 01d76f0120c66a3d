"""The simulation's servo-rate loop (C++, virtmech._sim through virtmech/sim/inner.py): it
gives the Python reference's log (tests/reference/sim_loop.py), the hand's plan is the
per-cycle intent, the loop takes its columns from the one table of each, and it leaves
MuJoCo's global timer callback as it found it."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

import virtmech as vm

mujoco = pytest.importorskip("mujoco")

from reference.hand import CycleIntent  # noqa: E402
from virtmech.scenarios import load  # noqa: E402
from virtmech.sim import inner, run  # noqa: E402
from virtmech.sim.human import (  # noqa: E402
    PLAN_COLUMNS,
    PLAN_INDEX,
    HandImpedance,
    Intent,
    plan_slice,
)
from virtmech.sim.log import log_columns  # noqa: E402

# every sensor effect on, so the compiled sensor model is compared as well
SENSORS = {
    "noise_rad": 2e-4,
    "delay_cycles": 2,
    "dropout_probability": 0.05,
    "velocity_cutoff_hz": 60.0,
}


@pytest.mark.parametrize(
    "name, duration",
    [("omni-fig11", 0.8), ("omni-fig10", 0.4), ("planar3r-fig10", 0.5)],
)
def test_compiled_loop_gives_the_python_reference_log(name, duration, monkeypatch):
    from reference.sim_loop import PyServoLoop

    s = load(name).with_overrides(duration_s=duration, sensors=SENSORS)
    a = run(s)
    monkeypatch.setattr(inner, "ServoLoop", PyServoLoop)
    b = run(s)
    assert a.columns == b.columns and a.log.shape == b.log.shape
    # the same physics, sensors, controller and hand, cycle by cycle: differences are the
    # rounding of two implementations of the same formulas (MuJoCo's friction makes the
    # state sensitive, so a loose bound on the state is still a strong check)
    assert np.isfinite(a.log[:, a.columns.index("tau0")]).all()
    diff = np.abs(a.log - b.log)
    diff[np.isnan(a.log) & np.isnan(b.log)] = 0.0
    assert diff.max() < 1e-9, a.columns[int(np.argmax(diff.max(axis=0)))]
    # the run was not trivial: the hand moved the handle and the device pushed back
    assert np.ptp(a.col("px")) > 1e-3 or np.ptp(a.col("py")) > 1e-3
    assert np.abs(a.col("fx")).max() > 0.05 or np.abs(a.col("fy")).max() > 0.05
    # the sensor settings took effect: measured positions are off the encoder grid by noise,
    # delayed, and not always equal to the true ones
    assert np.abs(a.col("qm0") - a.col("q0")).max() > 1e-5


def test_the_run_records_its_loop_and_there_is_one():
    s = load("omni-fig9").with_overrides(duration_s=0.02)
    assert run(s).info["physics"]["engine"] == "compiled"
    with pytest.raises(TypeError, match="engine"):
        run(s, engine="python")


SEGMENTS = [
    {"action": "hold", "start_s": 0.0, "duration_s": 0.1},
    {
        "action": "follow",
        "start_s": 0.1,
        "duration_s": 0.2,
        "theta": [0.2, 0.6],
        "orientation": "path",
    },
    {"action": "twist", "start_s": 0.3, "duration_s": 0.2, "angle_deg": 25.0, "axis": "normal"},
    {
        "action": "push",
        "start_s": 0.5,
        "duration_s": 0.2,
        "force": [0.3, 0.0, 1.5],
        "force_frame": "handle",
        "ramp_s": 0.05,
        "orientation": "passive",
    },
    {
        "action": "follow",
        "start_s": 0.7,
        "duration_s": 0.2,
        "offsets": [[0.01, 0.0, 0.0], [0.01, 0.02, 0.0]],
        "force": [0.0, 1.0, 0.0],
    },
    {"action": "resist", "start_s": 0.9, "duration_s": 0.1, "angle_deg": -10.0},
]


def test_the_run_reports_its_controllers_share_of_the_wall_time():
    s = load("omni-contact").with_overrides(duration_s=0.3)
    r = run(s)
    # every cycle steps the controller, which takes some time but not all of the loop's;
    # the derived columns take some time, and the loop spends some of its own on them (the
    # last stretch of each block, and waiting for the worker's), apart from the stepping
    # (not bounded by derived_time_s: a wait also holds the worker's wake-up)
    assert 0.0 < r.control_time_s < r.wall_time_s
    assert 0.0 < r.derived_time_s
    assert 0.0 < r.derived_wait_s < r.wall_time_s - r.control_time_s


def test_the_derived_columns_are_filled_on_a_second_thread_for_every_row(monkeypatch):
    # a run of three blocks (1 s each) of stretches of 900 and 100 cycles: every row's
    # distance columns, derived on the worker thread (the 900, each made 50 ms slow, so
    # that a block handed on before its rows are filled shows) or the loop's (the 100), are
    # the probe tip's height above its plane from that row's own handle pose (closed form:
    # p + L s, against the plane's point and normal), none lost, shifted or left unfilled
    # at a stretch's or block's end
    import threading
    import time

    from virtmech.sim.log import DerivedColumns

    threads, sunk = set(), []
    real = DerivedColumns.__call__

    def slow_on_the_worker(self, rows):
        name = threading.current_thread().name
        threads.add(name)
        if name != "MainThread":
            time.sleep(0.05)
        real(self, rows)

    monkeypatch.setattr(DerivedColumns, "__call__", slow_on_the_worker)
    s = load("omni-contact").with_overrides(duration_s=2.5)
    r = run(s, chunk_s=1.0, sink=lambda rows, cols: sunk.append(rows.copy()))
    assert r.n_cycles == 2501
    # the stretches before a block's last on the worker, the last on the loop's thread
    assert {t.split("_")[0] for t in threads} == {"virtmech-sim", "MainThread"}
    p, z = r.cols("px", "py", "pz"), r.cols("sx", "sy", "sz")
    height = (p + 0.08 * z - np.array([0.0, -0.07, -0.02])) @ np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(r.col("dist_normal"), height, rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.col("dist"), np.maximum(-height, 0.0), rtol=0, atol=1e-15)
    # the sink saw the same rows, derived columns filled, in order
    assert [len(b) for b in sunk] == [1000, 1000, 501]
    np.testing.assert_array_equal(np.concatenate(sunk), r.log)


def test_the_log_does_not_depend_on_how_the_run_is_split(monkeypatch):
    # noise, dropouts and several intent segments: blocks of 10 s (one), 1 s and 0.35 s
    # split the run into different stretches, planned and derived on different threads at
    # different times; the log is the same bit for bit. The plan of a stretch where a
    # segment starts (or the first) is made on the loop's thread from the handle's pose
    # there, every other one on the worker without it
    import threading

    s = load("omni-fig11").with_overrides(
        duration_s=2.5, sensors={"noise_rad": 2e-4, "dropout_probability": 0.05}
    )
    plans = []
    real_plan = Intent.plan

    def plan(self, k0, k1, T_handle):
        starts = set(self.start_cycles(2501)) | {0}
        plans.append((k0 in starts, threading.current_thread().name, T_handle is not None))
        return real_plan(self, k0, k1, T_handle)

    monkeypatch.setattr(Intent, "plan", plan)
    runs = [run(s, seed=3, chunk_s=c) for c in (10.0, 1.0, 0.35)]
    assert np.array_equal(runs[0].log, runs[1].log, equal_nan=True)
    assert np.array_equal(runs[0].log, runs[2].log, equal_nan=True)
    assert np.abs(runs[0].col("qm0") - runs[0].col("q0")).max() > 1e-5  # the noise is on
    assert {(st, t.split("_")[0], pose) for st, t, pose in plans} == {
        (True, "MainThread", True), (False, "virtmech-sim", False)}


def test_an_error_deriving_the_columns_is_raised_by_the_run(monkeypatch):
    # the first stretch derived on the worker fails: the run raises it
    import threading

    from virtmech.sim.log import DerivedColumns

    threads = []

    def failing(self, rows):
        threads.append(threading.current_thread().name)
        if threads[-1] != "MainThread":
            raise RuntimeError("derived columns failed")

    monkeypatch.setattr(DerivedColumns, "__call__", failing)
    with pytest.raises(RuntimeError, match="derived columns failed"):
        run(load("omni-contact").with_overrides(duration_s=1.5), chunk_s=1.0)
    assert any(t != "MainThread" for t in threads)


def test_the_hand_plan_is_the_per_cycle_intent():
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    T0 = arm.forward([0.2])
    hand = HandImpedance()
    T = 1e-3
    a = Intent(SEGMENTS, hand, arm, T0, T)
    b = CycleIntent(SEGMENTS, hand, arm, T0, T)
    N = 1100
    # a handle pose that moves, so segment starts that take the handle's pose are checked
    handle = [arm.forward([0.2 + 0.3 * k / N]) for k in range(N)]
    cuts = sorted(set(a.start_cycles(N)) | {0, 37, 400, N})
    assert {100, 300, 500, 700, 900} <= set(cuts)
    rows = np.vstack([a.plan(k0, k1, handle[k0]) for k0, k1 in zip(cuts[:-1], cuts[1:])])
    assert rows.shape == (N, len(PLAN_COLUMNS))
    for k in range(N):
        tg = b.update(k * T, handle[k])
        r = rows[k]
        np.testing.assert_allclose(r[0:3], tg.p, atol=1e-15)
        np.testing.assert_allclose(r[3:12].reshape(3, 3), tg.R, atol=1e-14)
        np.testing.assert_allclose(r[12:15], tg.v, atol=1e-9)
        np.testing.assert_allclose(r[15:18], tg.w, atol=1e-9)
        assert (r[18], r[19], r[20], r[21]) == (tg.k_t, tg.b_t, tg.k_r, tg.b_r)
        f, in_handle = r[plan_slice("fx", 3)], r[PLAN_INDEX["force_in_handle"]]
        force = handle[k][:3, :3] @ f if in_handle else f
        np.testing.assert_allclose(force, tg.force, atol=1e-14)
        assert r[PLAN_INDEX["segment"]] == tg.segment
        assert r[PLAN_INDEX["hand_attached"]] == 1.0 and not r[plan_slice("mx", 3)].any()
    # and the plan is not constant: every kind of segment moved something
    assert np.ptp(rows[:, 0]) > 0.01 and np.ptp(rows[:, 15:18]) > 0.1
    assert rows[:, PLAN_INDEX["force_in_handle"]].any()


def test_a_plan_across_a_segment_start_is_refused():
    arm = vm.PlanarArm([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    T0 = arm.forward([0.2])
    intent = Intent(SEGMENTS, HandImpedance(), arm, T0, 1e-3)
    with pytest.raises(ValueError, match="start_cycles"):
        intent.plan(0, 150, T0)


def _mujoco_timer() -> ctypes.c_void_p:
    # the library virtmech._sim loaded (the mujoco package's): the same mjcb_time
    from virtmech import _sim

    return ctypes.c_void_p.in_dll(ctypes.CDLL(_sim.__file__), "mjcb_time")


def test_the_loop_restores_mujocos_timer_callback():
    # (the restore on a throw is tested in C++: tests/cpp/test_sim_loop.cpp)
    before = _mujoco_timer().value
    assert before is not None  # the mujoco package installs one: the test is not vacuous
    run(load("omni-fig9").with_overrides(duration_s=0.05))
    assert _mujoco_timer().value == before


def _loop_settings(Cinv, c0, actuated) -> dict:
    from virtmech.sim.sensors import SensorSettings

    return dict(
        coupling_inv=Cinv,
        coupling_offset=c0,
        actuated=actuated,
        substeps=4,
        period_s=1e-3,
        comp_bodies=[],
        comp_masses=[],
        gravity=np.zeros(3),
        sensors=SensorSettings(counts_per_rev=0),
    )


#: one hinge about z with a motor that transmits nothing (gear 0)
HINGE_XML = (
    '<mujoco><worldbody><body><joint name="h" type="hinge"/><geom size="0.1"/></body>'
    '</worldbody><actuator><motor joint="h" gear="0"/></actuator></mujoco>'
)


def _hinge_loop(model, data):
    """The loop on HINGE_XML: a one-joint device, a PlanarArm."""
    T = np.eye(4)
    T[0, 3] = 0.1
    dev = vm.Device([vm.Joint("revolute", [0, 0, 1])], [True], handle=T)
    ctrl = vm.Controller(dev, vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1))
    return inner.ServoLoop(
        ctrl, model, data, log_columns=log_columns(1, 1),
        **_loop_settings(np.eye(1), np.zeros(1), [0]),
    )


def _still_plan(rows: int) -> np.ndarray:
    plan = np.zeros((rows, len(PLAN_COLUMNS)))
    plan[:, 3:12] = np.eye(3).ravel()
    return plan


def _log(rows: int, n: int = 1, m: int = 1) -> np.ndarray:
    return np.zeros((rows, len(log_columns(n, m))))


def test_the_loop_refuses_a_model_that_is_not_the_device():
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint type="hinge"/><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    data = mujoco.MjData(model)
    ctrl = vm.Controller(vm.PhantomOmni(), vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.08))
    with pytest.raises(ValueError, match="model: expected one MuJoCo .* joint per device joint"):
        inner.ServoLoop(
            ctrl, model, data, log_columns=log_columns(6, 1),
            **_loop_settings(np.eye(6), np.zeros(6), [0, 1, 2]),
        )


def test_the_layouts_come_from_the_tables(monkeypatch):
    cols = log_columns(6, 1)
    plan = inner.layout(inner.PLAN_FIELDS, PLAN_COLUMNS)
    log = inner.layout(inner.LOG_FIELDS, cols)
    assert plan["columns"] == len(PLAN_COLUMNS) and log["columns"] == len(cols)
    assert -1 not in plan.values() and -1 not in log.values()
    assert PLAN_COLUMNS[plan["anchor_R"] : plan["anchor_R"] + 9][-1] == "R22"
    assert cols[log["tau_motor"] : log["tau_motor"] + 6][-1] == "tau_motor5"
    # a layout names the loop's fields: a misspelt one is refused by the loop
    model = mujoco.MjModel.from_xml_string(HINGE_XML)
    monkeypatch.setitem(inner.LOG_FIELDS, "torque", "tau0")
    with pytest.raises(ValueError, match="log_layout: unknown field torque"):
        _hinge_loop(model, mujoco.MjData(model))


@pytest.mark.parametrize("device", ["omni", "planar3r"])
def test_step1_then_step2_is_mj_step_on_the_device_models(device):
    # the loop sets the motors and the hand's force between mj_step1 and mj_step2, which
    # must be mj_step with those inputs (the implicitfast integrator included)
    from virtmech.sim.model import build_mjcf, compile_model

    dev = vm.PhantomOmni() if device == "omni" else vm.Planar3R(0.25, 0.15)
    model = compile_model(build_mjcf(dev))
    d1, d2 = mujoco.MjData(model), mujoco.MjData(model)
    rng = np.random.default_rng(7)
    q0 = 0.3 * rng.normal(size=model.nq)
    for d in (d1, d2):
        d.qpos[:] = q0
    for _ in range(500):
        u = 0.2 * rng.normal(size=model.nu)
        f = 0.02 * rng.normal(size=model.nv)
        d1.ctrl[:], d1.qfrc_applied[:] = u, f
        mujoco.mj_step(model, d1)
        mujoco.mj_step1(model, d2)
        d2.ctrl[:], d2.qfrc_applied[:] = u, f
        mujoco.mj_step2(model, d2)
    assert np.ptp(d1.qpos) > 0.01  # it moved
    np.testing.assert_array_equal(d1.qpos, d2.qpos)
    np.testing.assert_array_equal(d1.qvel, d2.qvel)


def test_the_loop_writes_only_into_the_callers_arrays():
    from virtmech.sim.model import build_mjcf, compile_model

    omni = vm.PhantomOmni()
    built = build_mjcf(omni)
    model = compile_model(built)
    data = mujoco.MjData(model)
    data.qpos[:] = built.coupling.to_chain(omni.home)
    ctrl = vm.Controller(omni, vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.08))
    loop = inner.ServoLoop(
        ctrl, model, data, log_columns=log_columns(6, 1),
        **_loop_settings(built.coupling.Cinv, built.coupling.c0, [0, 1, 2]),
    )
    plan = _still_plan(3)
    noise, dropout = np.zeros((3, 6)), np.zeros(3)
    cols = len(log_columns(6, 1))
    with pytest.raises(TypeError):  # a converted copy would swallow the rows
        loop.run(0, plan, noise, dropout, np.zeros((3, cols), dtype=np.float32))
    with pytest.raises(TypeError):
        loop.run(0, plan, noise, dropout, np.zeros((3, 2 * cols))[:, ::2])
    with pytest.raises(ValueError, match=f"plan: expected shape \\(3, {len(PLAN_COLUMNS)}\\)"):
        loop.run(0, plan[:, :20].copy(), noise, dropout, np.zeros((3, cols)))
    with pytest.raises(ValueError, match="log: expected shape \\(3, "):
        loop.run(0, plan, noise, dropout, np.zeros((2, cols)))
    log = np.full((3, cols), -7.0)
    loop.run(0, plan, noise, dropout, log)
    c = log_columns(6, 1)
    np.testing.assert_allclose(log[:, c.index("t")], [0.0, 1e-3, 2e-3])  # t of each cycle
    np.testing.assert_allclose(log[0, c.index("q0") : c.index("q0") + 6], omni.home, atol=1e-12)
    # the columns computed after the run are left alone; every other column is written
    post = [i for i, name in enumerate(c) if (log[:, i] == -7.0).all()]
    assert [c[i] for i in post] == c[c.index("dist") :]


def test_a_loop_that_cannot_load_says_to_reinstall_virtmech(monkeypatch):
    # as when the installed mujoco is not the one virtmech._sim was built against (its
    # libmujoco.so.<version> is then missing)
    import sys

    monkeypatch.setitem(sys.modules, "virtmech._sim", None)
    with pytest.raises(ImportError, match="reinstall virtmech"):
        inner._sim_module()
