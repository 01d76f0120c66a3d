"""The simulation loop: the controller at the device rate with zero-order hold on torque,
MuJoCo physics at several kHz, modelled sensors, the human's wrench every physics step.

    per control cycle k (t = k T):
        q, dq       <- true joint state (device coordinates)
        qm, dqm     <- sensors (quantise, noise, dropout, delay, filtered difference)
        out         <- controller.step(qm, dqm, t)            (exactly a device callback)
        motors      <- out.torque (+ gravity compensation), held for the whole cycle;
                       the motors saturate at their torque limits
        anchor      <- intent timeline (the hand's target this cycle)
        repeat rate_hz * T times:
            hand wrench from the impedance at the current handle pose and twist
            mj_step
"""

from __future__ import annotations

import math
import os
import re
import sys
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

import virtmech as vm

from . import inner
from .geometry import COLUMNS as DIST_COLUMNS
from .geometry import distances, geometry_of
from .grip import finger_forces_batch
from .human import HandImpedance, Intent
from .model import (
    BuiltModel,
    DeviceModel,
    HandBody,
    build_mjcf,
    compile_model,
    world_gravity,
)
from .sensors import Sensors, SensorSettings

# ---------------------------------------------------------------------------------------
# objects from a scenario


def translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _pose(position, rotation) -> np.ndarray:
    T = translation(position)
    T[:3, :3] = vm.so3_exp(rotation)
    return T


def make_device(d: dict):
    """A vm device from a scenario's [device] table: its kind's parameters (virtmech.kinds;
    the MuJoCo model's keys aside)."""
    from ..scenarios.format import DEVICE_PHYSICS

    return vm.make_device({k: v for k, v in d.items() if k not in DEVICE_PHYSICS})


def make_mechanism(m: dict):
    """A vm mechanism from a scenario's [mechanism] table (its kind's parameters)."""
    return vm.make_mechanism(m)


def make_set(S: dict, device, ctrl):
    """The scenario's renderer: `ctrl` itself, or with [[set.members]] a vm.MechanismSet of
    the [mechanism] (member 0) and the members, each with the [controller] settings."""
    st = S.get("set") or {}
    extra = st.get("members") or []
    if not extra:
        return ctrl
    settings = {r["name"]: st[r["name"]] for r in vm.SET_SETTINGS if r["name"] in st}
    s = vm.MechanismSet(device, 1 + len(extra), period_s=S["controller"]["period_s"], **settings)
    s.add(ctrl)
    kw = controller_kwargs(S["controller"])
    for mm in extra:
        s.add(vm.Controller(device, make_mechanism(mm), **kw))
    return s


def controller_kwargs(c: dict) -> dict:
    """The [controller] table as vm.Controller's keywords (every row of its settings table
    the table holds)."""
    return {r["name"]: c[r["name"]] for r in vm.CONTROLLER_SETTINGS if r["name"] in c}


def device_physics(scenario_device: dict) -> DeviceModel:
    p = DeviceModel.for_device(scenario_device["type"])
    for k in p.to_dict():
        if k in scenario_device:
            setattr(p, k, float(scenario_device[k]))
    return p


# ---------------------------------------------------------------------------------------
# initial pose


# start-pose seeds by device name, in order of preference (the Omni's gimbal branches)
_SEEDS = {
    "PhantomOmni": [
        [0.0, 0.4, 0.2] + g
        for g in (
            [-1.5, 0.3, 1.5],
            [1.5, 0.3, -1.5],
            [0, 0.3, 0],
            [-1.5, 0.3, -1.5],
            [1.5, 0.3, 1.5],
        )
    ],
    "Planar3R": [[0.3, 1.5, -1.0], [-0.3, -1.5, 1.0]],
}


def _seeds(device) -> list[np.ndarray]:
    """The device's own seeds, its home, then four fixed draws within its limits (any
    device)."""
    lo = np.where(np.isfinite(device.lower), device.lower, -np.pi)
    hi = np.where(np.isfinite(device.upper), device.upper, np.pi)
    draws = np.random.default_rng(0).uniform(lo, hi, size=(4, device.dof))
    named = [np.array(s, dtype=float) for s in _SEEDS.get(device.name, [])]
    return named + [np.asarray(device.home, dtype=float)] + list(draws)


def solve_ik(device, T: np.ndarray, length_scale: float = 0.1, iterations: int = 200):
    """Joint values (within the device's limits) whose handle pose is closest to T, by
    damped least squares from several seeds, tried in order until one reaches T (else the
    closest); returns (q, residual pose error (6,))."""
    lo, hi = np.asarray(device.lower), np.asarray(device.upper)
    W = np.array([1, 1, 1, length_scale, length_scale, length_scale])
    best, best_err = None, None
    for q in _seeds(device):
        q = np.clip(q.astype(float), lo, hi)
        lam = 1e-3
        for _ in range(iterations):
            e = vm.pose_error(T, device.forward(q)) * W
            J = device.jacobian(q) * W[:, None]
            dq = np.linalg.solve(J.T @ J + lam * np.eye(len(q)), J.T @ e)
            qn = np.clip(q + dq, lo, hi)
            en = vm.pose_error(T, device.forward(qn)) * W
            if en @ en < e @ e:
                q, lam = qn, max(lam * 0.3, 1e-12)
            else:
                lam *= 10.0
            if np.linalg.norm(en) < 1e-12 or lam > 1e8:
                break
        err = vm.pose_error(T, device.forward(q))
        if best is None or np.linalg.norm(err * W) < np.linalg.norm(best_err * W):
            best, best_err = q, err
        if np.linalg.norm(best_err * W) < 1e-12:
            break  # the seeds are in order of preference: the first that reaches T wins
    return best, best_err


def initial_joints(scenario: dict, device, mechanism) -> np.ndarray:
    ini = scenario["initial"]
    if ini.get("q") is not None:
        return np.asarray(ini["q"], dtype=float)
    theta = mechanism.home.copy()
    theta[0] = ini["theta"]
    T = mechanism.forward(theta)
    if ini.get("stylus_theta") is not None:
        th2 = theta.copy()
        th2[0] = ini["stylus_theta"]
        T[:3, :3] = mechanism.forward(th2)[:3, :3]
    T[:3, 3] += np.asarray(ini["offset"])
    q, err = solve_ik(device, T, mechanism.length_scale)
    if np.linalg.norm(err[:3]) > 1e-6 or np.linalg.norm(err[3:]) > 1e-5:
        raise ValueError(
            f"initial: the device cannot reach the start pose (position error "
            f"{np.linalg.norm(err[:3]) * 1e3:.3g} mm, orientation error "
            f"{math.degrees(np.linalg.norm(err[3:])):.3g} deg); move the mechanism or the start"
        )
    return q


# ---------------------------------------------------------------------------------------
# geometry for the log


class PlanarGeometry:
    """The angles of the handle on a PlanarArm's circle (and its distance from the circle,
    as sim.geometry.planar_arm computes it for the log)."""

    def __init__(self, mech):
        self.c = np.asarray(mech.pivot, dtype=float)
        self.n = np.asarray(mech.normal, dtype=float)
        self.n /= np.linalg.norm(self.n)
        self.d = np.asarray(mech.zero_direction, dtype=float)
        self.d /= np.linalg.norm(self.d)
        self.e = np.cross(self.n, self.d)
        self.L = float(mech.length)

    def measure(self, T: np.ndarray) -> tuple[float, float, float]:
        w = T[:3, 3] - self.c
        h = float(w @ self.n)
        u, v = float(w @ self.d), float(w @ self.e)
        r = math.hypot(u, v)
        dist = math.hypot(r - self.L, h)
        s = -T[:3, 2]  # from the pivot toward the handle, if the stylus points at the pivot
        return dist, math.atan2(v, u), math.atan2(float(s @ self.e), float(s @ self.d))

    def measure_batch(self, p: np.ndarray, z: np.ndarray):
        """`measure` for N handle positions p (N, 3) and stylus axes z (N, 3) at once."""
        w = p - self.c
        h = w @ self.n
        u, v = w @ self.d, w @ self.e
        dist = np.hypot(np.hypot(u, v) - self.L, h)
        s = -z
        return dist, np.arctan2(v, u), np.arctan2(s @ self.e, s @ self.d)


# ---------------------------------------------------------------------------------------
# progress


class Progress:
    """A progress bar on stderr (tqdm) in simulated seconds, then one line with the
    scenario's simulated and wall time."""

    def __init__(self, label: str, total: float, enabled: bool):
        self.label, self.total, self.enabled = label, float(total), enabled
        self.bar = None
        self.wall0 = time.perf_counter()
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=self.total,
                desc=f"{label:<16}",
                file=sys.stderr,
                ascii=" #",
                ncols=80,
                mininterval=0.2 if sys.stderr.isatty() else 5.0,
                bar_format="{desc} [{bar}] {percentage:3.0f}%  {n:.2f}/{total:.2f} s",
            )

    def update(self, done: float) -> None:
        if self.bar is not None:
            self.bar.update(min(done, self.total) - self.bar.n)

    def close(self, wall: float | None = None) -> None:
        """Ends the bar at 100 % and writes the simulated and wall time (default: since the
        bar was made)."""
        if self.bar is None:
            return
        self.update(self.total)
        self.bar.close()
        wall = time.perf_counter() - self.wall0 if wall is None else wall
        speed = f", {self.total / wall:.1f}x real time" if wall > 0 else ""
        sys.stderr.write(
            f"{self.label}: {self.total:.2f} s simulated in {_seconds(wall)} wall{speed}\n"
        )
        sys.stderr.flush()


def _seconds(t: float) -> str:
    return f"{t * 1e3:.0f} ms" if t < 1.0 else f"{t:.2f} s"


# ---------------------------------------------------------------------------------------
# result


@dataclass
class SimResult:
    """One run: the per-cycle log (`log`, one row per control cycle, columns `columns`),
    timings and everything needed to reproduce and describe it (`info`)."""

    scenario: Any
    columns: list[str]
    log: np.ndarray
    sim_time_s: float
    #: wall time of the simulation (the loop, the hand's plan, the derived columns), not
    #: counting the sink's (writing the log: `sink_time_s`)
    wall_time_s: float
    info: dict = field(default_factory=dict)
    #: where the log is when it is not in `log` (a run with keep_log=False): a reader of
    #: blocks such as virtmech.sim.logio.LogFile; `blocks` reads either, block by block
    source: Any = None
    #: wall time spent in the sink (writing the log as it goes)
    sink_time_s: float = 0.0
    #: of `wall_time_s`, the time spent in the controller's (or the set's) step: the
    #: rendering itself, the rest is the simulation around it
    control_time_s: float = 0.0
    #: time spent deriving the log's columns from the logged state (distances from the
    #: shape, PlanarArm angles, the grip), mostly on a second thread, alongside the loop
    derived_time_s: float = 0.0
    #: of `wall_time_s`, the time the loop spent on the derived columns or waiting for them:
    #: each block's last stretch, filled by the loop itself, and the waits for the worker's
    #: stretches (a wait also holds the worker's wake-up, so this may exceed the filling's
    #: own time)
    derived_wait_s: float = 0.0

    def blocks(self, names, rows: int | None = None):
        """The named columns of the log, a block of rows at a time (virtmech.sim.logio)."""
        from .logio import blocks

        return blocks(self, names, rows)

    def col(self, name: str) -> np.ndarray:
        if self.source is not None:
            return self.cols(name)[:, 0]
        return self.log[:, self.columns.index(name)]

    def cols(self, *names: str) -> np.ndarray:
        if self.source is not None:  # the whole column(s), read from the source
            parts = list(self.blocks(names))
            return np.concatenate(parts) if parts else np.empty((0, len(names)))
        idx = [self.columns.index(n) for n in names]
        return self.log[:, idx]

    @property
    def t(self) -> np.ndarray:
        return self.col("t")

    @property
    def n_cycles(self) -> int:
        if self.source is not None:
            return int(self.source.rows)
        return int(self.log.shape[0])


def log_columns(n: int, m: int) -> list[str]:
    """The log's columns for a device of n joints and a mechanism of m (the table of
    sim/include/virtmech/sim/log_table.hpp)."""
    return inner.log_columns(n, m)


#: a column's unit by its name or prefix (the log's table)
UNITS = inner.UNITS


# ---------------------------------------------------------------------------------------
# the log, block by block

#: simulated seconds per block of the log (run's chunk_s)
CHUNK_S = 10.0
#: cycles of the last stretch of each block (its derived columns are the only ones not
#: filled alongside the loop)
DERIVE_TAIL_CYCLES = 100
#: a log larger than this is kept in a memory-mapped file when run is given a spill_dir
LOG_IN_MEMORY_BYTES = 256 * 2**20


def _log_store(rows: int, cols: int, spill_dir) -> np.ndarray:
    if spill_dir is None or rows * cols * 8 <= LOG_IN_MEMORY_BYTES:
        return np.empty((rows, cols))
    import tempfile

    fd, path = tempfile.mkstemp(prefix=".log-", suffix=".npy", dir=spill_dir)
    os.close(fd)
    # column-major: each column (what metrics and figures read) is contiguous on disk
    log = np.lib.format.open_memmap(
        path, mode="w+", dtype=np.float64, shape=(rows, cols), fortran_order=True
    )
    try:
        os.unlink(path)  # the mapping keeps the data until the log is released
    except OSError:  # pragma: no cover (systems that cannot remove a mapped file)
        pass
    return log


class _PostColumns:
    """Fills the columns that follow from the logged state alone (the distance from the
    path, the PlanarArm angles, the grip) in a block of rows."""

    def __init__(self, columns: list[str], mechanisms: list, planar, contacts):
        self.c = {name: i for i, name in enumerate(columns)}
        # the mechanisms (or their to_dict()), made once
        self.mechanisms = [vm.make_mechanism(m) if isinstance(m, dict) else m for m in mechanisms]
        self.planar, self.contacts = planar, contacts

    def _distances(self, log: np.ndarray, p_h: np.ndarray, z_h: np.ndarray) -> np.ndarray:
        """The distance columns (rows x 4): the mechanism's; in a set's run the rendered
        member's, and with none rendered the nearest member's (the one a snap would take).
        A member without a geometry (its distance is the nearest placement's error, logged
        for the rendered member, or member 0 with none) counts only on its own rows."""
        c = self.c
        e_pos = log[:, c["e0"] : c["e0"] + 3]
        if len(self.mechanisms) == 1:
            return distances(self.mechanisms[0], p_h, z_h, e_pos).columns()
        member = log[:, c["member"]].astype(int)
        logged = np.where(member >= 0, member, 0)  # whose errors the e columns are
        each = np.stack([distances(m, p_h, z_h, e_pos).columns() for m in self.mechanisms])
        for i, m in enumerate(self.mechanisms):
            if geometry_of(m) is None:
                each[i, logged != i] = np.nan
        rows = np.arange(len(log))
        # the set's own distance (MechanismSet::distance): a unilateral member's tip height
        # above its surface (its dist, the depth, is 0 all the way up), others' dist
        d = np.stack([np.maximum(each[i, :, 1], 0.0) if m.contact_joint >= 0 else each[i, :, 0]
                      for i, m in enumerate(self.mechanisms)])
        finite = np.isfinite(d)
        nearest = np.where(finite, d, np.inf).argmin(axis=0)
        pick = np.where(member >= 0, member, nearest)
        out = each[pick, rows]
        out[(member < 0) & ~finite.any(axis=0)] = np.nan
        return out

    def __call__(self, log: np.ndarray) -> None:
        c = self.c
        p_h = log[:, c["px"] : c["px"] + 3]
        z_h = log[:, c["sx"] : c["sx"] + 3]
        if self.planar is not None:
            _, a_pos, a_sty = self.planar.measure_batch(p_h, z_h)
        else:
            a_pos = a_sty = np.full(len(log), math.nan)
        _, F1, _, F2, mz = finger_forces_batch(
            p_h, z_h, log[:, c["fx"] : c["fx"] + 6], self.contacts
        )
        log[:, c["dist"] : c["dist"] + len(DIST_COLUMNS)] = self._distances(log, p_h, z_h)
        log[:, c["arm_pos_angle"]] = a_pos
        log[:, c["arm_stylus_angle"]] = a_sty
        log[:, c["ff1x"] : c["ff1x"] + 3] = F1
        log[:, c["ff2x"] : c["ff2x"] + 3] = F2
        log[:, c["grip_twist"]] = mz


def _built(scenario, table: str, build: Callable[[], Any]) -> Any:
    """build(), a constructor's ValueError (its message starts with the parameter's name)
    reported as a ScenarioError naming the scenario's file and key."""
    from ..scenarios import ScenarioError

    try:
        return build()
    except ValueError as e:
        msg = str(e)
        head, sep, rest = msg.partition(": ")
        head = head.strip()
        if sep and (head == table or head.startswith((table + ".", table + "["))):
            key, msg = head, rest
        elif sep and re.fullmatch(r"[A-Za-z_]\w*(\[\d+\])?", head):
            key, msg = f"{table}.{head}", rest
        else:
            key = table
        raise ScenarioError(f"{scenario.source}: {key}: {msg}") from None


def preflight(scenario) -> None:
    """What `run` checks before it simulates, without simulating: the device, the mechanism
    and the controller built from the scenario, and the start pose reached; the same
    ScenarioError naming the file and the key as `run` would raise (virtmech sweep checks
    every point of a grid so before any run starts)."""
    S = scenario.data
    device = _built(scenario, "device", lambda: make_device(S["device"]))
    mech = _built(scenario, "mechanism", lambda: make_mechanism(S["mechanism"]))
    _built(
        scenario,
        "controller",
        lambda: vm.Controller(device, mech, **controller_kwargs(S["controller"])),
    )
    _built(scenario, "set", lambda: make_set(S, device, vm.Controller(
        device, mech, **controller_kwargs(S["controller"]))))
    _built(scenario, "initial", lambda: initial_joints(S, device, mech))


# ---------------------------------------------------------------------------------------
# the loop


def run(
    scenario,
    seed: int | None = None,
    progress: bool = False,
    sink: Callable[[np.ndarray, list[str]], None] | None = None,
    keep_log: bool = True,
    chunk_s: float = CHUNK_S,
    spill_dir: str | Path | None = None,
) -> SimResult:
    """Runs a scenario (a virtmech.scenarios.Scenario, a name or a path) headless.
    `seed` overrides the scenario's; same scenario and seed give the same log.

    The log is produced in blocks of about `chunk_s` seconds of simulated time: `sink`, if
    given, is called with each block and the column names (a rows x columns array, blocks in
    order, a view valid during the call: e.g. virtmech.sim.output.CsvLog), so a long run can
    be written as it goes. keep_log=False keeps no log in the result
    (its `log` is empty: only the sink sees the rows). Otherwise a log larger than
    LOG_IN_MEMORY_BYTES is kept in a memory-mapped file in `spill_dir` (if given; the file
    is removed at once where the system allows and lives until the log is released).

    The control cycles and physics steps run in C++ (virtmech.sim.inner.ServoLoop), with
    Python's lock released, a stretch of at most 1000 cycles at a time; Python's part runs
    beside it on a worker thread: the next stretch's hand plan and sensor draws (where no
    intent segment starts there), and the columns the loop does not write (distances,
    PlanarArm angles, grip: they follow from each row alone) of the stretch before (a
    block's last stretch by the loop itself). A block is handed on once all its rows are
    filled (docs/simulation.md, "One loop, in C++")."""
    if not chunk_s > 0:
        raise ValueError(f"chunk_s: expected a number > 0, got {chunk_s!r}")
    import mujoco

    from .. import scenarios as sc

    if not isinstance(scenario, sc.Scenario):
        scenario = sc.load(scenario)
    S = scenario.data
    seed = S["seed"] if seed is None else int(seed)
    # the sensor noise's draws, and the dropouts' from their own stream (a child of the same
    # seed): the draws of each stream follow one another whatever the stretches, so the log
    # does not depend on where the run is split into stretches and blocks
    rng = np.random.default_rng(seed)
    dropout_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])

    device = _built(scenario, "device", lambda: make_device(S["device"]))
    mech = _built(scenario, "mechanism", lambda: make_mechanism(S["mechanism"]))
    ctrl = _built(
        scenario,
        "controller",
        lambda: vm.Controller(device, mech, **controller_kwargs(S["controller"])),
    )
    T_ctrl = S["controller"]["period_s"]
    n, m = device.dof, mech.dof
    renderer, members = _built(scenario, "set", lambda: make_set(S, device, ctrl)), []
    if renderer is not ctrl:
        members = [renderer.member(i).to_dict() for i in range(renderer.size)]
        m = max(renderer.member(i).dof for i in range(renderer.size))
    actuated = np.asarray(device.actuated, dtype=bool)
    act_idx = np.flatnonzero(actuated)

    human = HandImpedance(**{k: S["human"][k] for k in HandImpedance().to_dict()})
    contacts = S["human"]["grip_contacts"]
    phys = device_physics(S["device"])
    gravity_on = S["physics"]["gravity"]
    g_world = world_gravity(device)
    nsub = int(round(S["physics"]["rate_hz"] * T_ctrl))
    built: BuiltModel = build_mjcf(
        device,
        params=phys,
        hand=HandBody(human.mass_kg, human.inertia),
        gravity=g_world if gravity_on else np.zeros(3),
        timestep=T_ctrl / nsub,
    )
    model = compile_model(built)
    data = mujoco.MjData(model)
    C, Cinv, c0 = built.coupling.C, built.coupling.Cinv, built.coupling.c0

    q0 = _built(scenario, "initial", lambda: initial_joints(S, device, mech))
    data.qpos[:] = C @ q0 + c0
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)

    grav_comp = gravity_on and S["physics"]["gravity_compensation"]
    comp_bodies = [
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in built.device_bodies
    ]

    intent = _built(
        scenario, "intent", lambda: Intent(S["intent"], human, mech, device.forward(q0), T_ctrl)
    )
    planar = PlanarGeometry(mech) if S["mechanism"]["type"] == "PlanarArm" else None

    columns = log_columns(n, m)
    N = int(round(S["duration_s"] / T_ctrl)) + 1
    # the log is produced block by block (`block` cycles at a time, about chunk_s of
    # simulated time); each block is handed to `sink` and, unless the log would be too large
    # to hold, kept in memory for the result (else in a memory-mapped file in spill_dir)
    block = max(1, min(N, int(round(chunk_s / T_ctrl))))
    log = _log_store(N, len(columns), spill_dir) if keep_log else None
    buf = np.empty((block, len(columns)))  # the block being written, reused
    bar = Progress(scenario.name, S["duration_s"], progress)

    sensor_settings = SensorSettings(**S["sensors"])
    sensors = Sensors(sensor_settings, n, T_ctrl, rng)
    comp = comp_bodies if grav_comp else []
    servo = inner.ServoLoop(
        controller=renderer,
        model=model,
        data=data,
        coupling_inv=Cinv,
        coupling_offset=c0,
        actuated=[int(i) for i in act_idx],
        substeps=nsub,
        period_s=T_ctrl,
        comp_bodies=[int(b) for b in comp],
        comp_masses=[float(model.body_mass[b]) for b in comp],
        gravity=g_world,
        sensors=sensors,
        hand_body=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "hand"),
        log_columns=columns,
    )
    post = _PostColumns(
        columns, [renderer.member(i) for i in range(renderer.size)] if members else [mech],
        planar, contacts,
    )

    # stretches of cycles: split where a segment starts (the hand's plan needs the handle's
    # pose there), every 1000 cycles (progress), at the ends of the blocks and
    # DERIVE_TAIL_CYCLES before them (the last stretch's columns are derived while the loop
    # waits: a short one leaves little to wait for)
    starts = set(intent.start_cycles(N))
    ends = set(range(block, N, block)) | {N}
    cuts = sorted(
        starts | set(range(0, N, 1000)) | {0} | ends
        | {e - DERIVE_TAIL_CYCLES for e in ends if e - DERIVE_TAIL_CYCLES > 0}
    )
    stretches = list(zip(cuts[:-1], cuts[1:]))
    post_wall = 0.0  # the derived columns' time (mostly on the worker thread)

    def derive(rows: np.ndarray) -> float:
        """Fills the rows' derived columns; returns the time it took (added up by the loop's
        thread only)."""
        t_post = time.perf_counter()
        post(rows)
        return time.perf_counter() - t_post

    def inputs(k0: int, k1: int, T_h0: np.ndarray | None):
        """A stretch's hand plan, sensor noise and dropouts (the random draws in the
        stretches' order). T_h0, the handle's pose at k0, matters only where a segment
        starts there."""
        rows = k1 - k0
        plan = intent.plan(k0, k1, T_h0)
        noise = (
            rng.normal(0.0, sensor_settings.noise_rad, (rows, n))
            if sensor_settings.noise_rad > 0.0
            else np.zeros((rows, n))
        )
        dropout = (
            (dropout_rng.random(rows) < sensor_settings.dropout_probability).astype(float)
            if sensor_settings.dropout_probability > 0.0
            else np.zeros(rows)
        )
        return plan, noise, dropout

    # Python's work runs beside the loop, on one worker thread (the loop releases Python's
    # lock while it runs): the next stretch's inputs, unless a segment starts there (its
    # plan needs the handle's pose the stretch before ends with), then the stretch before's
    # derived columns. One worker takes them in that order, so the random draws keep theirs.
    worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="virtmech-sim")
    pending: list[Future] = []  # the derived columns of the current block's stretches
    wall0 = time.perf_counter()
    sink_wall = 0.0  # the sink's time (writing the log): not the simulation's
    wait_wall = 0.0  # the loop's time on the derived columns or waiting for them
    b0 = 0  # first cycle of the current block
    underived = None  # the rows of the last stretch run, not yet handed to the worker
    ahead: Future | None = None  # this stretch's inputs, made while the last one ran
    try:
        for i, (k0, k1) in enumerate(stretches):
            if ahead is not None:
                plan, noise, dropout = ahead.result()
                ahead = None
            else:
                plan, noise, dropout = inputs(k0, k1, device.forward(Cinv @ (data.qpos - c0)))
            if i + 1 < len(stretches) and stretches[i + 1][0] not in starts:
                ahead = worker.submit(inputs, *stretches[i + 1], None)
            if underived is not None:
                pending.append(worker.submit(derive, underived))
            servo.run(k0, plan, noise, dropout, buf[k0 - b0 : k1 - b0])
            underived = buf[k0 - b0 : k1 - b0]
            if k1 - b0 == block or k1 == N:
                # the block's last stretch on this thread (it would wait for it anyway, and
                # waking the worker costs more than a short stretch), then the others' ends
                t_wait = time.perf_counter()
                post_wall += derive(underived)
                underived = None
                for f in pending:
                    post_wall += f.result()  # its rows filled (or its error raised here)
                pending.clear()
                wait_wall += time.perf_counter() - t_wait
                rows_done = buf[: k1 - b0]
                if log is not None:
                    log[b0:k1] = rows_done
                if sink is not None:
                    t_sink = time.perf_counter()
                    sink(rows_done, columns)
                    sink_wall += time.perf_counter() - t_sink
                b0 = k1
            bar.update(k1 * T_ctrl)
    finally:  # no derived stretch left running past the run (on an error: none started)
        worker.shutdown(wait=True, cancel_futures=True)
    wall = time.perf_counter() - wall0 - sink_wall
    bar.close(wall)

    info = {
        "device": device.to_dict(),
        "device_physics": phys.to_dict(),
        "mechanism": mech.to_dict(),
        **({"set_members": members, "set": dict(S["set"], members=len(members))}
           if members else {}),
        "controller_model": {
            k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in ctrl.model.items()
        },
        "human": human.to_dict(),
        "grip_contacts": list(contacts),
        "sensors": sensor_settings.to_dict(),
        "physics": {
            "timestep_s": T_ctrl / nsub,
            "substeps": nsub,
            "gravity": (g_world if gravity_on else np.zeros(3)).tolist(),
            "gravity_compensation": grav_comp,
            "integrator": "implicitfast",
            "engine": "compiled",
        },
        "initial_q": q0.tolist(),
        "seed": seed,
        "versions": versions(),
        "mjcf": built.xml,
    }
    return SimResult(
        scenario=scenario,
        columns=columns,
        log=log if log is not None else np.empty((0, len(columns))),
        sim_time_s=(N - 1) * T_ctrl,
        wall_time_s=wall,
        sink_time_s=sink_wall,
        control_time_s=servo.control_time_s,
        derived_time_s=post_wall,
        derived_wait_s=wait_wall,
        info=info,
    )


def versions() -> dict:
    import platform

    import mujoco

    return {
        "virtmech": vm.__version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
