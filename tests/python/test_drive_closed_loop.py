"""The closed loop through a device: `virtmech drive` against the stand-in HD library serving
the simulated Omni (the MuJoCo model and loop of `virtmech run`, the same hand plan)
reproduces `virtmech run` of the same scenario."""

from __future__ import annotations

import json

import drive_support as ds
import numpy as np
import pyarrow.parquet as pq
import pytest

import virtmech.scenarios as sc
from virtmech import sim
from virtmech.sim.geometry import distances


@pytest.fixture(scope="module")
def library():
    return ds.standin_library()


def deviations(log: dict, reference, folder, dof: int, n: int):
    """The first n cycles' deviation from the mechanism: as the driver measured it (its
    log), of the simulated device's true handle (the stand-in's truth rows) and as the
    simulation measured it (`reference`, the SimResult of `virtmech run`)."""
    tr = ds.truth(folder, dof)[:n]
    c = ds.truth_columns(dof)
    p = tr[:, c.index("px") : c.index("px") + 3]
    z = tr[:, c.index("sx") : c.index("sx") + 3]
    e_pos = np.column_stack([log[f"e{i}"][:n] for i in range(3)])
    d_true = distances(reference.info["mechanism"], p, z, e_pos).columns()[:, 0]
    return log["dist"][:n], d_true, reference.col("dist")[:n]


def assert_within_a_tenth(d_drive, d_true, d_sim):
    """The driven run's deviations (measured, true) have the simulated run's maximum and rms
    within 10 %."""
    for d in (d_drive, d_true):
        assert abs(d.max() - d_sim.max()) <= 0.10 * d_sim.max()
        rms, rms_sim = np.sqrt(np.mean(d**2)), np.sqrt(np.mean(d_sim**2))
        assert abs(rms - rms_sim) <= 0.10 * rms_sim


@pytest.mark.parametrize("name", ["omni-fig11", "omni-fig10"])
def test_driving_the_simulated_omni_reproduces_virtmech_run(library, tmp_path, name):
    scenario = sc.load(name)
    reference = sim.run(scenario)
    cfg = ds.write_config(tmp_path, **ds.mujoco_config(tmp_path, scenario, reference))
    out = tmp_path / "out"
    # a watchdog above this machine's scheduling hiccups (the ticks' timing is measured, and
    # printed, not asserted): a trip cuts the force for its ramp-in, a different run
    args = [name, "--library", str(library), "--duration", str(scenario.duration_s)]
    args += ["--watchdog-ms", "20"]
    r = ds.drive([*args, "--out", str(out), "--format", "parquet", "--quiet"], cfg)
    assert r.returncode == 0, r.stderr
    table = pq.read_table(out / "log.parquet")
    log = {c: table.column(c).to_numpy() for c in table.column_names}
    n = min(len(log["t"]), reference.n_cycles)
    assert n >= reference.n_cycles - 1

    d_drive, d_true, d_sim = deviations(log, reference, tmp_path, 6, n)
    run_json = json.loads((out / "run.json").read_text())["drive"]
    tau_drive = np.column_stack([log[f"tau{i}"][:n] for i in range(6)])
    tau_sim = reference.cols(*[f"tau{i}" for i in range(6)])[:n]
    print(
        f"{name}: {n} ticks at {run_json['measured_rate_hz']:.2f} Hz, "
        f"{run_json['late_ticks']} late, {run_json['watchdog_trips']} watchdog, worst gap "
        f"{run_json['worst_gap_s'] * 1e3:.2f} ms, worst tick {run_json['worst_tick_us']:.1f} us; "
        f"max dist: drive {d_drive.max() * 1e3:.4f} mm, true {d_true.max() * 1e3:.4f} mm, "
        f"run {d_sim.max() * 1e3:.4f} mm; rms dist: drive {np.sqrt(np.mean(d_drive**2)) * 1e3:.4f}"
        f" mm, run {np.sqrt(np.mean(d_sim**2)) * 1e3:.4f} mm; max |tau drive - tau run| "
        f"{np.abs(tau_drive - tau_sim).max():.3g} N m"
    )
    assert_within_a_tenth(d_drive, d_true, d_sim)
    assert run_json["ended"] == "duration"
    if run_json["watchdog_trips"] == 0:
        # no tick late enough to trip the watchdog: the same readings, the same velocity
        # estimate, the same controller, so the same torques as the simulation's, bit for bit
        np.testing.assert_array_equal(tau_drive, tau_sim)
        np.testing.assert_allclose(d_true, d_sim, rtol=1e-12, atol=1e-15)


@pytest.fixture(scope="module")
def dhd_library():
    return ds.standin_library("dhd")


#: the system type the stand-in DHD library reports for each model (dhdGetSystemType's values)
SYSTEM_TYPE = {"omega.6": 34, "sigma.7": 104, "falcon": 60}


@pytest.mark.parametrize(
    "name, model",
    [("omega6-fig11", "omega.6"), ("omega6-fig11", "sigma.7"), ("falcon-contact", "falcon")],
)
def test_driving_the_simulated_cartesian_device_reproduces_virtmech_run(
    dhd_library, tmp_path, name, model
):
    """`virtmech drive --device forcedimension` against the stand-in DHD library serving the
    simulated omega.6, sigma.7 or Falcon (the MuJoCo model and loop of `virtmech run`, the
    same hand plan): the pose it serves is what the simulation's encoders read, the velocities
    the device's true rates (the SDK's own, in place of the driver's estimate), and the
    deviation from the mechanism is the simulated run's within 10 %."""
    path = tmp_path / f"{name}.toml"
    text = sc.path_of(name).read_text()
    path.write_text(text.replace('model = "omega.6"', f'model = "{model}"'))
    scenario = sc.load(path)
    assert scenario.data["device"]["model"] == model
    reference = sim.run(scenario)
    keys = ds.mujoco_config(tmp_path, scenario, reference)
    cfg = ds.write_config(tmp_path, system_type=SYSTEM_TYPE[model], **keys)
    out = tmp_path / "out"
    args = [str(path), "--device", "forcedimension", "--library", str(dhd_library)]
    args += ["--duration", str(scenario.duration_s), "--watchdog-ms", "20"]
    r = ds.drive([*args, "--out", str(out), "--format", "parquet", "--quiet"], cfg)
    assert r.returncode == 0, r.stderr
    table = pq.read_table(out / "log.parquet")
    log = {c: table.column(c).to_numpy() for c in table.column_names}
    n = min(len(log["t"]), reference.n_cycles)
    # the driver's own loop thread runs for the duration by the clock: a loaded machine may
    # leave it a few ticks short of the simulation's cycles
    assert n >= 0.99 * reference.n_cycles
    summary = ds.summary(tmp_path)
    # every control cycle sensed exactly the reading the stand-in served before it
    assert int(summary["reading_mismatches"]) == 0
    assert int(summary["cycles"]) >= n

    dof = 6 if model != "falcon" else 3
    d_drive, d_true, d_sim = deviations(log, reference, tmp_path, dof, n)
    run_json = json.loads((out / "run.json").read_text())["drive"]
    print(
        f"{name} on a simulated {model}: {n} ticks at {run_json['measured_rate_hz']:.2f} Hz, "
        f"{run_json['late_ticks']} late, {run_json['watchdog_trips']} watchdog; max dist: "
        f"drive {d_drive.max() * 1e3:.4f} mm, true {d_true.max() * 1e3:.4f} mm, run "
        f"{d_sim.max() * 1e3:.4f} mm; rms dist: drive {np.sqrt(np.mean(d_drive**2)) * 1e3:.4f}"
        f" mm, run {np.sqrt(np.mean(d_sim**2)) * 1e3:.4f} mm"
    )
    assert_within_a_tenth(d_drive, d_true, d_sim)
    assert run_json["ended"] == "duration"
    # the wrist's torque: the sigma.7's only (the omega.6's wrist has no motors)
    rows = np.fromfile(tmp_path / "standin.trace.ticks", dtype=np.float64).reshape(-1, 17)
    torque = np.abs(rows[:, 10:13]).max()
    assert (torque > 0.0) == (model == "sigma.7")
