"""The simulation run: the controller at the device rate with zero-order hold on torque,
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

Everything the run needs is built by virtmech.builder; the loop itself is C++
(virtmech.sim.inner.ServoLoop); this module feeds it stretch by stretch and collects the
log (virtmech.sim.log).
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import UserError
from .log import CHUNK_S, DERIVE_TAIL_CYCLES, SimResult, log_store

__all__ = ["Progress", "SimulationUnstable", "StretchInputs", "check_stable", "run"]


class SimulationUnstable(UserError):
    """MuJoCo found the state diverging (NaN, Inf or a huge acceleration, position or
    velocity) and reset it: what follows would not be the scenario's physics."""


def check_stable(scenario, sim, t0: float, t1: float) -> None:
    """Raises SimulationUnstable, naming the scenario's file and the stretch of simulated
    time [t0, t1] just run, where MuJoCo has warned that the simulation diverged (`sim`: the
    rig's SimModel)."""
    import mujoco

    w = mujoco.mjtWarning
    bad = {w.mjWARN_BADQACC: "acceleration", w.mjWARN_BADQVEL: "velocity",
           w.mjWARN_BADQPOS: "position"}
    for kind, what in bad.items():
        info = sim.data.warning[int(kind)]
        if info.number > 0:
            raise SimulationUnstable(
                f"{scenario.source}: the simulation became unstable between t = {t0:.3f} and "
                f"{t1:.3f} s (MuJoCo: NaN, Inf or a huge {what} at degree of freedom "
                f"{info.lastinfo}): "
                "the scenario drives the device harder than its physics can integrate; "
                "expected the intent's forces and moments and the hand's gains of a hand "
                "holding a stylus (a few newtons), or a higher physics.rate_hz"
            )


class Progress:
    """Progress on stderr in simulated seconds (virtmech.progress: a bar on a terminal,
    whole lines elsewhere), then one line with the scenario's simulated and wall time."""

    def __init__(self, label: str, total: float, enabled: bool):
        from ..progress import bar

        self.label, self.total, self.enabled = label, float(total), enabled
        self.bar = None
        self.wall0 = time.perf_counter()
        if enabled:
            self.bar = bar(
                self.total,
                f"{label:<16}",
                "{n:.2f}/{total:.2f} s",
                ascii=" #",
                ncols=80,
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
    from ..builder import build

    rig = build(scenario, seed)
    return _Run(rig, progress, sink, keep_log, chunk_s, spill_dir).go()


class StretchInputs:
    """A run's inputs a stretch of cycles at a time: the hand's plan (the rig's [[intent]]
    timeline), the sensor noise and the dropouts. The noise's draws and the dropouts' (from
    their own stream, a child of the same seed) follow one another whatever the stretches,
    so a run does not depend on where it is split (`virtmech run`'s blocks, `virtmech
    ros2-sim`'s cycles)."""

    def __init__(self, rig):
        self.rig = rig
        self.n = rig.device.dof
        self.rng = np.random.default_rng(rig.seed)
        self.dropout_rng = np.random.default_rng(np.random.SeedSequence(rig.seed).spawn(1)[0])
        self.intent = rig.intent()

    def __call__(self, k0: int, k1: int, T_h0: np.ndarray | None):
        """Cycles k0 .. k1 - 1: the hand's plan, sensor noise and dropouts (the random draws
        in the stretches' order). T_h0, the handle's pose at k0, matters only where a segment
        starts there."""
        rows, s = k1 - k0, self.rig.sensors
        plan = self.intent.plan(k0, k1, T_h0)
        noise = (
            self.rng.normal(0.0, s.noise_rad, (rows, self.n))
            if s.noise_rad > 0.0
            else np.zeros((rows, self.n))
        )
        dropout = (
            (self.dropout_rng.random(rows) < s.dropout_probability).astype(float)
            if s.dropout_probability > 0.0
            else np.zeros(rows)
        )
        return plan, noise, dropout


class _Run:
    """One run of a built rig: its stretches of cycles, the inputs of each (the hand's plan,
    the sensor draws), the blocks of the log and where they go."""

    def __init__(self, rig, progress, sink, keep_log, chunk_s, spill_dir):
        S = rig.data
        self.rig, self.sink = rig, sink
        self.T = rig.period_s
        self.n = rig.device.dof
        self.N = int(round(S["duration_s"] / self.T)) + 1
        self.inputs = StretchInputs(rig)  # the hand's plan and the sensor draws
        self.intent = self.inputs.intent
        self.servo = rig.servo_loop()
        self.post = rig.derived_columns()
        columns = rig.columns
        # the log is produced block by block (`block` cycles at a time, about chunk_s of
        # simulated time); each block is handed to `sink` and, unless the log would be too
        # large to hold, kept in memory for the result (else in a memory-mapped file)
        self.block = max(1, min(self.N, int(round(chunk_s / self.T))))
        self.log = log_store(self.N, len(columns), spill_dir) if keep_log else None
        self.buf = np.empty((self.block, len(columns)))  # the block being written, reused
        self.bar = Progress(rig.scenario.name, S["duration_s"], progress)
        self.starts = set(self.intent.start_cycles(self.N))
        self.post_wall = 0.0  # the derived columns' time (mostly on the worker thread)
        self.sink_wall = 0.0  # the sink's time (writing the log): not the simulation's
        self.wait_wall = 0.0  # the loop's time on the derived columns or waiting for them

    def stretches(self) -> list[tuple[int, int]]:
        """Stretches of cycles: split where a segment starts (the hand's plan needs the
        handle's pose there), every 1000 cycles (progress), at the ends of the blocks and
        DERIVE_TAIL_CYCLES before them (the last stretch's columns are derived while the
        loop waits: a short one leaves little to wait for)."""
        N, block = self.N, self.block
        ends = set(range(block, N, block)) | {N}
        tails = {e - DERIVE_TAIL_CYCLES for e in ends if e - DERIVE_TAIL_CYCLES > 0}
        cuts = sorted(self.starts | set(range(0, N, 1000)) | {0} | ends | tails)
        return list(zip(cuts[:-1], cuts[1:]))

    def handle_pose(self) -> np.ndarray:
        """The handle's pose now (the MuJoCo state's)."""
        sim = self.rig.sim
        cp = sim.coupling
        return self.rig.device.forward(cp.Cinv @ (sim.data.qpos - cp.c0))

    def derive(self, rows: np.ndarray) -> float:
        """Fills the rows' derived columns; returns the time it took (added up by the loop's
        thread only)."""
        t_post = time.perf_counter()
        self.post(rows)
        return time.perf_counter() - t_post

    def go(self) -> SimResult:
        """Python's work runs beside the loop, on one worker thread (the loop releases
        Python's lock while it runs): the next stretch's inputs, unless a segment starts
        there (its plan needs the handle's pose the stretch before ends with), then the
        stretch before's derived columns. One worker takes them in that order, so the random
        draws keep theirs."""
        stretches = self.stretches()
        worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="virtmech-sim")
        pending: list[Future] = []  # the derived columns of the current block's stretches
        wall0 = time.perf_counter()
        b0 = 0  # first cycle of the current block
        underived = None  # the rows of the last stretch run, not yet handed to the worker
        ahead: Future | None = None  # this stretch's inputs, made while the last one ran
        try:
            for i, (k0, k1) in enumerate(stretches):
                if ahead is not None:
                    plan, noise, dropout = ahead.result()
                    ahead = None
                else:
                    plan, noise, dropout = self.inputs(k0, k1, self.handle_pose())
                if i + 1 < len(stretches) and stretches[i + 1][0] not in self.starts:
                    ahead = worker.submit(self.inputs, *stretches[i + 1], None)
                if underived is not None:
                    pending.append(worker.submit(self.derive, underived))
                self.servo.run(k0, plan, noise, dropout, self.buf[k0 - b0 : k1 - b0])
                check_stable(self.rig.scenario, self.rig.sim, k0 * self.T, k1 * self.T)
                underived = self.buf[k0 - b0 : k1 - b0]
                if k1 - b0 == self.block or k1 == self.N:
                    self.end_block(b0, k1, underived, pending)
                    underived, b0 = None, k1
                self.bar.update(k1 * self.T)
        finally:  # no derived stretch left running past the run (on an error: none started)
            worker.shutdown(wait=True, cancel_futures=True)
        wall = time.perf_counter() - wall0 - self.sink_wall
        self.bar.close(wall)
        return self.result(wall)

    def end_block(self, b0: int, k1: int, last: np.ndarray, pending: list[Future]) -> None:
        """The block's last stretch derived on this thread (it would wait for it anyway, and
        waking the worker costs more than a short stretch), then the others' ends awaited;
        the block handed to the log and the sink."""
        t_wait = time.perf_counter()
        self.post_wall += self.derive(last)
        for f in pending:
            self.post_wall += f.result()  # its rows filled (or its error raised here)
        pending.clear()
        self.wait_wall += time.perf_counter() - t_wait
        rows_done = self.buf[: k1 - b0]
        if self.log is not None:
            self.log[b0:k1] = rows_done
        if self.sink is not None:
            t_sink = time.perf_counter()
            self.sink(rows_done, self.rig.columns)
            self.sink_wall += time.perf_counter() - t_sink

    def result(self, wall: float) -> SimResult:
        columns = self.rig.columns
        return SimResult(
            scenario=self.rig.scenario,
            columns=columns,
            log=self.log if self.log is not None else np.empty((0, len(columns))),
            sim_time_s=(self.N - 1) * self.T,
            wall_time_s=wall,
            sink_time_s=self.sink_wall,
            control_time_s=self.servo.control_time_s,
            derived_time_s=self.post_wall,
            derived_wait_s=self.wait_wall,
            info=self.rig.info(),
        )
