"""``virtmech bench``: how fast the servo cycle is, measured side by side in one run.

For each benchmark case (a device and a mechanism, driven along a fixed joint trajectory):

- the C++ cycle's per-cycle latency (median, p99, p99.9, worst) and the heap allocations it
  made, from the harness ``virtmech_cycle_bench`` installed with the package (a counting
  ``operator new`` and, on glibc, a counting ``malloc``: real counts, not assumptions);
- ``Controller.step`` called from Python over the same trajectory (median per call), so the
  binding's own cost is the difference;
- given a NumPy reference cycle (the same mathematics written the obvious way, its
  placements solved on their own to their own tolerance: ``tests/reference`` of a source
  checkout, which ``bench/numpy_baseline.py`` passes in; the installed package has none and
  skips that column with a note), that cycle timed over the same cycles, with its largest
  torque difference from the core;

and, when the simulation is installed, the closed-loop simulation's real-time factor for
every shipped scenario. The trajectory and the cases are those of ``bench/bench_cases.hpp``.

Timing figures are reports, not assertions: they depend on the machine and its load, which
the output describes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

CASES = (
    "omni+probe", "omni+planar_arm", "planar3r+planar_arm", "omni+probe_lifted", "arm6+serial5",
)

#: Default number of timed C++ cycles per case (enough for a stable p99.9).
DEFAULT_CYCLES = 1_000_000
#: Default number of Python ``step`` calls and NumPy reference cycles per case.
DEFAULT_PYTHON_CYCLES = 20_000
DEFAULT_NUMPY_CYCLES = 1_000
#: the most cycles of each kind a run times: their timings are kept in memory (the C++ harness
#: 8 B a cycle, a Python step about 180 B: under 1 GB each)
MAX_CYCLES = {"cycles": 100_000_000, "python_cycles": 5_000_000, "numpy_cycles": 1_000_000}
#: Untimed cycles before timing (the first cycle's initial placement, caches); as the harness.
WARMUP = 2000
#: Untimed cycles of the NumPy reference before its timed ones (longer than the torque ramp).
REFERENCE_WARMUP = 300


# ---------------------------------------------------------------------------------------
# the benchmark cases (bench/bench_cases.hpp)


@dataclass
class Case:
    """A controller and its device's joint trajectory."""

    name: str
    controller: Any
    center: np.ndarray
    amplitude: np.ndarray

    def joint_state(self, k: np.ndarray | int, period_s: float) -> tuple[np.ndarray, np.ndarray]:
        """q, dq at cycles k: q_i = c_i + a_i sin(w_i t + i), w_i = 1 + 0.37 i [rad/s]."""
        t = np.asarray(k, dtype=float)[..., None] * period_s
        i = np.arange(self.center.size, dtype=float)
        w = 1.0 + 0.37 * i
        q = self.center + self.amplitude * np.sin(w * t + i)
        dq = self.amplitude * w * np.cos(w * t + i)
        return q, dq


def _arm6_joints(vm: Any) -> tuple[list[Any], np.ndarray]:
    axes = ([0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0])
    offs = ([0, 0, 0.1], [0, 0, 0.05], [0.25, 0, 0], [0.1, 0, 0], [0.15, 0, 0], [0, 0, 0])
    joints = [vm.Joint("revolute", a, o, -2.5, 2.5) for a, o in zip(axes, offs)]
    handle = np.eye(4)
    handle[:3, 3] = [0.05, 0, 0]
    handle[:3, :3] = _rot(np.array([0.0, 1.0, 0.0]), math.pi / 2)
    return joints, handle


def make_case(name: str, **settings) -> Case:
    """Builds one benchmark case (the same as the C++ harness's); `settings` go to its
    vm.Controller (the default settings, as the harness's, when none)."""
    import virtmech as vm

    omni_center = np.array([0.0, 0.5, 0.3, 0.0, 0.8, 0.0])
    omni_amplitude = np.array([0.3, 0.2, 0.2, 0.4, 0.3, 0.5])
    if name in ("omni+probe", "omni+probe_lifted"):
        # table 1 cm above the handle's zero height (in reach), or 3 cm below (a stress case:
        # the handle is lifted beyond the probe's reach half the time)
        point = [0.0, 0.01 if name == "omni+probe" else -0.03, 0.0]
        dev = vm.PhantomOmni()
        mech = vm.Probe(point, [0, 1, 0], 0.1)
        return Case(name, vm.Controller(dev, mech, **settings), omni_center, omni_amplitude)
    if name == "omni+planar_arm":
        dev = vm.PhantomOmni()
        mech = vm.PlanarArm([0.0, 0.0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
        return Case(name, vm.Controller(dev, mech, **settings), omni_center, omni_amplitude)
    if name == "planar3r+planar_arm":
        dev = vm.Planar3R(0.2, 0.2, torque_limit=50.0, max_force=100.0)
        mech = vm.PlanarArm([0.25, 0.0, 0.0], [0, 0, 1], 0.1, [1, 0, 0])
        return Case(name, vm.Controller(dev, mech, **settings), np.array([-0.5, 1.6, 0.5]),
                    np.array([0.2, 0.2, 0.3]))
    if name == "arm6+serial5":
        joints, handle = _arm6_joints(vm)
        dev = vm.Device(joints, [True] * 6, handle=handle, torque_limit=[20.0] * 6,
                        max_force=40.0, max_torque=4.0, stiffness=800.0, damping=2.0)
        sj = [vm.Joint("prismatic" if i < 2 else "revolute", np.eye(3)[i % 3]) for i in range(5)]
        sh = np.eye(4)
        sh[:3, 3] = [0.3, 0, 0.2]
        mech = vm.SerialChain(sj, handle=sh, length_scale=0.1)
        return Case(name, vm.Controller(dev, mech, **settings), np.full(6, 0.3), np.full(6, 0.4))
    raise ValueError(f"case: expected one of {', '.join(CASES)}, got {name!r}")


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return c * np.eye(3) + (1.0 - c) * np.outer(axis, axis) + s * K


# ---------------------------------------------------------------------------------------
# measurements


def harness_path() -> Path | None:
    """The installed per-cycle harness, or $VIRTMECH_CYCLE_BENCH, or one on PATH."""
    env = os.environ.get("VIRTMECH_CYCLE_BENCH")
    if env:
        return Path(env)
    exe = "virtmech_cycle_bench" + (".exe" if os.name == "nt" else "")
    here = Path(__file__).resolve().parent / "bin" / exe
    if here.is_file():
        return here
    found = shutil.which(exe)
    return Path(found) if found else None


def run_harness(cycles: int, cases: list[str], cpu: int | None = None) -> dict[str, Any]:
    """Runs the C++ harness and returns its JSON report."""
    exe = harness_path()
    if exe is None:
        raise FileNotFoundError(
            "virtmech_cycle_bench not found: it is installed with the package (virtmech/bin); "
            "set VIRTMECH_CYCLE_BENCH to a build's bench/virtmech_cycle_bench")
    cmd = [str(exe), "--json", "--cycles", str(cycles), "--warmup", str(WARMUP)]
    for c in cases:
        cmd += ["--case", c]
    if cpu is not None:
        cmd += ["--cpu", str(cpu)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.strip()}")
    return json.loads(proc.stdout)


def _timer_overhead_ns() -> float:
    clock = time.perf_counter_ns
    d = np.empty(20000)
    for i in range(d.size):
        t0 = clock()
        d[i] = clock() - t0
    return float(np.median(d))


def python_step(case: Case, cycles: int) -> dict[str, Any]:
    """Times Controller.step from Python over the trajectory (after WARMUP untimed cycles);
    returns the per-call median [µs], the median of the call's time over the cycle's own
    (its `computation_time_us`, cycle by cycle: the binding's overhead), and the torques and
    iteration counts of every cycle."""
    c = case.controller
    c.reset()
    period = c.model["period_s"]
    q_w, dq_w = case.joint_state(np.arange(WARMUP), period)
    for k in range(WARMUP):
        c.step(q_w[k], dq_w[k])
    q, dq = case.joint_state(np.arange(WARMUP, WARMUP + cycles), period)
    clock = time.perf_counter_ns
    ns = np.empty(cycles)
    own_us = np.empty(cycles)
    tau = np.empty((cycles, q.shape[1]))
    its = np.empty((cycles, 2), dtype=int)
    step = c.step
    for k in range(cycles):
        qk, dqk = q[k], dq[k]
        t0 = clock()
        out = step(qk, dqk)
        ns[k] = clock() - t0
        own_us[k] = out.computation_time_us
        tau[k] = out.torque
        its[k] = out.iterations, out.iterations_star
    call_us = (ns - _timer_overhead_ns()) * 1e-3
    return {"median_us": float(np.median(call_us)),
            "overhead_us": float(np.median(call_us - own_us)), "own_us": own_us, "torque": tau,
            "iterations": its, "q": q, "dq": dq}


def numpy_reference(case: Case, reference: Any, q_warm: np.ndarray, dq_warm: np.ndarray,
                    q: np.ndarray, dq: np.ndarray) -> dict[str, Any]:
    """Runs the NumPy reference cycle (its own placements, to its own tolerance): untimed
    through the warm-up states, the first placed from every seed (the core's closed-form
    placements are global: the reference starts in the same basin), then timed per cycle,
    each placement warm-started from the last as in a servo loop. Returns the median [µs]
    and the largest torque difference from the core stepped through the same states with
    the same laws (the reference implements the paper's laws: no energy tank, so the core
    with passivity off)."""
    device, mechanism = reference.case_models(case.name)
    laws = make_case(case.name, passivity="off").controller
    npc = reference.NpController(laws, device, mechanism, global_search=True)
    for k in range(q_warm.shape[0]):
        npc.step(q_warm[k], dq_warm[k])
        laws.step(q_warm[k], dq_warm[k])
        npc.global_search = False
    clock = time.perf_counter_ns
    ns = np.empty(q.shape[0])
    difference = 0.0
    for k in range(q.shape[0]):
        t0 = clock()
        tau = npc.step(q[k], dq[k])
        ns[k] = clock() - t0
        difference = max(difference, float(np.abs(tau - laws.step(q[k], dq[k]).torque).max()))
    return {"median_us": float(np.median(ns)) * 1e-3, "torque_difference": difference}


def simulation_figures(scenarios: list[str] | None = None, repeats: int = 5,
                       mujoco_alone: Any = None,
                       show: Any = None) -> tuple[list[dict[str, Any]], str]:
    """Real-time factor of each shipped scenario, if the simulation is installed: simulated
    seconds per wall second of the closed loop (`SimResult.wall_time_s`); `repeats` runs,
    each followed by MuJoCo alone on the same steps (`mujoco_alone(result, 1)`, default
    `mujoco_alone_s`), so that both sides of each ratio are timed within moments of each
    other (a machine that speeds up or slows down over the runs changes both); every figure
    is that of the pair of median ratio (`realtime_factor` and `wall_time_s` too):
    `overhead_vs_mujoco` its wall time over its MuJoCo alone (`mujoco_alone_s`);
    `setup_and_run_wall_time_s` (the median over the runs) adds building the MJCF and
    solving the start pose; `control_time_s`: of that run's wall time, the
    controller's (or the set's) step, `control_us_per_cycle` the same per control cycle,
    `derived_time_s` the log's derived columns (distances from the shape, ...: on a second
    thread, alongside the loop), `derived_wait_s` the part of the wall time the loop spent
    on them or waited for them, and `loop_overhead_vs_mujoco` the rest of the wall time
    (the simulation around the rendering: sensors, the hand, the log rows) over MuJoCo
    alone. Returns the figures and a note; `show(line)`, if given, gets the table's heading
    and then each scenario's line as soon as it is measured."""
    try:
        from virtmech import scenarios as vs
        from virtmech import sim as vsim
    except Exception as exc:  # the simulation is optional
        return [], f"simulation not available ({type(exc).__name__}: {exc})"
    if not hasattr(vs, "names") or not hasattr(vs, "load") or not hasattr(vsim, "run"):
        return [], "simulation not available (needs scenarios.names/load and sim.run)"
    out: list[dict[str, Any]] = []
    notes: list[str] = []
    if show is not None:
        for line in _simulation_head():
            show(line)
    for name in scenarios if scenarios is not None else list(vs.names()):
        try:
            scenario = vs.load(name)
            runs = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                result = vsim.run(scenario, seed=0, progress=False)
                total = time.perf_counter() - t0
                alone = float((mujoco_alone or mujoco_alone_s)(result, 1))
                runs.append((float(result.wall_time_s) / alone, float(result.wall_time_s),
                             alone, total, float(result.control_time_s),
                             float(result.derived_time_s), float(result.derived_wait_s)))
            sim_s = float(result.sim_time_s)
            # the pair of median ratio, with its run's own controller and derived times (the
            # parts of one run, so that their difference is that run's rest)
            _, wall_s, mujoco_s, _, control_s, derived_s, wait_s = sorted(runs)[
                (len(runs) - 1) // 2]
            total_s = float(np.median([r[3] for r in runs]))
        except Exception as exc:
            notes.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        out.append({"scenario": name, "realtime_factor": sim_s / wall_s,
                    "sim_time_s": sim_s, "wall_time_s": wall_s,
                    "setup_and_run_wall_time_s": total_s,
                    "mujoco_alone_s": mujoco_s,
                    "overhead_vs_mujoco": wall_s / mujoco_s,
                    "control_time_s": control_s,
                    "control_us_per_cycle": control_s / max(result.n_cycles, 1) * 1e6,
                    "derived_time_s": derived_s,
                    "derived_wait_s": wait_s,
                    "loop_overhead_vs_mujoco": (wall_s - control_s - wait_s) / mujoco_s,
                    "engine": result.info["physics"].get("engine", "python"),
                    "runs": repeats})
        if show is not None:
            show(_simulation_line(out[-1]))
    return out, "; ".join(notes)


def mujoco_alone_s(result: Any, repeats: int = 3) -> float:
    """Wall time of MuJoCo alone for the run's physics steps: the run's own model (its
    MJCF) from its initial state, replaying the run open loop in MuJoCo's own rollout (C,
    no Python per step): every cycle's motor torques (`tau_motor`) and the hand's wrench
    on the handle (`fh`, `mh`, applied to the hand body whose centre of mass is the
    handle), held for the cycle's physics steps. The same model, the same number of steps
    and nearly the same motion, so MuJoCo meets the same joint limits and friction; after
    one untimed replay, median of `repeats`."""
    import mujoco
    from mujoco import rollout

    from virtmech.builder import make_device
    from virtmech.sim.model import coupling_of

    model = mujoco.MjModel.from_xml_string(result.info["mjcf"])
    data = mujoco.MjData(model)
    device = make_device(result.scenario.data["device"])
    coupling = coupling_of(device)
    n, nsub = device.dof, int(result.info["physics"]["substeps"])
    data.qpos[:] = coupling.to_chain(np.asarray(result.info["initial_q"]))
    data.qvel[:] = coupling.C @ result.cols(*[f"dq{i}" for i in range(n)])[0]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)
    act = np.flatnonzero(device.actuated)
    ctrl = result.cols(*[f"tau_motor{i}" for i in act])
    hand = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "hand")
    xfrc = np.zeros((result.n_cycles, model.nbody, 6))
    xfrc[:, hand] = result.cols("fhx", "fhy", "fhz", "mhx", "mhy", "mhz")
    control = np.repeat(np.hstack([ctrl, xfrc.reshape(result.n_cycles, -1)]), nsub, axis=0)
    control_spec = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED

    def replay() -> None:
        rollout.rollout(model, data, state0, control[None], control_spec=int(control_spec))

    replay()  # untimed: MuJoCo at its best, its model and data warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        replay()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info: dict[str, Any] = {"cpu": cpu, "logical_cpus": os.cpu_count(),
                            "platform": platform.platform(), "python": platform.python_version(),
                            "numpy": np.__version__}
    try:
        info["load_average"] = list(os.getloadavg())
    except (AttributeError, OSError):
        pass
    return info


#: why the NumPy column is empty when no reference is given
NO_REFERENCE = ("NumPy column skipped: the NumPy reference cycle is not part of the package; "
                "from a source checkout, python bench/numpy_baseline.py (or scripts/bench.sh) "
                "measures it")


def collect(cycles: int = DEFAULT_CYCLES, python_cycles: int = DEFAULT_PYTHON_CYCLES,
            numpy_cycles: int = DEFAULT_NUMPY_CYCLES, cases: list[str] | None = None,
            simulation: bool = True, cpu: int | None = None,
            reference: Any = None, show: Any = None) -> dict[str, Any]:
    """Runs every measurement and returns the report (the --json object). `reference`: a
    NumPy reference cycle module (tests/reference's interface: case_models, NpController),
    timed beside the core when given. `show(line)`, if given, gets the lines of
    `format_table` as their figures are measured: the machine and the headings first, then
    each case's line (the harness runs case by case), each simulation scenario's, the
    notes."""
    import virtmech as vm

    def say(*lines: str) -> None:
        for line in lines if show is not None else ():
            show(line)

    names = list(cases) if cases else list(CASES)
    report: dict[str, Any] = {"virtmech_version": vm.__version__, "machine": machine()}
    numpy_note = "NumPy column skipped (--numpy-cycles 0)" if numpy_cycles <= 0 else ""
    if numpy_cycles <= 0:
        reference = None
    elif reference is None:
        numpy_note = NO_REFERENCE
    out_cases = []
    for name in names:
        harness = run_harness(cycles, [name], cpu)
        if not out_cases:  # what the figures are measured on, from the first run
            report["machine"]["harness"] = harness["machine"]
            report["cycles"] = harness["cycles"]
            report["sizeof"] = harness["sizeof"]
            report["allocation_counter"] = harness["allocation_counter"]
            say(*_head(report), *_case_head())
        elif not harness["allocation_counter"].get("self_test_passed", True):
            report["allocation_counter"]["self_test_passed"] = False
        row = _case_row(name, harness["cases"][0], python_cycles, numpy_cycles, reference)
        out_cases.append(row)
        say(_case_line(row))
    if numpy_note:
        report["numpy_note"] = numpy_note
    report["cases"] = out_cases
    say(*_case_notes(report), "")
    if simulation:
        report["simulation"], note = simulation_figures(show=show)
    else:
        report["simulation"], note = [], "simulation skipped (--no-sim)"
    if note:
        report["simulation_note"] = note
    say(*_simulation_notes(report))
    return report


def _case_row(name: str, h: dict, python_cycles: int, numpy_cycles: int,
              reference: Any) -> dict[str, Any]:
    """One case's figures: the harness's (h), Python's step over the same trajectory, and,
    given a reference, the NumPy reference cycle's beside the core's."""
    case = make_case(name)
    py = python_step(case, python_cycles)
    row: dict[str, Any] = {
        "name": name,
        "median_us": float(h["median_us"]), "p99_us": float(h["p99_us"]),
        "p999_us": float(h["p999_us"]), "max_us": float(h["max_us"]),
        "mean_us": float(h["mean_us"]), "cycles": h["cycles"],
        "allocations": int(h["allocations"]),
        "mean_iterations": h["mean_iterations"] + h["mean_iterations_star"],
        "numpy_median_us": None, "speedup_vs_numpy": None,
        "cpp_median_numpy_cycles_us": None, "numpy_cycles": 0,
        "numpy_max_torque_difference": None,
        "python_step_median_us": py["median_us"],
        "python_overhead_us": py["overhead_us"],
        "python_cycles": python_cycles,
    }
    if reference is None:
        return row
    # the reference runs from a fresh start through the last REFERENCE_WARMUP cycles before
    # the timed ones (its torque ramp is over by then; its placements do not depend on the
    # history), then over the cycles Python timed
    period = case.controller.model["period_s"]
    q_w, dq_w = case.joint_state(np.arange(WARMUP - REFERENCE_WARMUP, WARMUP), period)
    m = min(numpy_cycles, python_cycles)
    nb = numpy_reference(case, reference, q_w, dq_w, py["q"][:m], py["dq"][:m])
    # side by side: the C++ cycle's own time over the very cycles NumPy ran (a case's cost
    # varies along its trajectory, so medians over other spans would not compare)
    cpp_same = float(np.median(py["own_us"][:m]))
    row.update({
        "numpy_median_us": nb["median_us"],
        "speedup_vs_numpy": nb["median_us"] / cpp_same if cpp_same > 0 else None,
        "cpp_median_numpy_cycles_us": cpp_same, "numpy_cycles": m,
        "numpy_max_torque_difference": nb["torque_difference"],
    })
    return row


def _head(r: dict[str, Any]) -> list[str]:
    """What the figures were measured on."""
    m = r["machine"]
    return [
        f"virtmech {r['virtmech_version']} benchmark: {r['cycles']} C++ cycles per case",
        f"machine: {m['cpu']}, {m['logical_cpus']} logical CPUs, {m.get('platform', '')}, "
        f"Python {m.get('python')}, NumPy {m.get('numpy')}",
        f"load average: {m.get('load_average')}; compiler: {m['harness'].get('compiler')}; "
        f"timer overhead {m['harness'].get('timer_overhead_ns')} ns (in the C++ figures)",
        "sizeof: " + ", ".join(f"{k} {v} B" for k, v in r["sizeof"].items()),
        "",
    ]


def _case_head() -> list[str]:
    return [
        f"{'case':<21}{'median':>8}{'p99':>8}{'p99.9':>8}{'max':>8}{'allocs':>7}"
        f"{'NumPy':>10}{'speedup':>9}{'Python':>8}{'overhead':>9}",
        f"{'':<21}{'[us]':>8}{'[us]':>8}{'[us]':>8}{'[us]':>8}{'':>7}"
        f"{'[us]':>10}{'[x]':>9}{'[us]':>8}{'[us]':>9}",
    ]


def _fit(x: float, width: int, decimals: int) -> str:
    """x right-aligned in width with at least one space before it: fewer decimals where a
    large value (a loaded machine's milliseconds) would run into the column before."""
    text = f"{x:.{decimals}f}"
    while len(text) >= width and decimals > 0:
        decimals -= 1
        text = f"{x:.{decimals}f}"
    return f"{text:>{width}}"


def _case_line(c: dict[str, Any]) -> str:
    nm, sp = c["numpy_median_us"], c["speedup_vs_numpy"]
    return (
        f"{c['name']:<21}{_fit(c['median_us'], 8, 3)}{_fit(c['p99_us'], 8, 3)}"
        f"{_fit(c['p999_us'], 8, 3)}{_fit(c['max_us'], 8, 1)}{c['allocations']:>7d}"
        f"{(f'{nm:.1f}' if nm is not None else '-'):>10}"
        f"{(f'{sp:.0f}' if sp is not None else '-'):>9}{c['python_step_median_us']:>8.3f}"
        f"{c['python_overhead_us']:>9.3f}"
    )


#: what the cases' `max` column measures
MAX_NOTE = (
    "(max: the slowest single cycle of the {cycles} timed, wall clock: where the process is "
    "not scheduled in real time it includes the operating system preempting it, often "
    "milliseconds, which the cycle's own work never takes; p99.9 is the cycle's cost)"
)


def _case_notes(r: dict[str, Any]) -> list[str]:
    lines = [MAX_NOTE.format(cycles=r.get("cycles", "?"))]
    if r.get("numpy_note"):
        lines.append(r["numpy_note"])
    return lines


def _simulation_head() -> list[str]:
    return [
        f"{'simulation scenario':<28}{'real-time factor':>18}{'vs MuJoCo alone':>17}"
        f"{'controller':>12}{'derived':>10}{'rest vs MuJoCo':>16}",
        f"{'':<28}{'':>18}{'':>17}{'[us/cycle]':>12}{'[%]':>10}{'':>16}",
    ]


def _simulation_line(s: dict[str, Any]) -> str:
    return (
        f"{s['scenario']:<28}{s['realtime_factor']:>17.1f}x"
        f"{s['overhead_vs_mujoco']:>16.2f}x"
        f"{s['control_us_per_cycle']:>12.2f}"
        f"{100 * s['derived_wait_s'] / s['wall_time_s']:>10.0f}"
        f"{s['loop_overhead_vs_mujoco']:>15.2f}x"
    )


#: what the simulation table's columns are
SIMULATION_NOTE = (
    "(vs MuJoCo alone: the loop's wall time over MuJoCo's for the same steps; controller: the "
    "rendering's own time per cycle; derived: the share of the wall time the loop spent on or "
    "waited for the log's derived columns (distances from a shape, computed on a second "
    "thread alongside the loop); rest vs MuJoCo: the wall time without those two over "
    "MuJoCo's)"
)


def _simulation_notes(r: dict[str, Any]) -> list[str]:
    lines = [SIMULATION_NOTE] if r["simulation"] else []
    if r.get("simulation_note"):
        lines.append(f"simulation: {r['simulation_note']}")
    return lines


def format_table(r: dict[str, Any]) -> str:
    """The report as a readable table (the lines `collect(show=...)` gives as it goes)."""
    lines = [*_head(r), *_case_head(), *map(_case_line, r["cases"]), *_case_notes(r), ""]
    if r["simulation"]:
        lines += [*_simulation_head(), *map(_simulation_line, r["simulation"])]
    return "\n".join(lines + _simulation_notes(r))


def main(argv: list[str], reference: Any = None) -> int:
    """Entry point of `virtmech bench [--json]` (and of bench/numpy_baseline.py, which passes
    the NumPy reference cycle); returns the exit status."""
    p = argparse.ArgumentParser(prog="virtmech bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--cycles", type=int, default=DEFAULT_CYCLES,
                   help=f"timed C++ cycles per case (default {DEFAULT_CYCLES})")
    p.add_argument("--python-cycles", type=int, default=DEFAULT_PYTHON_CYCLES,
                   help=f"timed Python step calls per case (default {DEFAULT_PYTHON_CYCLES})")
    p.add_argument("--numpy-cycles", type=int, default=DEFAULT_NUMPY_CYCLES,
                   help="timed cycles of the NumPy reference per case, where there is one "
                   f"(bench/numpy_baseline.py; default {DEFAULT_NUMPY_CYCLES}; 0: skip)")
    p.add_argument("--case", action="append", choices=CASES, help="only this case (repeatable)")
    p.add_argument("--no-sim", action="store_true", help="skip the simulation figures")
    p.add_argument("--cpu", type=int, default=None, help="pin the C++ harness to this CPU")
    a = p.parse_args(argv)
    for opt, least in (("cycles", 1), ("python_cycles", 1), ("numpy_cycles", 0)):
        v, most = getattr(a, opt), MAX_CYCLES[opt]
        if not least <= v <= most:
            p.error(f"--{opt.replace('_', '-')}: expected {least} to {most:,} (the timings "
                    f"are kept in memory), got {v}")
    # the table's lines as their figures are measured: on stdout, or with --json (one JSON
    # object on stdout at the end) on stderr
    stream = sys.stderr if a.json else sys.stdout

    def show(line: str) -> None:
        print(line, file=stream, flush=True)

    try:
        r = collect(a.cycles, a.python_cycles, a.numpy_cycles, a.case, not a.no_sim, a.cpu,
                    reference=reference, show=show)
    except (FileNotFoundError, RuntimeError) as exc:
        print(f"virtmech bench: {exc}", file=sys.stderr)
        return 1
    if a.json:
        print(json.dumps(r, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
