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

    # the deviation from the mechanism the driver measured, against the simulation's
    d_drive, d_sim = log["dist"][:n], reference.col("dist")[:n]
    # ... and the deviation of the simulated device's true handle (the stand-in's truth)
    tr = ds.truth(tmp_path)[:n]
    c = ds.TRUTH_COLUMNS
    p = tr[:, c.index("px") : c.index("px") + 3]
    z = tr[:, c.index("sx") : c.index("sx") + 3]
    e_pos = np.column_stack([log[f"e{i}"][:n] for i in range(3)])
    d_true = distances(reference.info["mechanism"], p, z, e_pos).columns()[:, 0]
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
    for d in (d_drive, d_true):
        assert abs(d.max() - d_sim.max()) <= 0.10 * d_sim.max()
        rms, rms_sim = np.sqrt(np.mean(d**2)), np.sqrt(np.mean(d_sim**2))
        assert abs(rms - rms_sim) <= 0.10 * rms_sim
    assert run_json["ended"] == "duration"
    if run_json["watchdog_trips"] == 0:
        # no tick late enough to trip the watchdog: the same readings, the same velocity
        # estimate, the same controller, so the same torques as the simulation's, bit for bit
        np.testing.assert_array_equal(tau_drive, tau_sim)
        np.testing.assert_allclose(d_true, d_sim, rtol=1e-12, atol=1e-15)
