"""`virtmech drive --device forcedimension` end to end against the stand-in DHD library
(tests/standin/standin_dhd.cpp, built here with CMake when missing): the force it sets is
Kp times the deviation and points back to the mechanism, an omega.6 gets no torque, a
sigma.7 its torque and a zero gripper force, the force ramps in, and every way a run ends
(Ctrl-C, a failing DHD call, a failing dhdOpen, a device virtmech does not model, a device
that is not the scenario's)."""

from __future__ import annotations

import json
import signal
import time

import drive_support as ds
import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.spatial.transform import Rotation

KP = 500.0
SCENARIO = """
[device]
type = "CartesianDevice"
model = "{model}"

[mechanism]
type = "Probe"
plane_point = [0.0, 0.0, -0.04]
plane_normal = [0.0, 0.0, 1.0]
length = 0.05

[controller]
passivity = "off"
kp = [500.0, 500.0, 500.0, 0.0, 0.0, 0.0]
"""
#: the stand-in's tick rows (standin_dhd.cpp, kTraceWidth)
COLUMNS = (
    ["tick", "px", "py", "pz", "a", "b", "c", "fx", "fy", "fz", "tx", "ty", "tz", "fg", "call"]
    + ["failure", "gap_s"]
)
ZERO_MASK = 0b11110  # the driver flags of a zero-force tick (watchdog, errors, stop)
#: a handle held with the probe's tip inside the plane (2.5 mm with the wrist turned, 4 mm on
#: a Falcon, whose handle does not turn)
POSITION = [0.01, -0.02, 0.006]
ROTATION = [0.2, -0.15, 0.4]


@pytest.fixture(scope="module")
def library():
    return ds.standin_library("dhd")


def scenario(folder, model="omega.6"):
    path = folder / "probe.toml"
    path.write_text(SCENARIO.format(model=model))
    return path


def ticks(folder) -> np.ndarray:
    data = np.fromfile(folder / "standin.trace.ticks", dtype=np.float64)
    return data.reshape(-1, len(COLUMNS))


def col(rows, name):
    return rows[:, COLUMNS.index(name)]


def depth_along_normal(position, rotation, model) -> float:
    """How far the probe's tip is below the plane z = -0.04 [m]: the tip 50 mm along the
    handle's +z, the SDK frame's -z (the default handle rotation), turned by the wrist where
    the model senses it (SciPy's intrinsic x-y-z rotation)."""
    R = Rotation.from_euler("XYZ", rotation).as_matrix() if model != "falcon" else np.eye(3)
    tip = np.asarray(position) + 0.05 * (R @ [0.0, 0.0, -1.0])
    return -0.04 - tip[2]


def drive(library, folder, model="omega.6", *flags, **config):
    keys = dict(position=POSITION, rotation=ROTATION, max_ticks=20000, **config)
    cfg = ds.write_config(folder, **keys)
    args = [str(scenario(folder, model)), "--device", "forcedimension", "--library",
            str(library), "--out", str(folder / "out"), *flags]
    return ds.drive(args, cfg)


def read_log(out) -> tuple[list[str], np.ndarray]:
    t = pq.read_table(out / "log.parquet")
    return t.column_names, np.column_stack([c.to_numpy() for c in t.columns])


def ramped_in(out) -> np.ndarray:
    """The ticks of a run's log (parquet) with the whole force: ramped in, not zeroed."""
    cols, log = read_log(out)
    flags = log[:, cols.index("flags")].astype(int)
    return (log[:, cols.index("ramp")] == 1.0) & ((flags & ZERO_MASK) == 0)


@pytest.fixture(scope="module")
def omega6_run(library, tmp_path_factory):
    folder = tmp_path_factory.mktemp("omega6")
    r = drive(library, folder, "omega.6", "--duration", "1.0", "--format", "parquet",
              system_type=34)
    assert r.returncode == 0, r.stderr
    return folder, r


def test_the_force_points_back_with_kp_times_the_deviation_and_no_torque_on_an_omega6(
    omega6_run,
):
    folder, _ = omega6_run
    rows = ticks(folder)
    held = rows[ramped_in(folder / "out")]  # past the ramp-in, before the stop's zero force
    assert len(held) > 300
    d = depth_along_normal(POSITION, ROTATION, "omega.6")
    assert 0.002 < d < 0.02
    F = held[:, [COLUMNS.index(c) for c in ("fx", "fy", "fz")]]
    expected = KP * d * np.array([0.0, 0.0, 1.0])  # out of the plane, back to the mechanism
    err = np.linalg.norm(F - expected, axis=1) / np.linalg.norm(expected)
    assert err.max() < 0.10, err.max()
    # no torque on an omega.6, whose wrist has no motors; dhdSetForceAndTorque (no gripper)
    assert np.all(held[:, COLUMNS.index("tx") : COLUMNS.index("tz") + 1] == 0.0)
    assert np.all(col(rows, "call") == 1)


def test_the_force_set_is_the_controllers_and_ramps_in(omega6_run):
    folder, _ = omega6_run
    rows = ticks(folder)
    cols, log = read_log(folder / "out")
    assert len(rows) == len(log)
    F_set = rows[:, [COLUMNS.index(c) for c in ("fx", "fy", "fz")]]
    F = log[:, cols.index("fx") : cols.index("fx") + 3]
    np.testing.assert_allclose(F_set, F, rtol=1e-12, atol=1e-12)  # the wrench sent as it is
    # the ramp-in: 1/250 more of the force each tick from the start (and from a watchdog
    # trip of a late tick), the force the ramp's factor times the same wrench
    ramp, flags = log[:, cols.index("ramp")], log[:, cols.index("flags")].astype(int)
    assert ramp[0] == 1 / 250
    stepped = (flags & ZERO_MASK) == 0
    k = np.arange(len(ramp))
    start = np.maximum.accumulate(np.where(flags & 2, k, 0))
    expected = np.minimum(1.0, (k - start + 1) / 250.0)
    np.testing.assert_allclose(ramp[stepped], expected[stepped], rtol=1e-12)
    unit = F[stepped] / ramp[stepped, None]
    np.testing.assert_allclose(unit, np.tile(unit[-1], (len(unit), 1)), rtol=1e-9, atol=1e-9)


def test_the_sdk_is_used_as_it_requires(omega6_run):
    folder, r = omega6_run
    s = ds.summary(folder)
    assert s["opens"] == "1" and s["closes"] == "1"
    assert s["stops"] == "1" and s["stop_before_close"] == "1"  # dhdStop, then dhdClose
    assert s["enables"] == "1" and s["sets_without_force"] == "0"
    assert s["calls_closed"] == "0" and s["bad_id"] == "0"
    rows = ticks(folder)
    assert np.all(rows[-1, COLUMNS.index("fx") : COLUMNS.index("tz") + 1] == 0.0)
    run = json.loads((folder / "out" / "run.json").read_text())
    dev = run["drive"]["device"]
    assert dev["model"] == "omega.6" and dev["vendor"] == "Force Dimension"
    assert dev["nominal_max_force_n"] == 12.0
    assert run["drive"]["measured_rate_hz"] == pytest.approx(1000.0, rel=0.05)
    if not dev["realtime_priority"]:
        # a servo thread at normal priority is said, with the jitter it measured
        assert "SCHED_FIFO not permitted" in r.stderr
        assert "worst gap between ticks" in r.stderr


def test_a_sigma7_gets_its_torque_and_a_zero_gripper_force(library, tmp_path):
    r = drive(library, tmp_path, "sigma.7", "--duration", "0.6", "--quiet", "--format",
              "parquet", system_type=104)
    assert r.returncode == 0, r.stderr
    rows = ticks(tmp_path)
    assert np.all(col(rows, "call") == 2) and np.all(col(rows, "fg") == 0.0)
    # the wrench the controller rendered is what was set: force and torque (its wrist driven)
    cols, log = read_log(tmp_path / "out")
    sent = rows[:, COLUMNS.index("fx") : COLUMNS.index("tz") + 1]
    rendered = log[:, cols.index("fx") : cols.index("fx") + 6]
    np.testing.assert_allclose(sent, rendered, rtol=1e-12, atol=1e-12)
    held = ramped_in(tmp_path / "out")
    assert held.sum() > 100
    assert np.linalg.norm(sent[held, 3:], axis=1).min() > 1e-3  # a torque, not only a force
    # the force pushes the tip back out of the plane (the fully actuated law shares the
    # deviation between the handle's position and its turn: less than Kp x depth)
    F = sent[held, :3]
    d = depth_along_normal(POSITION, ROTATION, "sigma.7")
    assert np.all(F[:, 2] > 0.5 * KP * d) and np.all(F[:, 2] <= KP * d)
    assert np.abs(F[:, :2]).max() < 1e-3 * KP * d


def test_a_falcon_is_driven_in_translation(library, tmp_path):
    r = drive(library, tmp_path, "falcon", "--duration", "0.6", "--quiet", "--format",
              "parquet", system_type=60)
    assert r.returncode == 0, r.stderr
    rows = ticks(tmp_path)
    held = rows[ramped_in(tmp_path / "out")]
    assert len(held) > 100
    d = depth_along_normal(POSITION, ROTATION, "falcon")  # its orientation is not sensed
    F = held[:, [COLUMNS.index(c) for c in ("fx", "fy", "fz")]]
    np.testing.assert_allclose(F, np.tile([0.0, 0.0, KP * d], (len(F), 1)), atol=0.1 * KP * d)
    assert np.all(held[:, COLUMNS.index("tx") : COLUMNS.index("tz") + 1] == 0.0)


def test_ctrl_c_stops_with_zero_force_and_exit_0(library, tmp_path):
    cfg = ds.write_config(tmp_path, position=POSITION, rotation=ROTATION)
    out = tmp_path / "o"
    args = [str(scenario(tmp_path)), "--device", "forcedimension", "--library", str(library),
            "--out", str(out)]
    p = ds.drive_process(args, cfg)
    try:
        deadline = time.monotonic() + 60
        while not (out / "log.csv").exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.5)
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    finally:
        p.kill()
    stdout, stderr = p.communicate()
    assert p.returncode == 0, stderr
    assert "interrupted" in stdout and "Traceback" not in stderr
    s = ds.summary(tmp_path)
    assert s["stops"] == "1" and s["closes"] == "1" and s["calls_closed"] == "0"
    rows = ticks(tmp_path)
    rows = rows[np.isfinite(col(rows, "fx"))]
    assert np.all(rows[-1, COLUMNS.index("fx") : COLUMNS.index("tz") + 1] == 0.0)
    assert np.abs(col(rows, "fz")).max() > 1.0


@pytest.mark.parametrize("call,name", [("force", "dhdSetForceAndTorque"),
                                       ("pose", "dhdGetPositionAndOrientationFrame")])
def test_a_failing_dhd_call_zeroes_the_force_and_exits_1_naming_the_sdk_error(
    library, tmp_path, call, name
):
    r = drive(library, tmp_path, "omega.6", "--duration", "5", "--quiet",
              error_at=f"400 {call}")
    assert r.returncode == 1
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert f"{name} failed: communication error (stand-in: injected at tick 400)" in lines[0]
    assert "dhdErrorGetLastStr" in lines[0] and "force zeroed" in lines[0]
    s = ds.summary(tmp_path)
    assert s["nonzero_after_failure"] == "0"
    assert s["stops"] == "1" and s["closes"] == "1"
    rows = ticks(tmp_path)
    before = rows[:400][np.isfinite(rows[:400, COLUMNS.index("fz")])]
    assert np.abs(before[:, COLUMNS.index("fz")]).max() > 1.0


def test_a_failing_open_exits_1_naming_the_sdk_error(library, tmp_path):
    r = drive(library, tmp_path, "omega.6", open_error="no device found (stand-in)")
    assert r.returncode == 1
    assert "dhdOpen failed: no device found (stand-in)" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_a_device_virtmech_does_not_model_is_refused(library, tmp_path):
    r = drive(library, tmp_path, "omega.6", system_type=63)
    assert r.returncode == 2
    assert "delta.3" in r.stderr and "system type 63" in r.stderr
    assert "does not model" in r.stderr and "Traceback" not in r.stderr
    assert ds.summary(tmp_path)["closes"] == "1"  # closed again


def test_a_device_that_is_not_the_scenario_s_model_is_refused(library, tmp_path):
    r = drive(library, tmp_path, "omega.6", system_type=104)
    assert r.returncode == 2
    assert 'model = "sigma.7"' in r.stderr and "Traceback" not in r.stderr


def test_a_missing_library_exits_2_naming_the_path(tmp_path):
    missing = tmp_path / "nowhere" / "libdhd.so"
    args = [str(scenario(tmp_path)), "--device", "forcedimension", "--library", str(missing)]
    r = ds.drive(args, None)
    assert r.returncode == 2
    assert str(missing) in r.stderr and "Force Dimension SDK" in r.stderr
