"""The simulation's log: its columns (one row per control cycle) and their units, the run's
result (`SimResult`), the columns that follow from each row alone (`DerivedColumns`: the
distances from the mechanism, a PlanarArm's angles, the grip), and the in-memory store of a
long log."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import virtmech as vm

from . import inner
from .geometry import COLUMNS as DIST_COLUMNS
from .geometry import distances, geometry_of
from .grip import finger_forces_batch

# ---------------------------------------------------------------------------------------
# geometry for the log


class PlanarGeometry:
    """The angles of the handle on a PlanarArm's circle (and its distance from the circle,
    as sim.geometry.planar_arm computes it for the log)."""

    def __init__(self, mech: dict):
        self.c = np.asarray(mech["pivot"], dtype=float)
        self.n = np.asarray(mech["normal"], dtype=float)
        self.n /= np.linalg.norm(self.n)
        self.d = np.asarray(mech["zero_direction"], dtype=float)
        self.d /= np.linalg.norm(self.d)
        self.e = np.cross(self.n, self.d)
        self.L = float(mech["length"])

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


def log_store(rows: int, cols: int, spill_dir) -> np.ndarray:
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


class DerivedColumns:
    """Fills the columns that follow from the logged state alone (the distance from the
    path, the PlanarArm angles, the grip) in a block of rows. `mechanisms`: the run's
    mechanisms (objects or their to_dict()), member 0 first; `contacts`: the grip's finger
    positions along the stylus [m]."""

    def __init__(self, columns: list[str], mechanisms: list, contacts):
        self.c = {name: i for i, name in enumerate(columns)}
        # the mechanisms (or their to_dict()), made once
        self.mechanisms = [vm.make_mechanism(m) if isinstance(m, dict) else m for m in mechanisms]
        first = self.mechanisms[0]
        self.planar = PlanarGeometry(first.to_dict()) if first.type == "PlanarArm" else None
        self.contacts = contacts

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

def versions() -> dict:
    import platform

    import mujoco

    return {
        "virtmech": vm.__version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
