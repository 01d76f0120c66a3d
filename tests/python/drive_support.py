"""The stand-in vendor libraries (tests/standin: OpenHaptics HD, Force Dimension DHD) for the
tests of `virtmech drive`: found or built with CMake, configured through the file
VIRTMECH_STANDIN_CONFIG names, and their traces read back (the summary's key-value lines and
one row per tick)."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

#: the columns of a tick row of the stand-in's trace (standin_hd.cpp, kTraceWidth)
TRACE_COLUMNS = (
    ["tick"]
    + [f"q{i}" for i in range(6)]
    + [f"torque{i}" for i in range(3)]
    + [f"gimbal_torque{i}" for i in range(3)]
    + ["error", "unused", "frames", "gap_s", "realtime"]
)


def _cmake(*args: str, cwd: Path = ROOT) -> None:
    r = subprocess.run(["cmake", *args], cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(
            f"building the stand-in HD library failed: cmake {' '.join(args)}\n"
            f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
        )


def standin_library(sdk: str = "hd") -> Path:
    """The stand-in libHD.so (sdk "hd") or libdhd.so (sdk "dhd"): $VIRTMECH_STANDIN_HD (or
    $VIRTMECH_STANDIN_DHD), else built with CMake (the target virtmech_standin_hd or
    virtmech_standin_dhd) in build/cpp where scripts/test.sh configured it, else in
    build/standin. A failure to build raises (the tests fail: they are never skipped)."""
    target, file = {"hd": ("virtmech_standin_hd", "libHD.so"),
                    "dhd": ("virtmech_standin_dhd", "libdhd.so")}[sdk]
    given = os.environ.get(f"VIRTMECH_STANDIN_{sdk.upper()}")
    if given:
        return Path(given)
    (ROOT / "build").mkdir(exist_ok=True)
    with open(ROOT / "build" / ".standin.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one build at a time (pytest-xdist's workers)
        build = ROOT / "build" / "cpp"
        if not (build / "CMakeCache.txt").exists():
            build = ROOT / "build" / "standin"
            if not (build / "CMakeCache.txt").exists():
                generator = ["-G", "Ninja"] if shutil.which("ninja") else []
                _cmake(
                    "-S",
                    str(ROOT),
                    "-B",
                    str(build),
                    *generator,
                    "-DCMAKE_BUILD_TYPE=Release",
                    "-DVIRTMECH_BUILD_STANDIN=ON",
                    f"-DPython_EXECUTABLE={sys.executable}",
                )
        _cmake("--build", str(build), "--target", target, "-j", "2")
    lib = build / "tests" / "standin" / file
    if not lib.exists():
        raise RuntimeError(f"the stand-in HD library was not built: {lib}")
    return lib


def write_config(folder: Path, **keys) -> Path:
    """A stand-in configuration in folder/standin.cfg, its trace in folder/standin.trace;
    keys: the configuration's keys (lists and arrays as space-separated numbers)."""
    cfg = folder / "standin.cfg"
    lines = [f"trace {folder / 'standin.trace'}"]
    for key, value in keys.items():
        if isinstance(value, (list, tuple, np.ndarray)):
            value = " ".join(repr(v) for v in np.asarray(value).ravel().tolist())
        lines.append(f"{key} {value}")
    cfg.write_text("\n".join(lines) + "\n")
    return cfg


def write_replay(folder: Path, q: np.ndarray) -> dict:
    """The replay stand-in's keys serving the angles q (ticks x 6: joints, gimbal [rad])."""
    path = folder / "replay.bin"
    np.ascontiguousarray(q, dtype=np.float64).tofile(path)
    return {"mode": "replay", "replay_file": path, "replay_rows": len(q)}


def summary(folder: Path) -> dict[str, str]:
    """The trace's summary: key -> the rest of its line."""
    out = {}
    for line in (folder / "standin.trace").read_text().splitlines():
        key, _, rest = line.partition(" ")
        out[key] = rest
    return out


def ticks(folder: Path) -> np.ndarray:
    """The trace's tick rows (ticks x len(TRACE_COLUMNS))."""
    data = np.fromfile(folder / "standin.trace.ticks", dtype=np.float64)
    return data.reshape(-1, len(TRACE_COLUMNS))


def _env(config: Path | None) -> dict:
    env = dict(os.environ)
    env.pop("VIRTMECH_STANDIN_CONFIG", None)
    if config is not None:
        env["VIRTMECH_STANDIN_CONFIG"] = str(config)
    return env


def drive(args: list[str], config: Path | None, timeout: float = 120.0):
    """`virtmech drive ARGS` in a process of its own (the stand-in configured by `config`);
    returns the CompletedProcess."""
    command = [sys.executable, "-m", "virtmech", "drive", *args]
    return subprocess.run(
        command, env=_env(config), capture_output=True, text=True, timeout=timeout
    )


def drive_process(args: list[str], config: Path | None) -> subprocess.Popen:
    """`virtmech drive ARGS` started, not waited for."""
    command = [sys.executable, "-m", "virtmech", "drive", *args]
    pipe = subprocess.PIPE
    return subprocess.Popen(command, env=_env(config), stdout=pipe, stderr=pipe, text=True)


def velocity_estimate(q: np.ndarray, period_s: float, cutoff_hz: float) -> np.ndarray:
    """The driver's velocity estimate written out (docs/devices.md, "Velocity estimate"):
    dq_k = dq_{k-1} + alpha ((q_k - q_{k-1}) / T - dq_{k-1}), dq_0 = 0, alpha = T / (T + 1 /
    (2 pi f_c))."""
    alpha = period_s / (period_s + 1.0 / (2.0 * np.pi * cutoff_hz))
    dq = np.zeros_like(q)
    for k in range(1, len(q)):
        dq[k] = dq[k - 1] + alpha * ((q[k] - q[k - 1]) / period_s - dq[k - 1])
    return dq


def truth_columns(n: int = 6) -> list[str]:
    """The stand-in's truth rows in mode mujoco for a device of n joints (standin_sim.hpp,
    truth_layout)."""
    return (
        ["t"]
        + [f"q{i}" for i in range(n)]
        + [f"dq{i}" for i in range(n)]
        + ["px", "py", "pz", "sx", "sy", "sz", "vx", "vy", "vz", "wx", "wy", "wz"]
        + [f"tau_motor{i}" for i in range(n)]
        + ["fhx", "fhy", "fhz", "mhx", "mhy", "mhz", "ax", "ay", "az", "segment"]
    )



def mujoco_config(folder: Path, scenario, reference) -> dict:
    """The stand-in's keys serving the simulated device of `scenario` as `virtmech run`
    builds it (virtmech.builder: the same MJCF, compiled and saved as MJB, the same loop
    settings), with the hand's plan the simulation's intent gives: each segment planned from
    the handle's pose where it starts in `reference` (the SimResult of that run)."""
    import mujoco

    import virtmech.sim.inner as inner
    from virtmech.builder import build
    from virtmech.sim.human import PLAN_COLUMNS

    rig = build(scenario)
    sim, device, T = rig.sim, rig.device, rig.period_s
    mujoco.mj_saveModel(sim.model, str(folder / "model.mjb"), None)
    cp = sim.coupling
    comp = sim.comp_bodies if sim.gravity_compensation else []

    # the hand's plan, segment by segment from the reference's handle pose at its start
    N = reference.n_cycles
    q_true = reference.cols(*[f"q{i}" for i in range(device.dof)])
    intent = rig.intent()
    cuts = sorted(set(intent.start_cycles(N)) | {0}) + [N]
    plan = np.concatenate(
        [intent.plan(k0, k1, device.forward(q_true[k0])) for k0, k1 in zip(cuts[:-1], cuts[1:])]
    )
    plan.astype(np.float64).tofile(folder / "plan.bin")
    lay = inner.layout(inner.PLAN_FIELDS, list(PLAN_COLUMNS))
    # PlanLayout's fields in its order (servo_loop.hpp)
    order = "columns anchor_p anchor_R anchor_v anchor_w k_t b_t k_r b_r force moment"
    order = (order + " force_in_handle hand_attached segment").split()
    p = scenario.data["device"]
    if p["type"] == "CartesianDevice":  # the DHD stand-in's device
        kind = {"device_model": p["model"], "handle_rotation": np.asarray(device.handle_rotation)}
    else:
        kind = {"l1": p["l1"], "l2": p["l2"]}
    return {
        "mode": "mujoco",
        "model": folder / "model.mjb",
        **kind,
        "coupling_inv": np.asarray(cp.Cinv, dtype=float),
        "coupling_offset": np.asarray(cp.c0, dtype=float),
        "actuated": [int(i) for i in np.flatnonzero(device.actuated)],
        "substeps": sim.substeps,
        "period_s": T,
        "comp_bodies": comp,
        "comp_masses": [float(sim.model.body_mass[b]) for b in comp],
        "gravity": np.asarray(sim.gravity_world, dtype=float),
        "quantum": rig.sensors.quantum_rad,
        "delay_cycles": int(rig.sensors.delay_cycles),
        "velocity_alpha": rig.sensors.velocity_alpha(T),
        "hand_body": sim.hand_body,
        "qpos0": cp.C @ rig.q0 + cp.c0,
        "plan_file": folder / "plan.bin",
        "plan_rows": len(plan),
        "plan_layout": [lay[k] for k in order],
        "truth_file": folder / "truth.bin",
        "max_ticks": N + 2000,
    }


def truth(folder: Path, n: int = 6) -> np.ndarray:
    """The stand-in's simulated device of n joints, one row per control cycle
    (truth_columns(n))."""
    data = np.fromfile(folder / "truth.bin", dtype=np.float64)
    return data.reshape(-1, len(truth_columns(n)))
