"""`virtmech ros2` and `virtmech ros2-sim` over a real DDS on loopback: each test in its own
DDS domain, the nodes as processes, a probe node in the test's process.

- the node's commands are vm.Controller's on the same joint states (the Touch drivers'
  convention on the wire, the map and the velocity estimate written out here);
- stale input zeroes the command, once, and the status says so;
- the pair ros2 + ros2-sim closes the loop: the deviation from the mechanism is the
  simulated run's within 20 %;
- mistakes (parameters, ROS arguments, the missing extra) exit 2 with one message.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from ros2_support import ROS_PLATFORM, Probe, domain_id, efforts_of, finish, ros_env, virtmech

import virtmech as vm

pytestmark = pytest.mark.skipif(
    not ROS_PLATFORM, reason="the ROS 2 wheels exist for CPython >= 3.10 on Linux only"
)

NAMES = ("waist", "shoulder", "elbow", "yaw", "pitch", "roll")


def to_touch(q) -> np.ndarray:
    """The Touch drivers' joints from OpenHaptics' (omni_state.cpp), written out."""
    t1, t2, t3, g1, g2, g3 = q
    return np.array([-t1, t2, t3 - t2, math.pi - g1, -g2 - 3 * math.pi / 4, -g3 - math.pi])


def touch_efforts(tau) -> np.ndarray:
    """The Touch joints' efforts doing the work of OpenHaptics-joint torques tau: with
    waist = -t1, shoulder = t2, elbow = t3 - t2, the shoulder's effort carries the elbow's."""
    a, b, c, d, e, f = tau
    return np.array([-a, b + c, c, -d, -e, -f])


@pytest.fixture
def domain(worker_id):
    return domain_id(worker_id)


@pytest.fixture
def env(domain, monkeypatch):
    e = ros_env(domain)
    for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):
        monkeypatch.setenv(k, e[k])
    monkeypatch.delenv("ROS_LOCALHOST_ONLY", raising=False)
    return e


def _stop(p: subprocess.Popen, timeout: float = 30.0) -> tuple[int, str, str]:
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
    return finish(p, timeout)


def _trajectory(count: int) -> np.ndarray:
    """OpenHaptics joints of a handle sweeping past omni-fig11's circle (off it, so the
    force is not zero), inside the Omni's range."""
    s = np.linspace(0.0, 1.0, count)[:, None]
    a = np.array([0.05, 0.45, -0.10, 0.20, 0.60, 0.10])
    b = np.array([-0.10, 0.65, 0.15, -0.30, 0.90, -0.20])
    return a + (b - a) * (0.5 - 0.5 * np.cos(np.pi * s))


def test_commands_are_the_controllers(env, domain):
    """Joint states in the Touch's convention, stamped 1 ms apart, through the node: every
    joint_command's efforts are vm.Controller's torques on the same joints (velocities by the
    sensors' filtered difference), mapped by virtual work; effort_commands the actuated three
    in order; force_feedback the force whose J^T gives the motors' torques."""
    from virtmech.builder import build

    # a watchdog longer than any pause of the probe here: one command per joint state
    node = virtmech(["ros2", "omni-fig11", "--ros-args", "-p", "marker_rate_hz:=50.0",
                     "-p", "watchdog_s:=5.0"], env)
    probe = Probe(domain)
    try:
        probe.wait_connected()
        Q = _trajectory(300)
        t0 = 1_700_000_000 * 10**9
        T_ns = 1_000_000
        answers = []
        for k, q in enumerate(Q):
            r = to_touch(q)
            stamp = t0 + k * T_ns
            answers.append(
                probe.answer(stamp, resend=lambda r=r, s=stamp: probe.send(NAMES, r, s))
            )
        probe.wait_for(lambda: probe.messages("markers"), 10, "markers")
        for topic in ("effort_commands", "force_feedback"):
            probe.wait_for(lambda t=topic: len(probe.messages(t)) >= len(Q), 10, topic)
        efforts_msgs = probe.messages("effort_commands")
        wrench_msgs = probe.messages("force_feedback")
    finally:
        probe.close()
        rc, out, err = _stop(node)
    assert rc == 0, err

    # the same joint states, offline: the scenario's controller with the node's watchdog
    rig = build("omni-fig11", simulated=False)
    ctrl = rig.with_controller(watchdog_s=5.0).controller
    T = 1e-3
    alpha = T / (T + 1.0 / (2 * math.pi * rig.sensors.velocity_cutoff_hz))
    dq = np.zeros(6)
    expected = []
    for k, q in enumerate(Q):
        if k > 0:
            dq = dq + alpha * ((q - Q[k - 1]) / T - dq)
        expected.append(np.asarray(ctrl.step(q, dq, k * T).torque))
    got = np.array([efforts_of(m, NAMES) for m in answers])
    want = np.array([touch_efforts(tau) for tau in expected])
    assert np.abs(want[:, :3]).max() > 0.05  # a force acts: the comparison means something
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)

    # effort_commands, one per joint state (then the end's zero): waist, shoulder, elbow
    E = np.array([m.data for _, m in efforts_msgs])
    assert len(E) >= len(Q)
    np.testing.assert_allclose(E[: len(Q)], want[:, :3], rtol=1e-9, atol=1e-12)
    # force_feedback: the driver's axes (x, -z, y of OpenHaptics'); J_v^T F = motor torques
    assert len(wrench_msgs) >= len(Q)
    for (_, m), q, tau in zip(wrench_msgs, Q, expected):
        w = m.wrench
        F_hd = np.array([w.force.x, w.force.z, -w.force.y])
        J = rig.device.jacobian(q)[:3, :3]
        np.testing.assert_allclose(J.T @ F_hd, tau[:3], rtol=1e-9, atol=1e-12)
        assert [w.torque.x, w.torque.y, w.torque.z] == [0.0, 0.0, 0.0]
    assert "300 joint states, 0 late" in out


def test_stale_input_zeroes_the_command_once(env, domain):
    """Joint states off the mechanism (a force), then none: the node's watchdog (0.2 s here)
    publishes one zero command on every output and its status says stale; joint
    states again and the force is back, ramping in."""
    node = virtmech(["ros2", "omni-fig11", "--ros-args", "-p", "watchdog_s:=0.2",
                     "-p", "status_rate_hz:=20.0"], env)
    probe = Probe(domain)
    try:
        probe.wait_connected()
        r = to_touch(_trajectory(2)[0])
        t0 = 1_700_000_000 * 10**9
        for k in range(400):  # 0.4 s at 1 kHz: past the ramp-in
            stamp = t0 + k * 1_000_000
            m = probe.answer(stamp, resend=lambda s=stamp: probe.send(NAMES, r, s))
        force = np.abs(efforts_of(m, NAMES)).max()
        assert force > 0.05
        t_last = time.monotonic()
        # the zero commands before (a pause of this busy process longer than the watchdog)
        before = sum(not np.any(efforts_of(c, NAMES)) for _, c in probe.messages("joint_command"))
        first = probe.wait_for(
            lambda: [t for t, _ in probe.messages("joint_command") if t > t_last], 30,
            "the stale zero command",
        )[0]
        time.sleep(1.0)  # five watchdogs more: no second zero command
        cmds = [(t, c) for t, c in probe.messages("joint_command") if t > t_last]
        assert len(cmds) == 1 and not np.any(efforts_of(cmds[0][1], NAMES))  # once: zero
        # the watchdog (0.2 s), its timer and the delivery: measured, not asserted
        print(f"stale zero command {first - t_last:.3f} s after the last joint state")
        for topic, zero in (
            ("effort_commands", lambda m: not any(m.data)),
            ("force_feedback", lambda m: not any(
                [m.wrench.force.x, m.wrench.force.y, m.wrench.force.z])),
        ):
            after = [m for t, m in probe.messages(topic) if t > t_last]  # the last command's too
            assert zero(after[-1]) and sum(map(zero, after)) == 1, topic
        status = probe.wait_for(
            lambda: [json.loads(m.data) for t, m in probe.messages("status") if t > cmds[0][0]],
            30, "a status after the stale zero",
        )
        assert status[-1]["stale"] is True and status[-1]["stale_events"] == before + 1
        assert status[-1]["force_n"] == 0.0
        # joint states resume 1.6 s later on the device's clock: the force ramps in again
        stamps = [t0 + (2000 + k) * 1_000_000 for k in range(3)]
        again = [probe.answer(s, resend=lambda s=s: probe.send(NAMES, r, s)) for s in stamps]
        f_again = [np.abs(efforts_of(m, NAMES)).max() for m in again]
        assert 0.0 < f_again[0] < 0.1 * force and f_again[0] < f_again[1] < f_again[2]
    finally:
        probe.close()
        rc, out, err = _stop(node)
    assert rc == 0, err


def _dist_rms(log_csv) -> float:
    import csv

    with open(log_csv, newline="") as f:
        rows = csv.reader(f)
        head = next(rows)
        i = head.index("dist")
        d = np.array([float(r[i]) for r in rows])
    return float(np.sqrt(np.mean(d**2)))


def _closed_loop(env, tmp_path, scenario: str, duration: float, *sim_flags: str):
    """ros2-sim (lockstep unless told) and ros2 on one scenario; the sim's run.json and its
    log's RMS distance."""
    node = virtmech(["ros2", scenario, "--ros-args", "-p", "marker_rate_hz:=0.0"], env)
    sim = virtmech(
        ["ros2-sim", scenario, "--duration", str(duration), "--out", str(tmp_path / "sim"),
         "--wait", "60", *sim_flags], env,
    )
    try:
        rc, out, err = finish(sim, timeout=600)
    finally:
        nrc, nout, nerr = _stop(node)
    assert rc == 0, err
    assert nrc == 0, nerr
    run = json.loads((tmp_path / "sim" / "run.json").read_text())
    return run, _dist_rms(tmp_path / "sim" / "log.csv"), out


def _reference(scenario: str, duration: float, out_dir):
    from virtmech import scenarios as sc
    from virtmech.runner import run_scenario

    s = sc.load(scenario).with_overrides(duration_s=duration)
    out_dir.mkdir(parents=True)
    r = run_scenario(s, out=out_dir)
    return r.metrics, _dist_rms(out_dir / "log.csv")


def test_pair_reproduces_the_simulated_run(env, tmp_path):
    """omni-fig11 (the paper's Fig. 11 on the Omni: the hand twists the handle, the robot
    holds it on the circle) closed over DDS in lockstep, its first 1.5 s: the largest and the
    RMS distance from the circle within 20 % of `virtmech run`'s."""
    run, rms, out = _closed_loop(env, tmp_path, "omni-fig11", 1.5, "--lockstep")
    ref, ref_rms = _reference("omni-fig11", 1.5, tmp_path / "ref")
    info = run["ros2_sim"]
    assert info["cycles"] == 1501 and info["lockstep_missed"] == 0, out
    got = run["metrics"]["dist_max_m"]
    assert got == pytest.approx(ref["dist_max_m"], rel=0.2)
    assert rms == pytest.approx(ref_rms, rel=0.2)
    assert ref["dist_max_m"] > 1e-3  # the hand moves the handle: a deviation to reproduce
    # the log: every number finite, the renderer's columns (it runs in the other process) zero
    import csv

    with open(tmp_path / "sim" / "log.csv", newline="") as f:
        rows = list(csv.reader(f))
    log = np.array(rows[1:], dtype=float)
    head = rows[0]
    assert np.all(np.isfinite(log[:, [head.index(c) for c in ("t", "q0", "tau0", "dist")]]))
    for c in ("fx", "fy", "fz", "e0", "f_null0", "f_range0"):
        assert not np.any(log[:, head.index(c)]), c


@pytest.mark.slow
@pytest.mark.parametrize("command", ["effort_commands", "force_feedback"])
def test_pair_through_the_other_outputs(env, tmp_path, command):
    """The loop closed through ros2_control's effort array, or through the handle force the
    Touch's driver takes (applied as J^T F at each cycle's pose): the same deviation."""
    run, rms, out = _closed_loop(env, tmp_path, "omni-fig11", 1.5, "--lockstep",
                                 "--command", command)
    ref, ref_rms = _reference("omni-fig11", 1.5, tmp_path / "ref")
    assert run["ros2_sim"]["lockstep_missed"] == 0, out
    assert run["metrics"]["dist_max_m"] == pytest.approx(ref["dist_max_m"], rel=0.2)
    assert rms == pytest.approx(ref_rms, rel=0.2)


@pytest.mark.slow
def test_pair_in_real_time(env, tmp_path, capsys):
    """omni-fig11 whole, the simulated device paced by the wall clock at 1 kHz and the node
    answering what it can: the deviation within 20 % of the simulated run's. Prints the round
    trip (median, p99): measured, not asserted. On a machine too busy to run the simulated
    device at 1 kHz (more than 2 % of its cycles behind the wall clock) the run is not a real
    time one: the figures are printed and the test skipped (bench/ros2_latency.py measures
    the pair on any machine)."""
    run, rms, out = _closed_loop(env, tmp_path, "omni-fig11", 3.5)
    info = run["ros2_sim"]
    with capsys.disabled():
        print(f"\nros2 real time: {out.strip()}")
    assert info["round_trip_count"] > 0
    if info["realtime_behind"] > 0.02 * info["cycles"]:
        pytest.skip(f"this machine did not keep the pair at 1 kHz: {out.strip()}")
    ref, ref_rms = _reference("omni-fig11", 3.5, tmp_path / "ref")
    assert run["metrics"]["dist_max_m"] == pytest.approx(ref["dist_max_m"], rel=0.2)
    assert rms == pytest.approx(ref_rms, rel=0.2)


def test_sim_flags_are_checked(env):
    cases = [
        (["--timeout", "0"], "virtmech ros2-sim: --timeout 0: expected a number of seconds > 0"),
        (["--duration", "-1"], "virtmech ros2-sim: --duration -1:"),
        (["--command", "force"], "virtmech ros2-sim: argument --command: invalid choice"),
    ]
    procs = [virtmech(["ros2-sim", "omni-fig11", *a], env) for a, _ in cases]
    for p, (_, message) in zip(procs, cases):
        rc, out, err = finish(p)
        assert rc == 2 and err.startswith(message), err
        assert "Traceback" not in err


def test_bad_parameters_exit_2_with_a_message(env):
    cases = [
        (["-p", "joint_names:=[a,b]"], "virtmech ros2: joint_names: expected 6 names"),
        (["-p", "watchdog_s:=-1.0"], "virtmech ros2: watchdog_s: expected a number > 0"),
        (["-p", "wachdog_s:=0.1"], "virtmech ros2: -p wachdog_s: no such parameter"),
        (["-r", "joint_states"], "virtmech ros2: --ros-args -r joint_states: Couldn't parse"),
    ]
    procs = [virtmech(["ros2", "omni-fig11", "--ros-args", *a], env) for a, _ in cases]
    for p, (_, message) in zip(procs, cases):
        rc, out, err = finish(p)
        assert rc == 2, err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(message), err
        assert "Traceback" not in err


def test_missing_extra_names_the_pip_command(monkeypatch, capsys):
    from virtmech import cli

    monkeypatch.setitem(sys.modules, "rclpy", None)
    assert cli.main(["ros2", "omni-fig11"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("virtmech ros2: ROS 2 needs the [ros2] extra")
    assert "pip install 'virtmech[ros2]'" in err and len(err.splitlines()) == 1


def test_virtmech_imports_no_ros():
    code = (
        "import sys, virtmech, virtmech.cli; virtmech.cli.build_parser(); "
        "import virtmech.ros2, virtmech.ros2.render; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rcl_interfaces')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={**os.environ})
    assert out.stdout.strip() == "[]"


def test_markers_and_status(env, domain):
    """The MarkerArray draws the mechanism (the circle), the placements and the forces; the
    status topic gives the rate and the controller's status names."""
    node = virtmech(["ros2", "omni-fig11", "--ros-args", "-p", "marker_rate_hz:=1000.0",
                     "-p", "status_rate_hz:=20.0", "-p", "watchdog_s:=5.0"], env)
    probe = Probe(domain)
    try:
        probe.wait_connected()
        r = to_touch(_trajectory(2)[0])
        t0 = 1_700_000_000 * 10**9
        for k in range(50):
            s = t0 + k * 1_000_000
            probe.answer(s, resend=lambda s=s: probe.send(NAMES, r, s))
        arrays = probe.wait_for(lambda: probe.messages("markers"), 10, "markers")
        status = probe.wait_for(
            lambda: [m for _, m in probe.messages("status")
                     if json.loads(m.data)["messages"] == 50],
            10, "a status after the 50 joint states",
        )
    finally:
        probe.close()
        _stop(node)
    ns = {m.ns for _, a in arrays for m in a.markers}
    assert {"mechanism", "handle", "theta", "theta_star", "force", "force_null", "force_range",
            "values"} <= ns
    circle = next(m for _, a in arrays for m in a.markers if m.ns == "mechanism" and m.points
                  and m.type == m.LINE_LIST)
    P = np.array([[p.x, p.y, p.z] for p in circle.points])
    mech = vm.PlanarArm([-0.07, 0.04, 0.0], [0.0, 0.0, 1.0], 0.08, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(np.linalg.norm(P - np.array(mech.to_dict()["pivot"]), axis=1),
                               0.08, atol=1e-12)
    s = json.loads(status[-1].data)
    assert "ramping" in s["status"] and s["stale"] is False and s["late"] == 0
    assert s["node"] == "/virtmech" and s["input"] == "/joint_states"
