"""A driven device in the viewer (`virtmech drive --view`): the ticks `virtmech drive` logs,
appended as they come, drawn as a replay's frames (virtmech.view.replay) that follow the
device. The real handle, the mechanism's placements θ and θ*, and the forces are drawn from
the device's readings; the hand gizmo is off (the hand is the user's): the target marker sits
on the handle."""

from __future__ import annotations

import math

import numpy as np

from .replay import Replay


class DeviceFeed(Replay):
    """The last `window_s` of a driven device's log, appended block by block from the drive's
    thread (`append`), read frame by frame by the viewer's (each read sees one whole
    snapshot: appending swaps it at once)."""

    def __init__(self, rig, window_s: float = 20.0):
        self.folder = None
        self.info = {}
        self.name = rig.scenario.name
        self._drawn(rig.data, rig)
        device = self.device
        self.columns = self.needed()
        self.col = {c: i for i, c in enumerate(self.columns)}
        self.rows = max(2, int(round(window_s / self.T)))
        # before the first tick: the device's home, no force
        first = np.zeros((1, len(self.columns)))
        first[0, self.col["q0"] : self.col["q0"] + self.n] = device.home
        first[0, self.col["theta0"] : self.col["theta0"] + self.m] = math.nan
        first[0, self.col["theta_star0"] : self.col["theta_star0"] + self.m] = math.nan
        first[0, self.col["dist"]] = math.nan
        T = device.forward(np.asarray(device.home, dtype=float))
        first[0, self.col["px"] : self.col["px"] + 3] = T[:3, 3]
        first[0, self.col["ax"] : self.col["ax"] + 3] = T[:3, 3]
        first[0, self.col["sx"] : self.col["sx"] + 3] = T[:3, 2]
        self._work = 0.0
        self._snap = self._snapshot(first, np.zeros(1))

    def _snapshot(self, log: np.ndarray, work: np.ndarray) -> Replay:
        snap = Replay.__new__(Replay)
        snap.__dict__.update({k: v for k, v in self.__dict__.items() if k != "_snap"})
        snap.log, snap.work = log, work
        snap.t = log[:, self.col["t"]]
        snap.duration = float(snap.t[-1])
        return snap

    def append(self, rows: np.ndarray, columns: list[str]) -> None:
        """Rows of the drive's log (its `columns`): the newest kept, the oldest beyond the
        window dropped."""
        if len(rows) == 0:
            return
        c = self.col
        block = np.asarray(rows[:, [columns.index(n) for n in self.columns]], dtype=float)
        # no hand: the target on the handle, where the readings put it (a tick whose cycle
        # faulted carries no handle pose of the controller's)
        q = block[:, c["q0"] : c["q0"] + self.n]
        read = np.isfinite(q).all(axis=1)
        block[:, c["ax"] : c["ax"] + 3] = block[:, c["px"] : c["px"] + 3]
        if read.any():
            block[read, c["ax"] : c["ax"] + 3] = self.device.forward_many(q[read])[:, :3, 3]
        W, tw = block[:, c["fx"] : c["fx"] + 6], block[:, c["vx"] : c["vx"] + 6]
        work = self._work + np.cumsum(np.einsum("ij,ij->i", W, tw)) * self.T
        self._work = float(work[-1])
        old = self._snap
        log = np.concatenate([old.log, block])[-self.rows :]
        self._snap = self._snapshot(log, np.concatenate([old.work, work])[-self.rows :])

    @property
    def duration(self) -> float:
        return self._snap.duration

    def index_at(self, t: float) -> int:
        return Replay.index_at(self._snap, t)

    def frame(self, t: float) -> dict:
        return Replay.frame(self._snap, t)

    def history(self, t: float, window_s: float = 6.0, points: int = 600) -> np.ndarray:
        return Replay.history(self._snap, t, window_s, points)
