"""The hand's intent cycle by cycle and the hand's wrench, written out one cycle at a time:
the references virtmech.sim.human.Intent.plan (vectorised over stretches of cycles) and the
C++ loop's hand wrench (sim/src/servo_loop.cpp) are compared with (tests/python/
test_sim_engine.py, test_sim_sensors_grip.py, reference.sim_loop). The original actions only
(hold, follow with a minimum-jerk profile, twist, resist, push)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import virtmech as vm
from virtmech.sim.human import Intent, min_jerk, rotation

#: the actions only `Intent.plan` plans (not `CycleIntent.update`)
PLAN_ONLY = ("wrench", "release", "sine", "chirp")


@dataclass
class HandTarget:
    """Where the hand wants the handle this cycle, and how stiffly."""

    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    w: np.ndarray
    k_t: float
    b_t: float
    k_r: float
    b_r: float
    force: np.ndarray
    segment: int
    moment: np.ndarray | None = None  #: pushed moment [N·m], world axes (None: zero)
    attached: bool = True  #: False: the hand has let go (no wrench at all)


class CycleIntent(Intent):
    """Intent with `update(t, T_handle)`: the hand's target once per control cycle, in
    order."""

    def _follow(self, seg: dict, s: float) -> tuple[np.ndarray, np.ndarray]:
        p, R = self._follow_batch(seg, np.array([s]))
        return p[0], R[0]

    def update(self, t: float, T_handle: np.ndarray) -> HandTarget:
        while (
            self.active + 1 < len(self.segments)
            and t >= self.segments[self.active + 1]["start_s"] - 1e-12
        ):
            self._start(self.active + 1, T_handle)
        force = np.zeros(3)
        if self.active >= 0:
            seg = self.segments[self.active]
            if (
                seg["action"] in PLAN_ONLY
                or "moment" in seg
                or seg.get("profile", "min_jerk") != "min_jerk"
            ):
                raise ValueError(
                    f"Intent.update: intent[{self._given[self.active]}] (action "
                    f"{seg['action']!r}) is planned by Intent.plan only"
                )
            dur = seg.get("duration_s", 0.0)
            s = min_jerk((t - seg["start_s"]) / dur) if dur > 0 else 1.0
            action = seg["action"]
            if action == "hold":
                self.p_a, self.R_a = self._start_p, self._start_R
            elif action == "follow":
                self.p_a, self.R_a = self._follow(seg, s)
            elif action in ("twist", "resist"):
                self.p_a = self._start_p
                ang = np.radians(seg["angle_deg"]) * s
                self.R_a = rotation(self._axis_vec, ang) @ self._start_R
            elif action == "push":
                self.p_a, self.R_a = self._start_p, self._start_R
            if "force" in seg:
                ramp = seg.get("ramp_s", 0.1)
                tin = t - seg["start_s"]
                tout = seg["start_s"] + dur - t if dur > 0 else math.inf
                g = min(min_jerk(tin / ramp), min_jerk(tout / ramp)) if ramp > 0 else 1.0
                if tin >= 0 and tout >= 0:
                    f = np.asarray(seg["force"], dtype=float)
                    if seg.get("force_frame", "world") == "handle":
                        f = T_handle[:3, :3] @ f
                    force = g * f
        if self._prev_p is None:
            v, w = np.zeros(3), np.zeros(3)
        else:
            v = (self.p_a - self._prev_p) / self.T
            w = vm.so3_log(self.R_a @ self._prev_R.T) / self.T
        self._prev_p, self._prev_R = self.p_a.copy(), self.R_a.copy()
        h = self.hand
        return HandTarget(
            p=self.p_a,
            R=self.R_a,
            v=np.zeros(3) if self.trans_passive else v,
            w=np.zeros(3) if self.rot_passive else w,
            k_t=0.0 if self.trans_passive else float(self.k_t),
            b_t=h.damping,
            k_r=0.0 if self.rot_passive else float(self.k_r),
            b_r=h.rot_damping,
            force=force,
            segment=self.active,
        )


def hand_wrench(target: HandTarget, T: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """The wrench (6,) [N; N·m] the hand applies at the handle origin, world axes (zero
    when the hand has let go)."""
    if not target.attached:
        return np.zeros(6)
    F = target.k_t * (target.p - T[:3, 3]) + target.b_t * (target.v - twist[:3]) + target.force
    M = target.k_r * vm.so3_log(target.R @ T[:3, :3].T) + target.b_r * (target.w - twist[3:])
    if target.moment is not None:
        M = M + target.moment
    return np.concatenate([F, M])
