"""`virtmech drive --device openhaptics` end to end against the stand-in HD library
(tests/standin, built here with CMake when missing): the torques it commands against
vm.Controller's on the same readings, how it uses the HD API (frames, priority, force output,
no gimbal torque on the Omni), the ramp-in, the watchdog, and every way a run ends (Ctrl-C,
an HD error, a failing hdInitDevice, a missing library, a mismatched device, a stall)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time

import drive_support as ds
import numpy as np
import pyarrow.parquet as pq
import pytest

import virtmech as vm
from virtmech.builder import controller_kwargs, make_device, make_mechanism
from virtmech.sim.log import log_columns
from virtmech.sim.start import seeds

T = 1e-3
SCENARIO = """
[device]
type = "PhantomOmni"

[mechanism]
type = "PlanarArm"
pivot = [-0.07, 0.04, 0.0]
normal = [0.0, 0.0, 1.0]
length = 0.08
zero_direction = [1.0, 0.0, 0.0]

[controller]
passivity = "off"
kp = [500.0, 500.0, 500.0, 0.0, 0.0, 0.0]
"""
ZERO_MASK = 0b11110  # the driver flags of a zero-torque tick (watchdog, errors, stop)


@pytest.fixture(scope="module")
def library():
    return ds.standin_library()


def scenario_file(folder):
    path = folder / "circle.toml"
    path.write_text(SCENARIO)
    return path


@pytest.fixture
def scenario(tmp_path):
    return scenario_file(tmp_path)


def scenario_objects():
    """The scenario's data (defaults filled), its device and its mechanism."""
    import virtmech.scenarios as sc

    S = sc.loads('name = "circle"\nduration_s = 1.0\n' + SCENARIO).data
    return S, make_device(S["device"]), make_mechanism(S["mechanism"])


def run(library, source, out, cfg, *flags: str):
    """`virtmech drive SOURCE --library LIBRARY --out OUT FLAGS...` against the stand-in."""
    return ds.drive([str(source), "--library", str(library), "--out", str(out), *flags], cfg)


def held_poses(device, mech, seconds_each: float = 0.4) -> tuple[np.ndarray, list[int]]:
    """Joint readings holding five poses off the circle (up to 7 mm: forces up to the 3.3 N
    limit), each for seconds_each; and the index of each hold's last row."""
    holds = (
        (0.3, [0.002, 0, 0]),
        (0.6, [0, 0.004, 0.002]),
        (0.9, [0.007, 0, 0]),
        (0.2, [0, -0.003, -0.003]),
        (0.5, [0.0, 0.0, 0.0]),
    )
    poses = []
    for theta, offset in holds:
        th = mech.home.copy()
        th[0] = theta
        target = mech.forward(th)
        target[:3, 3] += offset
        q, err, _ = vm.reach(device, target, seeds(device), mech.length_scale)
        assert np.linalg.norm(err) < 1e-9
        poses.append(q)
    n = int(round(seconds_each / T))
    rows = np.repeat(np.array(poses), n, axis=0)
    return rows, [n * (i + 1) - 1 for i in range(len(poses))]


def read_log(out) -> tuple[list[str], np.ndarray]:
    t = pq.read_table(out / "log.parquet")
    return t.column_names, np.column_stack([c.to_numpy() for c in t.columns])


def driven_ticks(folder) -> np.ndarray:
    """The stand-in's tick rows in which the driver's callback ran (a torque was set)."""
    rows = ds.ticks(folder)
    return rows[np.isfinite(rows[:, ds.TRACE_COLUMNS.index("torque0")])]


@pytest.fixture(scope="module")
def held_run(library, tmp_path_factory):
    """One drive over the held poses, replayed by the stand-in (2.1 s)."""
    folder = tmp_path_factory.mktemp("held")
    S, device, mech = scenario_objects()
    q, ends = held_poses(device, mech)
    (folder / "circle.toml").write_text(SCENARIO)
    cfg = ds.write_config(folder, **ds.write_replay(folder, q), max_ticks=5000)
    out = folder / "out"
    flags = ("--duration", "2.1", "--format", "parquet", "--quiet")
    r = run(library, folder / "circle.toml", out, cfg, *flags)
    assert r.returncode == 0, r.stderr
    return dict(folder=folder, out=out, S=S, device=device, mech=mech, q=q, ends=ends)


def controller_of(S, device, mech, max_force=3.3):
    kw = dict(controller_kwargs(S["controller"]), watchdog_s=0.005, max_force=max_force)
    return vm.Controller(device, mech, **kw)


def test_commanded_torque_is_1000_times_the_controllers_on_the_same_readings(held_run):
    # the stand-in's readings and the torques set, tick by tick, against vm.Controller
    # stepped on the same readings, the velocity estimate written out, the same time stamps
    S, device, mech = held_run["S"], held_run["device"], held_run["mech"]
    trace = driven_ticks(held_run["folder"])
    cols, log = read_log(held_run["out"])
    assert len(log) == len(trace)
    q = trace[:, 1:7]
    np.testing.assert_array_equal(log[:, cols.index("qm0") : cols.index("qm0") + 6], q)
    dq = ds.velocity_estimate(q, T, 100.0)
    t, flags = log[:, cols.index("t")], log[:, cols.index("flags")].astype(int)
    ctrl = controller_of(S, device, mech)
    expected = np.array([ctrl.step(q[k], dq[k], t[k]).torque[:3] for k in range(len(q))])
    expected[(flags & ZERO_MASK) != 0] = 0.0
    commanded = trace[:, 7:10]
    np.testing.assert_array_equal(commanded, 1000.0 * expected)  # bit for bit
    # no clamp of the driver's own below the device's: torques beyond the 200 mN·m a vendor
    # sample clamps the Touch's waist and elbow to are sent as they are
    assert np.abs(commanded).max() > 250.0


def test_held_poses_command_1000_times_a_fresh_controllers_torque(held_run):
    # at the end of each hold (the velocity estimate settled to zero) the command equals
    # 1000 x the torque of a controller that has only ever seen that pose
    S, device, mech = held_run["S"], held_run["device"], held_run["mech"]
    trace = driven_ticks(held_run["folder"])
    cols, log = read_log(held_run["out"])
    checked = 0
    # (a hold the calibration's ticks took much of, still ramping in or after a watchdog
    # trip, is left out: the test above covers every tick)
    for pose in held_run["q"][held_run["ends"]]:
        rows = np.flatnonzero(np.all(trace[:, 1:7] == pose, axis=1))
        if len(rows) < 200 or log[rows[-1], cols.index("ramp")] < 1.0:
            continue
        ctrl = controller_of(S, device, mech)
        for _ in range(400):  # past the ramp-in (0.25 s)
            out = ctrl.step(pose, np.zeros(6))
        expected = 1000.0 * out.torque[:3]
        np.testing.assert_allclose(trace[rows[-1], 7:10], expected, rtol=1e-9, atol=1e-9)
        checked += 1
    assert checked >= 3


def test_the_hd_api_is_used_as_the_sdk_requires(held_run):
    s = ds.summary(held_run["folder"])
    assert s["sets_outside_frame"] == "0"  # every hdSet inside a frame
    assert s["illegal_begin"] == "0" and s["illegal_end"] == "0"
    assert s["frames_begun"] == s["frames_ended"]
    assert s["force_output_enables"] == "1"  # hdEnable(HD_FORCE_OUTPUT) ...
    assert s["torque_without_force_output"] == "0"  # ... before any torque
    assert s["priorities"].split()[-1] == "65535"  # the servo at HD_MAX_SCHEDULER_PRIORITY
    assert s["gimbal_sets"] == "0"  # no gimbal torque on an Omni / Touch
    assert np.isnan(ds.ticks(held_run["folder"])[:, 10:13]).all()
    assert s["scheduler_running"] == "0" and s["unscheduled"] == "1"
    assert s["disable_calls"] == "1"
    assert s["last_joint_torque"] == "0 0 0"


def assert_ramps_in(cols, log) -> None:
    """The log's ramp-in factor: 0.25 s from the first tick, from every watchdog trip and
    from the tick after a fault (a replayed jump between poses is an implausible velocity),
    1/250 more each tick, then 1 (the ticks after the stop have none, a fault's tick 0)."""
    ramp = log[:, cols.index("ramp")]
    flags = log[:, cols.index("flags")].astype(int)
    faulted = (log[:, cols.index("status")].astype(int) & vm.status.FAULT_MASK) != 0
    k = np.arange(len(ramp))
    start = np.maximum.accumulate(np.where(flags & 2, k, np.where(faulted, k + 1, 0)))
    expected = np.minimum(1.0, (k - start + 1) / 250.0)
    stepped = ((flags & ZERO_MASK) == 0) & ~faulted
    np.testing.assert_allclose(ramp[stepped], expected[stepped], rtol=1e-12)
    assert (ramp[faulted] == 0.0).all()


def test_the_force_ramps_in(held_run):
    trace = driven_ticks(held_run["folder"])
    cols, log = read_log(held_run["out"])
    assert_ramps_in(cols, log)
    ramp = log[:, cols.index("ramp")]
    assert ramp[0] == 1 / 250 and (ramp[:249] < 1).all()
    # and the command with it
    f = np.linalg.norm(log[:, cols.index("fx") : cols.index("fx") + 3], axis=1)
    assert f[0] < 0.01 * f[:250].max()
    assert np.linalg.norm(trace[0, 7:10]) < 0.01 * np.abs(trace[:, 7:10]).max()


def test_the_log_has_run_s_columns_and_the_device_in_run_json(held_run):
    cols, log = read_log(held_run["out"])
    assert cols[: len(log_columns(6, 1))] == log_columns(6, 1)
    driver = ["flags", "gap_s", "tick_us", "step_us", "device_error"]
    assert cols[len(log_columns(6, 1)) :] == driver
    run_json = json.loads((held_run["out"] / "run.json").read_text())
    d = run_json["drive"]
    assert d["device"]["model"] == "Touch"
    assert d["device"]["serial"] == "standin-0001"
    assert d["device"]["nominal_max_force_n"] == 3.3
    assert d["ended"] == "duration"
    assert d["ticks"] == len(log)
    # the rate the stand-in's scheduler runs at, as measured by the driver's clock
    assert d["measured_rate_hz"] == pytest.approx(1000.0, rel=0.02)
    assert run_json["controller_model"]["watchdog_s"] == 0.005
    assert run_json["controller_model"]["max_force"] == 3.3
    assert run_json["units"]["tick_us"].startswith("µs")
    assert math.isfinite(run_json["metrics"]["force_max_n"])


def test_a_shipped_scenario_s_simulation_sections_are_ignored_with_one_note(library, tmp_path):
    cfg = ds.write_config(tmp_path)
    r = run(library, "omni-fig11", tmp_path / "o", cfg, "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    notes = [line for line in r.stderr.splitlines() if "note:" in line]
    assert len(notes) == 1
    for table in ("[human]", "[[intent]]", "[initial]", "[checks]"):  # omni-fig11's
        assert table in notes[0]
    assert "[physics]" not in notes[0] and "[controller]" not in notes[0].split("ignored")[0]
    assert "Traceback" not in r.stderr
    # a file of [device], [mechanism] and [controller] alone gets no note
    r = run(library, scenario_file(tmp_path), tmp_path / "o", cfg, "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    assert "note:" not in r.stderr


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_stops_with_zero_torque_and_exit_0(library, scenario, tmp_path, signum):
    cfg = ds.write_config(tmp_path)
    out = tmp_path / "o"
    p = ds.drive_process([str(scenario), "--library", str(library), "--out", str(out)], cfg)
    try:
        deadline = time.monotonic() + 60
        while not (out / "log.csv").exists() and time.monotonic() < deadline:
            time.sleep(0.1)  # the first rows are written once the servo runs
        time.sleep(0.5)
        t0 = time.monotonic()
        p.send_signal(signum)
        p.wait(timeout=30)
        took = time.monotonic() - t0
    finally:
        p.kill()
    stdout, stderr = p.communicate()
    assert p.returncode == 0, stderr
    print(f"{signal.Signals(signum).name} to exit: {took:.2f} s")  # measured, not asserted
    assert "interrupted" in stdout
    s = ds.summary(tmp_path)
    assert s["scheduler_running"] == "0" and s["scheduler_stops"] != "0"
    assert s["unscheduled"] == "1"
    assert s["disable_calls"] == "1"
    assert s["last_joint_torque"] == "0 0 0"
    assert (driven_ticks(tmp_path)[-1, 7:10] == 0).all()


def test_an_hd_error_mid_run_zeroes_the_torque_and_exits_1_naming_it(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, error_at="600 0x0302 7")
    r = run(library, scenario, tmp_path / "o", cfg, "--duration", "5", "--quiet")
    assert r.returncode == 1
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, r.stderr
    assert "HD_COMM_ERROR (0x0302)" in lines[0]
    assert "communication error (stand-in)" in lines[0]  # hdGetErrorString's text
    s = ds.summary(tmp_path)
    assert s["error_tick"] == "600"
    assert s["nonzero_torque_after_error"] == "0"
    rows = ds.ticks(tmp_path)
    after = rows[600:]
    set_after = after[np.isfinite(after[:, 7])]
    assert len(set_after) > 0 and (set_after[:, 7:10] == 0).all()
    assert np.abs(rows[:600, 7:10][np.isfinite(rows[:600, 7])]).max() > 0
    assert s["disable_calls"] == "1" and s["scheduler_running"] == "0"


def test_a_ramp_in_that_steps_onto_the_hand_is_refused_before_any_force(
    library, scenario, tmp_path
):
    scenario.write_text(scenario.read_text() + "ramp_time_s = 0.001\n")  # [controller]'s
    cfg = ds.write_config(tmp_path)
    r = run(library, scenario, tmp_path / "o", cfg, "--duration", "0.5", "--quiet")
    assert r.returncode == 2, r.stdout + r.stderr
    assert "[controller] ramp_time_s: expected at least 0.02 s on a device" in r.stderr
    assert "got a ramp-in of 0.001 s" in r.stderr and "Traceback" not in r.stderr
    s = ds.summary(tmp_path)
    assert s["torque_sets"] == "0" and s["scheduler_running"] == "0"
    assert not (tmp_path / "o").exists()


def test_an_output_folder_that_cannot_be_made_is_refused_before_the_device_opens(
    library, scenario, tmp_path
):
    (tmp_path / "afile").write_text("")
    cfg = ds.write_config(tmp_path)
    r = run(library, scenario, tmp_path / "afile" / "o", cfg, "--duration", "0.5", "--quiet")
    assert r.returncode == 2, r.stdout + r.stderr
    assert "--out" in r.stderr and "afile is not a folder" in r.stderr
    s = ds.summary(tmp_path) if (tmp_path / "standin.trace").exists() else {}
    assert s.get("torque_sets", "0") == "0" and s.get("force_output_enables", "0") == "0"


class _ErrorAsTheDurationEnds:
    """A driver whose first poll shows both the duration over and a device error (an error
    in the run's last poll)."""

    stats = {"elapsed_s": 1.0004, "stop": "device_error", "device_error": 0x0302}
    stopped = False

    def read_records(self, most):
        return np.zeros((0, 4))

    def stalled(self, stall_s):
        return False

    def stop(self):
        self.stopped = True

    def describe_error(self, code):
        return f"HD_COMM_ERROR (0x{code:04X})"


def test_a_device_error_in_the_run_s_last_poll_is_named_not_taken_for_its_end():
    import types

    from virtmech import drive

    driver = _ErrorAsTheDurationEnds()
    rows = types.SimpleNamespace(columns=[])
    r = drive._serve(driver, "x", rows, types.SimpleNamespace(signal=None), 1.0, [], True)
    assert driver.stopped
    assert (r.reason, r.exit_code) == ("device_error", 1)
    assert "HD_COMM_ERROR (0x0302)" in r.message and "duration" not in r.message


CTRL_C_AFTER_OPEN = """
import os, signal, sys
import virtmech.drive as drive
check_rate = drive._check_rate
def interrupted(*args, **kwargs):  # Ctrl-C as the device has just opened (before calibrating)
    os.kill(os.getpid(), signal.SIGINT)
    return check_rate(*args, **kwargs)
drive._check_rate = interrupted
scenario, _ = drive.load(sys.argv[1])
r = drive.run(scenario, "openhaptics", library=sys.argv[2], quiet=True)
print(r.reason, r.exit_code, r.message, sep="|")
"""


def test_ctrl_c_after_the_device_opened_never_starts_the_servo(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path)
    env = {**os.environ, "VIRTMECH_STANDIN_CONFIG": str(cfg)}
    p = subprocess.run([sys.executable, "-c", CTRL_C_AFTER_OPEN, str(scenario), str(library)],
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    reason, code, message = p.stdout.strip().splitlines()[-1].split("|")
    assert (reason, code) == ("interrupted", "0")
    assert message == "stopped (interrupted) before the servo started"
    s = ds.summary(tmp_path)
    assert s["torque_sets"] == "0" and s["force_output_enables"] == "0", s
    assert s["scheduler_running"] == "0" and s["disable_calls"] == "1"


def test_a_failing_init_device_exits_1_naming_the_error(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, init_error="0x0303 -1")
    r = run(library, scenario, tmp_path / "o", cfg)
    assert r.returncode == 1
    assert "hdInitDevice" in r.stderr and "HD_COMM_CONFIG_ERROR (0x0303)" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert "Traceback" not in r.stderr


def test_a_missing_library_exits_2_naming_the_path(scenario, tmp_path):
    r = run("/nowhere/libHD.so", scenario, tmp_path / "o", None)
    assert r.returncode == 2
    assert "/nowhere/libHD.so" in r.stderr and "OpenHaptics" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    # none given and none installed: what was searched and what to install
    r = ds.drive([str(scenario), "--out", str(tmp_path / "o")], None)
    assert r.returncode == 2
    assert "libHD.so: not found" in r.stderr and "install OpenHaptics" in r.stderr
    assert not (tmp_path / "o").exists()  # refused before the servo: no folder made


def test_a_device_that_is_not_the_scenario_s_exits_2(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, model_type="Touch X")
    r = run(library, scenario, tmp_path / "o", cfg)
    assert r.returncode == 2
    assert "Touch X" in r.stderr and "HD_DEVICE_MODEL_TYPE" in r.stderr
    assert ds.summary(tmp_path)["disable_calls"] == "1"


def test_an_uncalibrated_device_is_calibrated_or_the_inkwell_asked_for(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, calibration="needs_update", calibration_style=2)
    r = run(library, scenario, tmp_path / "o", cfg, "--duration", "0.3")
    assert r.returncode == 0, r.stderr
    assert ds.summary(tmp_path)["calibration_updates"] == "1"
    cfg = ds.write_config(
        tmp_path, calibration="needs_manual_input", inkwell_after_checks=3, calibration_style=4
    )
    r = run(library, scenario, tmp_path / "o", cfg, "--duration", "0.3")
    assert r.returncode == 0, r.stderr
    assert "put the stylus in the inkwell" in r.stderr
    assert ds.summary(tmp_path)["calibration_state"] == str(0x5000)


def test_a_late_tick_zeroes_the_force_which_ramps_back(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, late_at="700 8")
    out = tmp_path / "o"
    r = run(library, scenario, out, cfg, "--duration", "1.2", "--format", "parquet", "--quiet")
    assert r.returncode == 0, r.stderr
    cols, log = read_log(out)
    flags = log[:, cols.index("flags")].astype(int)
    gap = log[:, cols.index("gap_s")]
    k = int(np.nanargmax(gap))  # the tick the stand-in held back by 8 ms
    assert gap[k] > 0.008 and flags[k] & 2
    assert (log[k, cols.index("tau_motor0") : cols.index("tau_motor0") + 6] == 0).all()
    assert np.abs(log[k - 1, cols.index("tau_motor0") : cols.index("tau_motor0") + 3]).max() > 0
    assert_ramps_in(cols, log)  # from it the force ramps in again
    # the late tick is the ramp's first (its torque zeroed), the next its second
    assert log[k, cols.index("ramp")] == 1 / 250 and log[k + 1, cols.index("ramp")] == 2 / 250
    assert json.loads((out / "run.json").read_text())["drive"]["watchdog_trips"] >= 1


def test_a_stalled_servo_ends_the_run_with_exit_1(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, stall_at=400)
    r = run(library, scenario, tmp_path / "o", cfg, "--duration", "10", "--quiet")
    assert r.returncode == 1
    assert "stalled" in r.stderr
    assert ds.summary(tmp_path)["disable_calls"] == "1"


def test_a_force_limit_above_the_device_s_is_brought_to_it(library, scenario, tmp_path):
    cfg = ds.write_config(tmp_path, nominal_max_force=1.2)
    out = tmp_path / "o"
    r = run(library, scenario, out, cfg, "--duration", "0.5", "--format", "parquet", "--quiet")
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "run.json").read_text())["controller_model"]["max_force"] == 1.2
    cols, log = read_log(out)
    f = np.linalg.norm(log[:, cols.index("fx") : cols.index("fx") + 3], axis=1)
    assert f.max() <= 1.2 + 1e-9


def test_a_set_of_mechanisms_is_driven(library, tmp_path):
    # omni-snap's [set]: every member with the watchdog and the device's force limit
    cfg = ds.write_config(tmp_path)
    out = tmp_path / "o"
    r = run(library, "omni-snap", out, cfg, "--duration", "0.3", "--format", "parquet", "--quiet")
    assert r.returncode == 0, r.stderr
    run_json = json.loads((out / "run.json").read_text())
    assert len(run_json["set_members"]) == 2
    assert run_json["controller_model"]["watchdog_s"] == 0.005
    cols, log = read_log(out)
    assert set(np.unique(log[:, cols.index("member")])) <= {-1.0, 0.0, 1.0}
    assert run_json["drive"]["ticks"] == len(log) >= 300


def test_the_viewer_follows_the_driven_device(library, tmp_path):
    # drive --view: the viewer's state (GET /state) is the device's latest tick: the handle
    # where the replayed readings put it, the target on it (no hand gizmo), time going on
    from test_view import free_port_pair, get_state

    S, device, mech = scenario_objects()
    q, _ = held_poses(device, mech)
    cfg = ds.write_config(tmp_path, **ds.write_replay(tmp_path, q))
    port = free_port_pair()
    args = [str(scenario_file(tmp_path)), "--library", str(library), "--duration", "6"]
    p = ds.drive_process([*args, "--out", str(tmp_path / "o"), "--view", str(port), "--quiet"], cfg)
    states = []
    try:
        deadline = time.monotonic() + 60
        while p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.5)
            try:
                states.append(get_state(port))
            except OSError:
                continue  # not serving yet, or stopped
        p.wait(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 0, p.communicate()[1]
    ticking = [s for s in states if s["t"] > 0]
    assert len(ticking) >= 3
    assert all(s["mode"] == "device" for s in states)
    assert ticking[-1]["t"] > ticking[0]["t"]
    poses = [device.forward(pose)[:3, 3] for pose in q[:: int(round(0.4 / T))]]
    for s in ticking:
        handle = np.asarray(s["handle"]["position"])
        assert min(np.linalg.norm(handle - x) for x in poses) < 1e-9
        np.testing.assert_array_equal(s["target"]["position"], handle)
