"""The live simulation behind `virtmech view`: a scenario built as every run builds it
(virtmech.builder: device, controller, MuJoCo model and start), stepped a few control
cycles at a time by the same C++ servo loop `virtmech run` uses (virtmech.sim.inner.
ServoLoop), with the hand's anchor taken from the viewer (the
mouse) instead of the scenario's intent.

Per stretch of cycles (`LiveSim.step(n)`): a hand plan of n identical rows (anchor = the
target pose, anchor rates zero, the hand's gains from the settings), the sensor noise of
the stretch, then `ServoLoop.run`; the columns the loop does not write (distances, PlanarArm
angles, grip) are filled as `virtmech run` fills them. The rows are the log's rows
(virtmech.sim.log.log_columns); while recording they go to log.csv and, when the recording
stops, run.json (and the figures) are written as `virtmech run` writes them.

Settings that the loop holds (the controller's law, gains and passivity; the sensors' delay)
take effect by building a new controller and loop on the same MuJoCo state: the handle stays
where it is, the controller starts again (placements from the handle, force ramped in over
`ramp_time_s`). The hand's impedance and the sensor noise take effect at the next stretch.
No C++ is specific to the viewer.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..sim.human import PLAN_COLUMNS, PLAN_INDEX, plan_slice
from ..sim.run_loop import check_stable
from ..sim.sensors import SensorSettings

#: the controller laws the viewer offers (scenario key controller.law)
LAWS = ("auto", "under_actuated", "null_space")


@dataclass
class Settings:
    """What the viewer's controls change. kp, kv: the controller's translational gains
    [N/m], [N·s/m] (the three of them; the rotational ones stay the scenario's)."""

    law: str = "auto"
    kp: float = 500.0
    kv: float = 1.0
    passivity: bool = False
    hand_stiffness: float = 200.0  #: [N/m]
    hand_damping: float = 5.0  #: [N·s/m]
    hand_rot_stiffness: float = 1.0  #: [N·m/rad]
    hand_rot_damping: float = 0.01  #: [N·m·s/rad]
    noise_rad: float = 0.0
    delay_cycles: int = 0

    def to_dict(self) -> dict:
        return asdict(self)

    def scenario_keys(self, base_kp, base_kv) -> dict:
        """The scenario's keys (dotted) these settings stand for."""
        kp = np.array(base_kp, dtype=float)
        kv = np.array(base_kv, dtype=float)
        kp[:3], kv[:3] = self.kp, self.kv
        return {
            "controller.law": self.law,
            "controller.kp": kp.tolist(),
            "controller.kv": kv.tolist(),
            "controller.passivity": "energy_tank" if self.passivity else "off",
            "human.stiffness": self.hand_stiffness,
            "human.damping": self.hand_damping,
            "human.rot_stiffness": self.hand_rot_stiffness,
            "human.rot_damping": self.hand_rot_damping,
            "sensors.noise_rad": self.noise_rad,
            "sensors.delay_cycles": int(self.delay_cycles),
        }


def quat_wxyz(R: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix."""
    import mujoco

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def rot_of_wxyz(q) -> np.ndarray:
    """The rotation matrix of a quaternion (w, x, y, z) (normalised first)."""
    import mujoco

    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, q)
    return R.reshape(3, 3)


def _from_rig(path: str, doc: str = ""):
    """A read-only attribute of LiveSim that is its rig's (a dotted path into it)."""

    def get(self):
        obj = self.rig
        for part in path.split("."):
            obj = getattr(obj, part)
        return obj

    return property(get, doc=doc or f"The rig's {path}.")


class LiveSim:
    """One scenario, steppable: `step(n)` runs n control cycles (real time is the caller's
    business), `set_target(p, R)` moves the hand's anchor, `apply(settings)` changes the
    controls, `snapshot` is the state after the last stretch (a dict, see `_snap`)."""

    #: rows of the plotted history kept (one every `HISTORY_STRIDE` cycles)
    HISTORY = 600
    HISTORY_STRIDE = 10

    def __init__(self, scenario, seed: int | None = None):
        from ..builder import build

        self.rig = build(scenario, seed)
        rig = self.rig
        self.scenario = rig.scenario
        self.seed = rig.seed
        self.rng = np.random.default_rng(self.seed)
        self.col = {c: i for i, c in enumerate(rig.columns)}
        self.post = rig.derived_columns()
        human, sens = rig.human, rig.sensors
        self.base_kp = np.asarray(rig.controller.model["kp"], dtype=float)
        self.base_kv = np.asarray(rig.controller.model["kv"], dtype=float)
        self.settings = Settings(
            law=self.scenario.data["controller"]["law"],
            kp=float(self.base_kp[0]),
            kv=float(self.base_kv[0]),
            passivity=self.scenario.data["controller"]["passivity"] == "energy_tank",
            hand_stiffness=human.stiffness,
            hand_damping=human.damping,
            hand_rot_stiffness=human.rot_stiffness,
            hand_rot_damping=human.rot_damping,
            noise_rad=float(sens.noise_rad),
            delay_cycles=int(sens.delay_cycles),
        )
        self.sensor_settings = SensorSettings(**sens.to_dict())
        self.servo = rig.servo_loop(self.sensor_settings)

        self.k = 0  # control cycles run since the start (or the last reset)
        T0 = self.device.forward(self.q0)
        self.target_p = T0[:3, 3].copy()
        self.target_R = T0[:3, :3].copy()
        self._plan = np.zeros((0, len(PLAN_COLUMNS)))
        self.work_j = 0.0  # the device's work on the handle and the hand, since the start
        self.history = np.full((self.HISTORY, 7), np.nan)  # t, |f|, |f_null|, |f_range|,
        self._hist_n = 0  # dist, work, tank
        self.recorder: Recorder | None = None
        self.lock = threading.Lock()  # guards snapshot and history
        self.snapshot = self._snap(None)

    # -------------------------------------------------------------------------------------
    # what the rig holds (virtmech.builder.Rig)

    device = _from_rig("device")
    mech = _from_rig("mechanism", "The [mechanism] (member 0 of a set).")
    ctrl = _from_rig("controller", "The [mechanism]'s controller with the current settings.")
    renderer = _from_rig("renderer", "What renders: the controller, or a set's MechanismSet.")
    model = _from_rig("sim.model")
    data = _from_rig("sim.data")
    built = _from_rig("sim.built")
    T = _from_rig("period_s", "The control period [s].")
    nsub = _from_rig("sim.substeps", "Physics steps per control cycle.")
    n = _from_rig("device.dof")
    m = _from_rig("width", "The log's theta columns: the widest member's joints.")
    q0 = _from_rig("q0", "The start pose.")
    columns = _from_rig("columns", "The log's columns.")

    def _last(self):
        """The last cycle's CycleOutput (a set's: the member rendered)."""
        last = self.renderer.last
        return getattr(last, "cycle", last)

    def current_scenario(self):
        """The scenario with the current settings' keys set (what a recording says it ran)."""
        return self.scenario.with_keys(self.settings.scenario_keys(self.base_kp, self.base_kv))

    def apply(self, settings: Settings) -> None:
        """New settings; the controller and the loop are built again if the law, the gains,
        the passivity or the sensors' delay changed. A ValueError (a setting the controller
        refuses) leaves everything as it was."""
        old = self.settings
        rebuild = (
            settings.law != old.law
            or settings.kp != old.kp
            or settings.kv != old.kv
            or settings.passivity != old.passivity
            or settings.delay_cycles != old.delay_cycles
        )
        if rebuild:
            keys = settings.scenario_keys(self.base_kp, self.base_kv)
            rig = self.rig.with_controller(
                law=settings.law,
                kp=np.asarray(keys["controller.kp"]),
                kv=np.asarray(keys["controller.kv"]),
                passivity=keys["controller.passivity"],
            )
            sensors = SensorSettings(
                **{**self.sensor_settings.to_dict(), "delay_cycles": int(settings.delay_cycles)}
            )
            self.rig, self.sensor_settings = rig, sensors
        self.sensor_settings.noise_rad = float(settings.noise_rad)
        self.settings = settings
        if rebuild:
            self.servo = self.rig.servo_loop(self.sensor_settings)

    def set_target(self, p, R=None) -> None:
        self.target_p = np.asarray(p, dtype=float).copy()
        if R is not None:
            self.target_R = np.asarray(R, dtype=float).copy()

    # -------------------------------------------------------------------------------------
    # stepping

    def _plan_rows(self, n: int) -> np.ndarray:
        if self._plan.shape[0] != n:
            self._plan = np.zeros((n, len(PLAN_COLUMNS)))
        P, c, s = self._plan, PLAN_INDEX, self.settings
        P[:, plan_slice("ax", 3)] = self.target_p
        P[:, plan_slice("R00", 9)] = self.target_R.reshape(9)
        P[:, plan_slice("vx", 6)] = 0.0  # the hand damps against the world
        P[:, c["k_t"]] = s.hand_stiffness
        P[:, c["b_t"]] = s.hand_damping
        P[:, c["k_r"]] = s.hand_rot_stiffness
        P[:, c["b_r"]] = s.hand_rot_damping
        P[:, plan_slice("fx", 6)] = 0.0
        P[:, c["force_in_handle"]] = 0.0
        P[:, c["hand_attached"]] = 1.0
        P[:, c["segment"]] = 0.0
        return P

    def step(self, n: int) -> np.ndarray:
        """Runs n control cycles; returns their log rows (n, len(columns))."""
        n = int(n)
        plan = self._plan_rows(n)
        noise_rad = self.sensor_settings.noise_rad
        noise = (
            self.rng.normal(0.0, noise_rad, (n, self.n)) if noise_rad > 0 else np.zeros((n, self.n))
        )
        dropout = np.zeros(n)
        rows = np.empty((n, len(self.columns)))
        self.servo.run(self.k, plan, noise, dropout, rows)
        check_stable(self.scenario, self.rig.sim, self.k * self.T, (self.k + n) * self.T)
        self.post(rows)
        self.k += n
        c = self.col
        W = rows[:, c["fx"] : c["fx"] + 6]
        tw = rows[:, c["vx"] : c["vx"] + 6]
        work = np.cumsum(np.einsum("ij,ij->i", W, tw)) * self.T + self.work_j
        self.work_j = float(work[-1])
        snap = self._snap(rows)
        last = self._last()
        tank = float(last.energy) if self.settings.passivity else math.nan
        sel = np.flatnonzero((self.k - n + np.arange(n)) % self.HISTORY_STRIDE == 0)
        with self.lock:
            self.snapshot = snap
            if len(sel):
                h = np.column_stack(
                    [
                        rows[sel, c["t"]],
                        np.linalg.norm(W[sel, :3], axis=1),
                        np.linalg.norm(rows[sel, c["f_null0"] : c["f_null0"] + 3], axis=1),
                        np.linalg.norm(rows[sel, c["f_range0"] : c["f_range0"] + 3], axis=1),
                        rows[sel, c["dist"]],
                        work[sel],
                        np.full(len(sel), tank),
                    ]
                )
                self.history = np.roll(self.history, -len(h), axis=0)
                self.history[-len(h) :] = h
                self._hist_n = min(self.HISTORY, self._hist_n + len(h))
        if self.recorder is not None:
            self.recorder.add(rows)
        return rows

    def history_rows(self) -> np.ndarray:
        with self.lock:
            return self.history[self.HISTORY - self._hist_n :].copy()

    def geom_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(positions (g, 3), rotation matrices (g, 3, 3)) of the model's geoms now (call
        from the thread that steps)."""
        return self.data.geom_xpos.copy(), self.data.geom_xmat.reshape(-1, 3, 3).copy()

    def _snap(self, rows: np.ndarray | None) -> dict:
        """The state after the last stretch: what the viewer draws and `state()` reports."""
        c = self.col
        if rows is None:
            q = self.q0
            t = 0.0
            wrench = wn = wr = np.zeros(6)
            dist = math.nan
            status: list[str] = []
            T_m = T_ms = None
            theta = theta_s = np.full(self.m, math.nan)
            energy = stored = 0.0
        else:
            r = rows[-1]
            q = r[c["q0"] : c["q0"] + self.n]
            t = float(r[c["t"]])
            wrench = r[c["fx"] : c["fx"] + 6]
            wn = r[c["f_null0"] : c["f_null0"] + 6]
            wr = r[c["f_range0"] : c["f_range0"] + 6]
            dist = float(r[c["dist"]])
            last = self._last()
            status = list(last.status_names)
            T_m, T_ms = np.asarray(last.mechanism_pose), np.asarray(last.mechanism_pose_star)
            theta = r[c["theta0"] : c["theta0"] + self.m]
            theta_s = r[c["theta_star0"] : c["theta_star0"] + self.m]
            energy, stored = float(last.energy), float(last.stored_energy)
        T_h = self.device.forward(q)
        xpos, xmat = self.geom_poses()
        return {
            "t": t,
            "cycles": self.k,
            "q": np.array(q),
            "handle": T_h,
            "target_p": self.target_p.copy(),
            "target_R": self.target_R.copy(),
            "wrench": np.array(wrench),
            "wrench_null": np.array(wn),
            "wrench_range": np.array(wr),
            "mechanism_pose": T_m,
            "mechanism_pose_star": T_ms,
            "theta": np.array(theta),
            "theta_star": np.array(theta_s),
            "dist": dist,
            "status": status,
            "energy_tank_j": energy,
            "stored_energy_j": stored,
            "work_j": self.work_j,
            "geom_xpos": xpos,
            "geom_xmat": xmat,
            "joint_xanchor": self.data.xanchor.copy(),
            "wall": time.perf_counter(),
        }

    # -------------------------------------------------------------------------------------
    # recording

    def start_recording(self, folder: str | Path) -> Path:
        if self.recorder is not None:
            return self.recorder.folder
        self.recorder = Recorder(self, Path(folder))
        return self.recorder.folder

    def stop_recording(self) -> Recorder | None:
        """Stops recording; returns the recorder (its `finish()` writes run.json and the
        figures, which takes a second: call it off the stepping thread)."""
        rec, self.recorder = self.recorder, None
        if rec is not None:
            rec.close_log()
        return rec


class Recorder:
    """log.csv written as `virtmech run` writes it (virtmech.sim.logio.CsvLog, the same
    columns, t from 0 at the start of the recording), in blocks of `BLOCK` rows; then
    run.json (virtmech.sim.output.write_run) with the metrics, and the figures."""

    BLOCK = 2000

    def __init__(self, sim: LiveSim, folder: Path):
        from ..sim.logio import CsvLog, LogFile

        folder.mkdir(parents=True, exist_ok=True)
        self.folder = folder
        self.sim = sim
        self.scenario = sim.current_scenario()
        self.columns = sim.columns
        self.csv = CsvLog(folder / "log.csv")
        self.scratch = LogFile(folder)
        self.buf = np.empty((self.BLOCK, len(self.columns)))
        self.used = 0
        self.rows = 0
        self.t0: float | None = None
        self.k0 = sim.k
        self.wall0 = time.perf_counter()
        self.wall = 0.0

    def add(self, rows: np.ndarray) -> None:
        tcol = self.sim.col["t"]
        if self.t0 is None:
            self.t0 = float(rows[0, tcol])
        i = 0
        while i < len(rows):
            take = min(len(rows) - i, self.BLOCK - self.used)
            part = self.buf[self.used : self.used + take]
            part[:] = rows[i : i + take]
            part[:, tcol] -= self.t0
            self.used += take
            i += take
            if self.used == self.BLOCK:
                self._flush()

    def _flush(self) -> None:
        if self.used:
            block = self.buf[: self.used]
            self.csv(block, self.columns)
            self.scratch(block, self.columns)
            self.rows += self.used
            self.used = 0

    def close_log(self) -> None:
        self._flush()
        self.csv.close()
        self.wall = time.perf_counter() - self.wall0

    def finish(self) -> Path:
        """run.json (with the metrics) and plane.png, time.png; returns the folder."""
        from ..sim.log import SimResult
        from ..sim.output import metrics, write_run
        from ..viz import write_figures

        sim = self.sim
        try:
            if self.rows == 0:
                return self.folder
            duration = max((self.rows - 1) * sim.T, sim.T)
            scenario = self.scenario.with_overrides(duration_s=duration)
            result = SimResult(
                scenario=scenario,
                columns=self.columns,
                log=np.empty((0, len(self.columns))),
                sim_time_s=(self.rows - 1) * sim.T,
                wall_time_s=self.wall,
                info=info_of(sim),
                source=self.scratch,
            )
            result.info["log_file"] = "log.csv"
            result.info["recorded_by"] = "virtmech view (the hand: the viewer's target)"
            m = metrics(result)
            write_run(result, self.folder, log=False, metrics=m)
            write_figures(result, self.folder)
        finally:
            self.scratch.close()
        return self.folder


def info_of(sim: LiveSim) -> dict:
    """run.json's description of the live simulation (the rig's, with the hand and the
    sensors as the viewer's controls have them)."""
    st = sim.settings
    human = {
        "stiffness": st.hand_stiffness,
        "damping": st.hand_damping,
        "rot_stiffness": st.hand_rot_stiffness,
        "rot_damping": st.hand_rot_damping,
    }
    return sim.rig.info(human=human, sensors=sim.sensor_settings)


class Pacer:
    """Runs a LiveSim against the wall clock in a background thread: every `chunk_s` of
    wall time it runs the control cycles that are due (at most `max_lag_s` worth; beyond
    that the simulation falls behind and the real-time factor shows it). Changes from other
    threads go through `call` (run between stretches, in the stepping thread)."""

    def __init__(self, sim: LiveSim, chunk_s: float = 0.005, max_lag_s: float = 0.1):
        self.sim = sim
        self.chunk_s = chunk_s
        self.max_lag_s = max_lag_s
        self.paused = False
        self._calls: list = []
        self._calls_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.rtf = 0.0  # simulated / wall time over the last second
        self.load = 0.0  # the stepping's share of the wall time over the last second
        self.chunk_times: list[float] = []  # wall time of each stretch [s] (the last 2000)
        self.error: BaseException | None = None  # what ended the thread, if anything
        #: called (in the stepping thread) with the exception of a `call` that failed
        self.on_error = lambda e: None
        self._window: list[tuple[float, float, float]] = []  # (wall, sim, busy)

    def call(self, fn) -> None:
        """Runs fn(sim) in the stepping thread before the next stretch; if it returns a
        LiveSim, that one is stepped from then on."""
        with self._calls_lock:
            self._calls.append(fn)

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="virtmech-view-sim", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as e:  # reported by the viewer; the thread ends
            self.error = e

    def _loop(self) -> None:
        T = self.sim.T
        wall0 = time.perf_counter()
        k_ref = self.sim.k
        busy = 0.0
        while not self._stop.is_set():
            with self._calls_lock:
                calls, self._calls = self._calls, []
            for fn in calls:
                try:
                    new = fn(self.sim)
                except Exception as e:  # a call that fails leaves the simulation running
                    self.on_error(e)
                    continue
                if isinstance(new, LiveSim):
                    self.sim = new
                wall0, k_ref = time.perf_counter(), self.sim.k  # a new reference
                self._window.clear()
            now = time.perf_counter()
            if self.paused:  # the real-time factor is measured again from the resumption
                wall0, k_ref = now, self.sim.k
                self._window.clear()
                self.rtf = self.load = 0.0
                time.sleep(0.01)
                continue
            due = k_ref + int((now - wall0) / T) - self.sim.k
            lag = due * T
            if lag > self.max_lag_s:  # too far behind: let the wall clock go
                k_skip = due - int(self.max_lag_s / T)
                k_ref -= k_skip
                due -= k_skip
            if due * T < self.chunk_s:
                time.sleep(max(0.0, self.chunk_s - due * T))
                continue
            t0 = time.perf_counter()
            self.sim.step(due)
            dt = time.perf_counter() - t0
            busy += dt
            self.chunk_times.append(dt)
            if len(self.chunk_times) > 4000:
                del self.chunk_times[:2000]
            self._measure(time.perf_counter(), busy)

    def _measure(self, now: float, busy: float) -> None:
        w = self._window
        w.append((now, self.sim.k * self.sim.T, busy))
        while len(w) > 2 and now - w[0][0] > 1.0:
            w.pop(0)
        if len(w) >= 2 and w[-1][0] > w[0][0]:
            dw = w[-1][0] - w[0][0]
            self.rtf = (w[-1][1] - w[0][1]) / dw
            self.load = (w[-1][2] - w[0][2]) / dw
