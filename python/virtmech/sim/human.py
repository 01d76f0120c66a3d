"""The human: a hand impedance coupled to the handle, driven by an intent timeline.

Model (one choice among those the issue allows, documented in docs/simulation.md):

- The hand's **mass and rotational inertia** ride rigidly on the handle (a body welded to
  the stylus in the MJCF, its weight carried by the user's arm: MuJoCo ``gravcomp``).
- The arm's **impedance** couples the handle to an *anchor* pose the intent moves. Every
  physics step the simulation applies to the handle the wrench

      F = k_t (p_a - p) + b_t (v_a - v) + f_push
      M = k_r log(R_a R^T) + b_r (w_a - w)

  with p, R, v, w the handle's pose and twist (from the core's kinematics at the true joint
  values). A *passive* axis group has k = 0 and damps against the world (v_a = 0): the
  relaxed hand that lets the robot move it.
- The **intent** is a list of segments (hold; follow a path; twist the handle; push with a
  force; resist = hold the position stiffly while twisting). Any segment may also push
  with a force (world or handle axes), ramped in and out over `ramp_s`. Each segment starts from
  where the previous left the anchor (or from the handle, where the previous segment left
  that axis group passive) and moves it with a minimum-jerk time scaling.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

import virtmech as vm


@dataclass
class HandImpedance:
    """Hand and arm holding a stylus (ranges from relaxed to tense: m 0.05..0.6 kg, b 2..10
    N·s/m, k 50..500 N/m; from fits of the arm at a HapticMaster's handle and of fingertip
    impedance, Hajian & Howe 1997). Rotational values are estimates (check)."""

    mass_kg: float = 0.2
    damping: float = 5.0  #: translational [N·s/m]
    stiffness: float = 200.0  #: translational [N/m]
    inertia: float = 2.0e-4  #: rotational, about the handle origin [kg·m²] (check)
    rot_damping: float = 0.01  #: [N·m·s/rad] (check)
    rot_stiffness: float = 1.0  #: [N·m/rad] (check)

    def to_dict(self) -> dict:
        return asdict(self)


def min_jerk(x: float) -> float:
    """Minimum-jerk time scaling of x in [0, 1] (clipped)."""
    x = min(max(x, 0.0), 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)


def min_jerk_array(x: np.ndarray) -> np.ndarray:
    """`min_jerk` of every element of x."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    return vm.so3_exp(np.asarray(axis, dtype=float) * angle)


def rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rotations (m, 3, 3) about the unit `axis` by each of `angles` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    th = np.asarray(angles, dtype=float)[:, None, None]
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * (K @ K)


def so3_log_batch(R: np.ndarray) -> np.ndarray:
    """so3_log of each rotation in R (m, 3, 3): rotation vectors (m, 3). The angle comes from
    atan2(|sin|, cos), exact for small rotations; rotations within 1e-6 rad of pi, where the
    axis is not in the skew part, go through vm.so3_log."""
    v = 0.5 * np.stack(
        (R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]), axis=1
    )
    s = np.linalg.norm(v, axis=1)
    c = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    th = np.arctan2(s, c)
    f = np.where(s > 1e-300, th / np.where(s > 1e-300, s, 1.0), 1.0)
    out = v * f[:, None]
    for i in np.flatnonzero(th > math.pi - 1e-6):
        out[i] = vm.so3_log(R[i])
    return out


#: columns of a hand plan (Intent.plan): one row per control cycle
PLAN_COLUMNS = (
    ["ax", "ay", "az"]
    + [f"R{i}{j}" for i in range(3) for j in range(3)]
    + ["vx", "vy", "vz", "wx", "wy", "wz", "k_t", "b_t", "k_r", "b_r"]
    + ["fx", "fy", "fz", "force_in_handle", "segment"]
)
#: column of each name in PLAN_COLUMNS
PLAN_INDEX = {name: i for i, name in enumerate(PLAN_COLUMNS)}


def plan_slice(first: str, width: int = 1) -> slice:
    """The PLAN_COLUMNS from `first`, `width` of them."""
    i = PLAN_INDEX[first]
    return slice(i, i + width)


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


class Intent:
    """The intent timeline: call `update(t, T_handle)` once per control cycle, in order."""

    def __init__(
        self, segments: list[dict], hand: HandImpedance, mechanism, T0: np.ndarray, period_s: float
    ):
        self.segments = sorted(segments, key=lambda s: s["start_s"])
        self.hand = hand
        self.mechanism = mechanism
        self.T = period_s
        self.p_a = T0[:3, 3].copy()
        self.R_a = T0[:3, :3].copy()
        self.trans_passive = False
        self.rot_passive = False
        self.k_t = hand.stiffness
        self.k_r = hand.rot_stiffness
        self.active = -1
        self._start_p = self.p_a.copy()
        self._start_R = self.R_a.copy()
        self._prev_p: np.ndarray | None = None
        self._prev_R: np.ndarray | None = None

    # the plane normal of the mechanism (axis "normal")
    def _normal(self) -> np.ndarray:
        d = self.mechanism.to_dict()
        for key in ("normal", "plane_normal"):
            if key in d:
                return np.asarray(d[key], dtype=float)
        return np.asarray(self.mechanism.joints[0].axis, dtype=float)

    def _axis(self, seg: dict, T_handle: np.ndarray) -> np.ndarray:
        a = seg.get("axis", "normal")
        if isinstance(a, str):
            v = self._normal() if a == "normal" else T_handle[:3, 2]
        else:
            v = np.asarray(a, dtype=float)
        return v / np.linalg.norm(v)

    def _start(self, i: int, T_handle: np.ndarray) -> None:
        seg = self.segments[i]
        # a segment starts from the anchor, or from the handle where the hand was passive
        self._start_p = T_handle[:3, 3].copy() if self.trans_passive else self.p_a.copy()
        self._start_R = T_handle[:3, :3].copy() if self.rot_passive else self.R_a.copy()
        action = seg["action"]
        default_t = "passive" if action in ("twist",) else "hold"
        self.trans_passive = seg.get("translation", default_t) == "passive"
        self.rot_passive = seg.get("orientation", "hold") == "passive"
        self.k_t = seg.get("stiffness", self.hand.stiffness)
        self.k_r = seg.get("rot_stiffness", self.hand.rot_stiffness)
        self._axis_vec = self._axis(seg, T_handle)
        if action == "follow" and "theta" in seg:
            self._path0 = self.mechanism.forward(np.array([float(seg["theta"][0])]))
        self.active = i

    def _follow(self, seg: dict, s: float) -> tuple[np.ndarray, np.ndarray]:
        p, R = self._follow_batch(seg, np.array([s]))
        return p[0], R[0]

    def start_cycles(self, n_cycles: int) -> list[int]:
        """The control cycles (< n_cycles) at which a segment starts: a plan must not run
        across one (it needs the handle's pose there)."""
        out = []
        for seg in self.segments:
            start = seg["start_s"] - 1e-12
            k = max(0, math.ceil(start / self.T))
            while k * self.T < start:
                k += 1
            while k > 0 and (k - 1) * self.T >= start:
                k -= 1
            if k < n_cycles:
                out.append(k)
        return sorted(set(out))

    def plan(self, k0: int, k1: int, T_handle: np.ndarray) -> np.ndarray:
        """The hand's targets for control cycles k0 .. k1 - 1 (t = k T), one row each with the
        columns PLAN_COLUMNS: what `update` returns cycle by cycle, for a stretch in which no
        segment starts after k0 (see `start_cycles`). T_handle is the handle's pose at cycle
        k0 (a segment starting there starts from it). A push given in handle axes is
        returned in handle axes with force_in_handle = 1: it turns with the handle."""
        t = np.arange(k0, k1) * self.T
        m = len(t)
        while (
            self.active + 1 < len(self.segments)
            and t[0] >= self.segments[self.active + 1]["start_s"] - 1e-12
        ):
            self._start(self.active + 1, T_handle)
        nxt = self.active + 1
        if nxt < len(self.segments) and m > 1:
            if t[-1] >= self.segments[nxt]["start_s"] - 1e-12:
                raise ValueError(
                    f"Intent.plan: segment {nxt} starts inside cycles {k0}..{k1 - 1}; split the "
                    "plan at start_cycles()"
                )
        P = np.empty((m, len(PLAN_COLUMNS)))
        p = np.broadcast_to(self.p_a, (m, 3)).copy()
        R = np.broadcast_to(self.R_a, (m, 3, 3)).copy()
        force = np.zeros((m, 3))
        in_handle = 0.0
        if self.active >= 0:
            seg = self.segments[self.active]
            dur = seg.get("duration_s", 0.0)
            s = min_jerk_array((t - seg["start_s"]) / dur) if dur > 0 else np.ones(m)
            action = seg["action"]
            p[:], R[:] = self._start_p, self._start_R
            if action == "follow":
                p, R = self._follow_batch(seg, s)
            elif action in ("twist", "resist"):
                R = rotations(self._axis_vec, np.radians(seg["angle_deg"]) * s) @ self._start_R
            if "force" in seg:
                ramp = seg.get("ramp_s", 0.1)
                tin = t - seg["start_s"]
                tout = seg["start_s"] + dur - t if dur > 0 else np.full(m, math.inf)
                if ramp > 0:
                    g = np.minimum(min_jerk_array(tin / ramp), min_jerk_array(tout / ramp))
                else:
                    g = np.ones(m)
                g = np.where((tin >= 0) & (tout >= 0), g, 0.0)
                force = g[:, None] * np.asarray(seg["force"], dtype=float)[None, :]
                in_handle = 1.0 if seg.get("force_frame", "world") == "handle" else 0.0
        # anchor rates: differences with the previous cycle's anchor (0 on the very first)
        if self._prev_p is None:
            pp = np.vstack([p[:1], p[:-1]])
            Rp = np.concatenate([R[:1], R[:-1]])
        else:
            pp = np.vstack([self._prev_p[None], p[:-1]])
            Rp = np.concatenate([self._prev_R[None], R[:-1]])
        v = (p - pp) / self.T
        w = so3_log_batch(R @ np.transpose(Rp, (0, 2, 1))) / self.T
        self.p_a, self.R_a = p[-1].copy(), R[-1].copy()
        self._prev_p, self._prev_R = p[-1].copy(), R[-1].copy()
        h, c = self.hand, PLAN_INDEX
        P[:, plan_slice("ax", 3)] = p
        P[:, plan_slice("R00", 9)] = R.reshape(m, 9)
        P[:, plan_slice("vx", 3)] = 0.0 if self.trans_passive else v
        P[:, plan_slice("wx", 3)] = 0.0 if self.rot_passive else w
        P[:, c["k_t"]] = 0.0 if self.trans_passive else float(self.k_t)
        P[:, c["b_t"]] = h.damping
        P[:, c["k_r"]] = 0.0 if self.rot_passive else float(self.k_r)
        P[:, c["b_r"]] = h.rot_damping
        P[:, plan_slice("fx", 3)] = force
        P[:, c["force_in_handle"]] = in_handle
        P[:, c["segment"]] = self.active
        return P

    def _follow_batch(self, seg: dict, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = len(s)
        p = np.broadcast_to(self._start_p, (m, 3)).copy()
        R = np.broadcast_to(self._start_R, (m, 3, 3)).copy()
        if "theta" in seg:
            a, b = seg["theta"]
            T0 = self._path0
            Ts = self.mechanism.forward_many((a + s * (b - a))[:, None])
            p += Ts[:, :3, 3] - T0[:3, 3]
            if seg.get("orientation", "hold") == "path":
                R = Ts[:, :3, :3] @ (T0[:3, :3].T @ self._start_R)
        else:
            pts = np.vstack([np.zeros(3), np.asarray(seg["offsets"], dtype=float)])
            seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            total = float(seglen.sum())
            if total > 0.0:
                dist = s * total
                cum = np.cumsum(seglen)
                k = np.minimum(np.searchsorted(cum, dist, side="left"), len(seglen) - 1)
                before = cum[k] - seglen[k]
                safe = np.where(seglen[k] > 0, seglen[k], 1.0)
                u = np.where(seglen[k] > 0, (dist - before) / safe, 0.0)
                p += pts[k] + u[:, None] * (pts[k + 1] - pts[k])
        return p, R

    # ---- one cycle at a time --------------------------------------------------------

    def update(self, t: float, T_handle: np.ndarray) -> HandTarget:
        while (
            self.active + 1 < len(self.segments)
            and t >= self.segments[self.active + 1]["start_s"] - 1e-12
        ):
            self._start(self.active + 1, T_handle)
        force = np.zeros(3)
        if self.active >= 0:
            seg = self.segments[self.active]
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
    """The wrench (6,) [N; N·m] the hand applies at the handle origin, world axes."""
    F = target.k_t * (target.p - T[:3, 3]) + target.b_t * (target.v - twist[:3]) + target.force
    M = target.k_r * vm.so3_log(target.R @ T[:3, :3].T) + target.b_r * (target.w - twist[3:])
    return np.concatenate([F, M])
