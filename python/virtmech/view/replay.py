"""A run's log played back: the folder `virtmech run` writes (log.csv or log.parquet and
run.json), read into memory (the columns the viewer draws), and the frame at any time in
the same form as the live simulation's snapshot (virtmech.view.live.LiveSim).

What is drawn is computed from the logged joint values, not copied from the logged handle
columns: the device's bodies by MuJoCo's forward kinematics of the scenario's model
(`q` through the device's joint map), the handle pose by the core's `device.forward(q)`,
the mechanism's placements by `mechanism.forward(theta)` and `forward(theta_star)`; the
forces are the logged `fx..mz`, `f_null*`, `f_range*`, the hand's target the logged anchor
`ax..az` (its orientation is not logged).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..sim.logio import LOG_FORMATS


def is_log_dir(path: str | Path) -> bool:
    p = Path(path)
    return p.is_dir()


#: the log files a run writes (its --format)
LOG_NAMES = tuple(f"log.{f}" for f in LOG_FORMATS)


def _log_file(folder: Path, named: object = None) -> Path:
    """The run's log: the file run.json names (`log_file`), else log.csv or log.parquet."""
    names = (named,) if isinstance(named, str) and named in LOG_NAMES else LOG_NAMES
    for name in names:
        if (folder / name).is_file():
            return folder / name
    if names != LOG_NAMES:
        raise UserError(
            f"LOG_DIR {folder}: no {named} in the folder, the log its run.json names; "
            "expected the folder as `virtmech run` wrote it"
        )
    raise UserError(
        f"LOG_DIR {folder}: no log.csv or log.parquet in the folder; expected a folder "
        "written by `virtmech run` (log.csv and run.json)"
    )


class Replay:
    """A logged run, frame by frame: `frame(t)` at the last logged cycle at or before t."""

    def __init__(self, folder: str | Path):
        from .. import scenarios as sc
        from ..builder import build

        folder = Path(folder)
        self.folder = folder
        run_json = folder / "run.json"
        if not run_json.is_file():
            raise UserError(
                f"LOG_DIR {folder}: no run.json in the folder; expected a folder written by "
                "`virtmech run` (log.csv and run.json)"
            )
        try:
            info = json.loads(run_json.read_text(encoding="utf-8"))
            log_path = _log_file(folder, info.get("log_file"))
            S = info["scenario"]
            self.name = str(info.get("name", folder.name))
            rig = build(sc.validate(S, source=str(run_json)), simulated=False)
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
            raise UserError(
                f"LOG_DIR {folder}: run.json cannot be read as a run of `virtmech run` ({e})"
            ) from None
        self.info = info
        self._drawn(S, rig)
        self.columns, self.log = self._read(log_path)
        self.col = {c: i for i, c in enumerate(self.columns)}
        c = self.col
        self.t = self.log[:, c["t"]]
        W = self.log[:, c["fx"] : c["fx"] + 6]
        tw = self.log[:, c["vx"] : c["vx"] + 6]
        self.work = np.cumsum(np.einsum("ij,ij->i", W, tw)) * self.T
        self.duration = float(self.t[-1]) if len(self.t) else 0.0

    def _drawn(self, S: dict, rig) -> None:
        """The device and the mechanism of the scenario data S (`rig`, built from it with
        simulated=False), and the device's model for drawing (no hand, no gravity)."""
        import mujoco

        from ..sim.model import HandBody, build_mjcf, compile_model, device_physics

        self.scenario_data = S
        self.device, self.mech = rig.device, rig.mechanism
        self.n, self.m = rig.device.dof, rig.width
        self.T = float(S["controller"]["period_s"])
        built = build_mjcf(
            self.device,
            params=device_physics(S["device"]),
            hand=HandBody(0.0, 0.0),
            gravity=np.zeros(3),
            timestep=self.T,
        )
        self.built = built
        self.model = compile_model(built)
        self.data = mujoco.MjData(self.model)
        self.C, self.c0 = built.coupling.C, built.coupling.c0

    def needed(self) -> list[str]:
        names = ["t"]
        names += [f"q{i}" for i in range(self.n)]
        names += ["px", "py", "pz", "sx", "sy", "sz", "vx", "vy", "vz", "wx", "wy", "wz"]
        names += ["fx", "fy", "fz", "mx", "my", "mz", "status", "ax", "ay", "az", "dist"]
        names += [f"theta{i}" for i in range(self.m)] + [f"theta_star{i}" for i in range(self.m)]
        names += [f"f_null{i}" for i in range(6)] + [f"f_range{i}" for i in range(6)]
        return names

    def _read(self, path: Path) -> tuple[list[str], np.ndarray]:
        from ..sim.logio import read_csv_blocks, read_parquet_blocks

        reader = read_parquet_blocks if path.suffix == ".parquet" else read_csv_blocks
        try:
            columns, blocks = reader(path)
            need = self.needed()
            missing = [n for n in need if n not in columns]
            if missing:
                raise UserError(
                    f"LOG_DIR {self.folder}: {path.name} lacks the columns "
                    f"{', '.join(missing[:6])}; expected a log written by `virtmech run`"
                )
            idx = [columns.index(n) for n in need]
            parts = [np.asarray(b[:, idx], dtype=float) for b in blocks]
        except (OSError, ValueError) as e:
            raise UserError(f"LOG_DIR {self.folder}: {path.name} cannot be read ({e})") from None
        if not parts or sum(len(p) for p in parts) == 0:
            raise UserError(f"LOG_DIR {self.folder}: {path.name} has no rows")
        return need, np.concatenate(parts)

    def index_at(self, t: float) -> int:
        """The row of the last cycle at or before t (the first row before the start)."""
        i = int(np.searchsorted(self.t, t + 1e-9, side="right")) - 1
        return min(max(i, 0), len(self.t) - 1)

    def frame(self, t: float) -> dict:
        """The frame at time t, in the form of LiveSim.snapshot."""
        import mujoco

        from .. import status as st

        i = self.index_at(t)
        r = self.log[i]
        c = self.col
        q = r[c["q0"] : c["q0"] + self.n]
        self.data.qpos[:] = self.C @ q + self.c0
        mujoco.mj_kinematics(self.model, self.data)
        theta = r[c["theta0"] : c["theta0"] + self.m]
        theta_s = r[c["theta_star0"] : c["theta_star0"] + self.m]

        def placement(th):
            return self.mech.forward(th) if np.all(np.isfinite(th)) else None

        return {
            "t": float(r[c["t"]]),
            "cycles": i,
            "q": q.copy(),
            "handle": self.device.forward(q),
            "target_p": r[c["ax"] : c["ax"] + 3].copy(),
            "target_R": None,
            "wrench": r[c["fx"] : c["fx"] + 6].copy(),
            "wrench_null": r[c["f_null0"] : c["f_null0"] + 6].copy(),
            "wrench_range": r[c["f_range0"] : c["f_range0"] + 6].copy(),
            "mechanism_pose": placement(theta),
            "mechanism_pose_star": placement(theta_s),
            "theta": theta.copy(),
            "theta_star": theta_s.copy(),
            "dist": float(r[c["dist"]]),
            "status": list(st.names(int(r[c["status"]]))),
            "energy_tank_j": math.nan,
            "stored_energy_j": math.nan,
            "work_j": float(self.work[i]),
            "geom_xpos": self.data.geom_xpos.copy(),
            "geom_xmat": self.data.geom_xmat.reshape(-1, 3, 3).copy(),
            "joint_xanchor": self.data.xanchor.copy(),
            "logged_handle_p": r[c["px"] : c["px"] + 3].copy(),
            "logged_stylus": r[c["sx"] : c["sx"] + 3].copy(),
        }

    def history(self, t: float, window_s: float = 6.0, points: int = 600) -> np.ndarray:
        """The plotted rows (t, |f|, |f_null|, |f_range|, dist, work, tank) over the
        `window_s` before t, at most `points` of them."""
        i1 = self.index_at(t) + 1
        i0 = self.index_at(t - window_s)
        step = max(1, (i1 - i0) // points)
        sel = np.arange(i0, i1, step)
        c, L = self.col, self.log
        return np.column_stack(
            [
                L[sel, c["t"]],
                np.linalg.norm(L[sel, c["fx"] : c["fx"] + 3], axis=1),
                np.linalg.norm(L[sel, c["f_null0"] : c["f_null0"] + 3], axis=1),
                np.linalg.norm(L[sel, c["f_range0"] : c["f_range0"] + 3], axis=1),
                L[sel, c["dist"]],
                self.work[sel],
                np.full(len(sel), math.nan),
            ]
        )
