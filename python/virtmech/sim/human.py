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
- The **intent** is a list of segments (hold; follow a path, with a minimum-jerk or a
  constant-speed profile; twist the handle; push with a force; resist = hold the position
  stiffly while twisting; sine and chirp oscillations of the anchor; a pure wrench with no
  impedance; release = no hand at all). Any segment but release may also push with a force
  and a moment (world or handle axes), ramped in and out over `ramp_s`. Each segment starts
  from where the previous left the anchor (or from the handle, where the previous segment
  left that axis group passive, pushed a pure wrench or let go).
- **Release**: the plan's `hand_attached` column is 0; the loop then applies no hand wrench
  and zeroes the hand body's mass and inertia in the model (servo_loop.hpp), so the handle
  moves as on a model built without the hand; a later segment takes hold again.
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


def min_jerk_rate(x: np.ndarray) -> np.ndarray:
    """d min_jerk / dx of every element of x (0 outside [0, 1])."""
    x = np.asarray(x, dtype=float)
    inside = (x >= 0.0) & (x <= 1.0)
    return np.where(inside, 30.0 * x * x * (1.0 - x) ** 2, 0.0)


def min_jerk_integral(x: np.ndarray) -> np.ndarray:
    """The integral of min_jerk from 0 to x, for x in [0, 1] (clipped): x^4 (5/2 - 3 x + x^2);
    1/2 at x = 1."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return x**4 * (2.5 - 3.0 * x + x * x)


def ramp_envelope(tau: np.ndarray, duration: float, ramp: float):
    """(g, dg/dtau): 0 before tau = 0 and after `duration` (none: never ends), ramped up
    and down with min_jerk over `ramp` [s], 1 in between."""
    tau = np.asarray(tau, dtype=float)
    end = duration if duration > 0 else math.inf
    tout = end - tau
    if ramp > 0:
        gi, go = min_jerk_array(tau / ramp), min_jerk_array(tout / ramp)
        di, do = min_jerk_rate(tau / ramp) / ramp, -min_jerk_rate(tout / ramp) / ramp
        g = np.minimum(gi, go)
        dg = np.where(gi <= go, di, do)
    else:
        g, dg = np.ones_like(tau), np.zeros_like(tau)
    inside = (tau >= 0) & (tout >= 0)
    return np.where(inside, g, 0.0), np.where(inside, dg, 0.0)


def constant_speed_distance(tau: np.ndarray, length: float, speed: float, ramp: float):
    """(distance, speed) along a path of `length` [m] at time tau [s] of a constant-speed
    segment: the speed rises from 0 to `speed` over `ramp` with a min_jerk profile, holds,
    and falls back to 0 at the end, which is at length / speed + ramp (each ramp covers
    speed * ramp / 2)."""
    tau = np.asarray(tau, dtype=float)
    D = length / speed + ramp
    if ramp > 0:
        d_in = speed * ramp * min_jerk_integral(tau / ramp)
        d_out = length - speed * ramp * min_jerk_integral((D - tau) / ramp)
        cruise = speed * ramp / 2.0 + speed * (tau - ramp)
        d = np.where(tau < ramp, d_in, np.where(tau > D - ramp, d_out, cruise))
        v = speed * np.minimum(min_jerk_array(tau / ramp), min_jerk_array((D - tau) / ramp))
    else:
        d, v = speed * tau, np.full(tau.shape, speed)
    d = np.where(tau <= 0, 0.0, np.where(tau >= D, length, d))
    v = np.where((tau <= 0) | (tau >= D), 0.0, v)
    return d, v


class ArcLength:
    """Arc length along a one-joint mechanism's path theta in [a, b] and its inverse: the
    path's speed |dp/dtheta| (five-point central differences) on a grid of 2049 values of
    theta, integrated with Simpson's rule; theta(s) by cubic Hermite interpolation with the
    slopes 1 / |dp/dtheta| (exact where |dp/dtheta| is constant, e.g. a PlanarArm's circle;
    elsewhere the grid's accuracy, about h^4 with h = (b - a) / 2048)."""

    NODES = 2049  # odd: Simpson pairs

    def __init__(self, mechanism, a: float, b: float):
        self.mechanism, self.a, self.b = mechanism, float(a), float(b)
        self.sign = 1.0 if b >= a else -1.0
        th = np.linspace(self.a, self.b, self.NODES)
        self.theta = th
        self.rate = np.linalg.norm(self.dp(th), axis=1)  # |dp/dtheta|
        h = (self.b - self.a) / (self.NODES - 1)
        # cumulative Simpson over pairs of intervals; the node between, by the integral of
        # the quadratic through the pair over its first half
        r = self.rate
        s = np.zeros(self.NODES)
        for_pairs = abs(h) / 3.0 * (r[0:-2:2] + 4.0 * r[1:-1:2] + r[2::2])
        s[2::2] = np.cumsum(for_pairs)
        s[1::2] = s[0:-2:2] + abs(h) / 12.0 * (5.0 * r[0:-2:2] + 8.0 * r[1:-1:2] - r[2::2])
        self.s = s
        self.length = float(s[-1])

    def dp(self, th: np.ndarray) -> np.ndarray:
        """dp/dtheta (m, 3) of the path's position at each theta: five-point central
        differences (truncation h^4, rounding 1e-16 / h; h = 1e-3 gives about 1e-13 relative
        on a circle)."""
        h = 1e-3
        th = np.asarray(th, dtype=float)

        def p(x):
            return self.mechanism.forward_many(x[:, None])[:, :3, 3]

        return (p(th - 2 * h) - 8.0 * p(th - h) + 8.0 * p(th + h) - p(th + 2 * h)) / (12.0 * h)

    def theta_at(self, d: np.ndarray) -> np.ndarray:
        """theta at arc length d in [0, length] from a."""
        d = np.clip(np.asarray(d, dtype=float), 0.0, self.length)
        s, th = self.s, self.theta
        i = np.clip(np.searchsorted(s, d, side="right") - 1, 0, len(s) - 2)
        ds = s[i + 1] - s[i]
        safe = np.where(ds > 0, ds, 1.0)
        u = np.where(ds > 0, (d - s[i]) / safe, 0.0)
        m0 = self.sign / np.maximum(self.rate[i], 1e-300) * ds
        m1 = self.sign / np.maximum(self.rate[i + 1], 1e-300) * ds
        u2, u3 = u * u, u * u * u
        return (
            (2 * u3 - 3 * u2 + 1) * th[i]
            + (u3 - 2 * u2 + u) * m0
            + (-2 * u3 + 3 * u2) * th[i + 1]
            + (u3 - u2) * m1
        )


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
    + ["fx", "fy", "fz", "mx", "my", "mz", "force_in_handle", "hand_attached", "segment"]
)
#: actions that Intent.plan plans and the per-cycle Intent.update does not

#: column of each name in PLAN_COLUMNS
PLAN_INDEX = {name: i for i, name in enumerate(PLAN_COLUMNS)}


def plan_slice(first: str, width: int = 1) -> slice:
    """The PLAN_COLUMNS from `first`, `width` of them."""
    i = PLAN_INDEX[first]
    return slice(i, i + width)


class Intent:
    """The intent timeline: `plan(k0, k1, T_handle)` over consecutive stretches of cycles
    (see `start_cycles`). Segments are the [[intent]] tables as dicts; a mistake that
    needs the mechanism raises a ValueError naming `intent[i].key` (i: the segment's place
    in `segments`)."""

    def __init__(
        self, segments: list[dict], hand: HandImpedance, mechanism, T0: np.ndarray, period_s: float
    ):
        order = sorted(range(len(segments)), key=lambda i: segments[i]["start_s"])
        self.segments = [segments[i] for i in order]
        self._given = order  # each (sorted) segment's index in `segments`
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
        self.damped = True  # False: a pure wrench (no damping either)
        self.attached = True  # False: released
        # each segment's duration [s]: a constant-speed follow's from its path and speed
        self._arcs: dict[int, ArcLength] = {}
        for i, seg in enumerate(self.segments):
            if seg["action"] == "follow" and "theta" in seg and mechanism.dof != 1:
                raise ValueError(
                    f"intent[{self._given[i]}].theta: expected a one-joint mechanism (theta = "
                    f"[a, b] are its joint values), got {type(mechanism).__name__} with "
                    f"{mechanism.dof} joints; give the path as offsets instead"
                )
        self.durations = [self._duration(i, seg) for i, seg in enumerate(self.segments)]

    def _path_length(self, i: int, seg: dict) -> float:
        if "theta" in seg:
            if i not in self._arcs:
                a, b = (float(x) for x in seg["theta"])
                self._arcs[i] = ArcLength(self.mechanism, a, b)
            return self._arcs[i].length
        pts = np.vstack([np.zeros(3), np.asarray(seg["offsets"], dtype=float)])
        return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())

    def _duration(self, i: int, seg: dict) -> float:
        """The segment's duration [s] (0: none): duration_s, or for a constant-speed follow
        its path length / speed_m_s + ramp_s."""
        if seg["action"] == "follow" and seg.get("profile", "min_jerk") == "constant":
            L, V, r = self._path_length(i, seg), float(seg["speed_m_s"]), seg.get("ramp_s", 0.1)
            if not L > 0.0:
                raise ValueError(
                    f"intent[{self._given[i]}].speed_m_s: a constant-speed follow needs a path "
                    f"of non-zero length; its path is {L:g} m long"
                )
            if L < V * r:
                raise ValueError(
                    f"intent[{self._given[i]}].speed_m_s: value {V:g} is out of range; expected "
                    f"at most path length / ramp_s = {L:.6g} m / {r:g} s = {L / r:.6g} m/s "
                    f"(the ramps in and out cover speed * ramp_s of the {L:.6g} m path)"
                )
            return L / V + r
        return float(seg.get("duration_s", 0.0))

    # the plane normal of the mechanism (axis "normal")
    def _normal(self) -> np.ndarray:
        d = self.mechanism.to_dict()
        for key in ("normal", "plane_normal"):
            if key in d:
                return np.asarray(d[key], dtype=float)
        if hasattr(self.mechanism, "joints"):  # a serial chain: its first joint's axis
            return np.asarray(self.mechanism.joints[0].axis, dtype=float)
        # a mechanism on a shape: the side the hand is on at its home (against the stylus)
        return -np.asarray(self.mechanism.forward(self.mechanism.home), dtype=float)[:3, 2]

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
        # taken from the handle: the anchor's rate starts from 0, not from the jump between
        # where the anchor was left and the handle
        if self.trans_passive and self._prev_p is not None:
            self._prev_p = self._start_p.copy()
        if self.rot_passive and self._prev_R is not None:
            self._prev_R = self._start_R.copy()
        action = seg["action"]
        default_t = "passive" if action in ("twist",) else "hold"
        self.trans_passive = seg.get("translation", default_t) == "passive"
        self.rot_passive = seg.get("orientation", "hold") == "passive"
        # a pure wrench and a released hand: no impedance at all (and the next segment
        # starts from the handle)
        free = action in ("wrench", "release")
        if free:
            self.trans_passive = self.rot_passive = True
        self.damped = not free
        self.attached = action != "release"
        self.k_t = seg.get("stiffness", self.hand.stiffness)
        self.k_r = seg.get("rot_stiffness", self.hand.rot_stiffness)
        self._axis_vec = self._axis(seg, T_handle)
        if action == "follow" and "theta" in seg:
            self._path0 = self.mechanism.forward(np.array([float(seg["theta"][0])]))
        self.active = i

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
        columns PLAN_COLUMNS, for a stretch in which no segment starts after k0 (see
        `start_cycles`). T_handle is the handle's pose at cycle k0 (a segment starting there
        starts from it). A push given in handle axes is returned in handle axes with
        force_in_handle = 1: it turns with the handle."""
        t = np.arange(k0, k1) * self.T
        self._advance(t, k0, k1, T_handle)
        p, R, v_exact, w_exact = self._anchor(t)
        force, moment, in_handle = self._push(t)
        v, w = self._rates(p, R, v_exact, w_exact)
        self.p_a, self.R_a = p[-1].copy(), R[-1].copy()
        self._prev_p, self._prev_R = p[-1].copy(), R[-1].copy()
        return self._rows(p, R, v, w, force, moment, in_handle)

    def _advance(self, t: np.ndarray, k0: int, k1: int, T_handle: np.ndarray) -> None:
        """The segments that start by the stretch's first cycle started (from T_handle); a
        ValueError where one would start inside the stretch."""
        while (
            self.active + 1 < len(self.segments)
            and t[0] >= self.segments[self.active + 1]["start_s"] - 1e-12
        ):
            self._start(self.active + 1, T_handle)
        nxt = self.active + 1
        if nxt < len(self.segments) and len(t) > 1:
            if t[-1] >= self.segments[nxt]["start_s"] - 1e-12:
                raise ValueError(
                    f"Intent.plan: segment {nxt} starts inside cycles {k0}..{k1 - 1}; split the "
                    "plan at start_cycles()"
                )

    def _anchor(self, t: np.ndarray):
        """The anchor's poses p (m, 3), R (m, 3, 3) at times t, and its rates in closed form
        where the action has them (else None)."""
        m = len(t)
        p = np.broadcast_to(self.p_a, (m, 3)).copy()
        R = np.broadcast_to(self.R_a, (m, 3, 3)).copy()
        v_exact = w_exact = None
        if self.active < 0:
            return p, R, v_exact, w_exact
        seg = self.segments[self.active]
        dur = self.durations[self.active]
        tau = t - seg["start_s"]
        s = min_jerk_array(tau / dur) if dur > 0 else np.ones(m)
        action = seg["action"]
        p[:], R[:] = self._start_p, self._start_R
        if action == "follow":
            if seg.get("profile", "min_jerk") == "constant":
                p, R, v_exact = self._follow_constant(seg, tau)
            else:
                p, R = self._follow_batch(seg, s)
        elif action in ("twist", "resist"):
            R = rotations(self._axis_vec, np.radians(seg["angle_deg"]) * s) @ self._start_R
        elif action in ("sine", "chirp"):
            x, dx = self._oscillation(seg, tau, dur)
            n = self._axis_vec
            if "amplitude_m" in seg:
                p = self._start_p[None, :] + x[:, None] * n[None, :]
                v_exact = dx[:, None] * n[None, :]
            else:
                R = rotations(n, x) @ self._start_R
                w_exact = dx[:, None] * n[None, :]
        return p, R, v_exact, w_exact

    def _push(self, t: np.ndarray):
        """The pushed force and moment (m, 3) each at times t, ramped in and out, and whether
        they are in handle axes (1.0) or world axes (0.0)."""
        m = len(t)
        force, moment = np.zeros((m, 3)), np.zeros((m, 3))
        if self.active < 0:
            return force, moment, 0.0
        seg = self.segments[self.active]
        if "force" not in seg and "moment" not in seg:
            return force, moment, 0.0
        dur = self.durations[self.active]
        g, _ = ramp_envelope(t - seg["start_s"], dur, seg.get("ramp_s", 0.1))
        if "force" in seg:
            force = g[:, None] * np.asarray(seg["force"], dtype=float)[None, :]
        if "moment" in seg:
            moment = g[:, None] * np.asarray(seg["moment"], dtype=float)[None, :]
        return force, moment, 1.0 if seg.get("force_frame", "world") == "handle" else 0.0

    def _rates(self, p: np.ndarray, R: np.ndarray, v_exact, w_exact):
        """The anchor's rates: differences with the previous cycle's anchor (0 on the very
        first), or the closed form."""
        if self._prev_p is None:
            pp = np.vstack([p[:1], p[:-1]])
            Rp = np.concatenate([R[:1], R[:-1]])
        else:
            pp = np.vstack([self._prev_p[None], p[:-1]])
            Rp = np.concatenate([self._prev_R[None], R[:-1]])
        v = (p - pp) / self.T if v_exact is None else v_exact
        w = so3_log_batch(R @ np.transpose(Rp, (0, 2, 1))) / self.T if w_exact is None else w_exact
        return v, w

    def _rows(self, p, R, v, w, force, moment, in_handle: float) -> np.ndarray:
        """The plan's rows (PLAN_COLUMNS) from the anchor, its rates, the push and the
        state of the hand (passive groups, damping, attached)."""
        m = len(p)
        P = np.empty((m, len(PLAN_COLUMNS)))
        h, c = self.hand, PLAN_INDEX
        P[:, plan_slice("ax", 3)] = p
        P[:, plan_slice("R00", 9)] = R.reshape(m, 9)
        P[:, plan_slice("vx", 3)] = 0.0 if self.trans_passive else v
        P[:, plan_slice("wx", 3)] = 0.0 if self.rot_passive else w
        P[:, c["k_t"]] = 0.0 if self.trans_passive else float(self.k_t)
        P[:, c["b_t"]] = h.damping if self.damped else 0.0
        P[:, c["k_r"]] = 0.0 if self.rot_passive else float(self.k_r)
        P[:, c["b_r"]] = h.rot_damping if self.damped else 0.0
        P[:, plan_slice("fx", 3)] = force
        P[:, plan_slice("mx", 3)] = moment
        P[:, c["force_in_handle"]] = in_handle
        P[:, c["hand_attached"]] = 1.0 if self.attached else 0.0
        P[:, c["segment"]] = self.active
        return P

    def _oscillation(self, seg: dict, tau: np.ndarray, dur: float):
        """(x, dx/dt) of a sine or chirp segment at its times tau: the displacement [m] or
        angle [rad] about the start, amplitude ramped in and out over ramp_s."""
        g, dg = ramp_envelope(tau, dur, seg.get("ramp_s", 0.1))
        if seg["action"] == "sine":
            f = float(seg["frequency_hz"])
            phase, rate = 2.0 * math.pi * f * tau, np.full(tau.shape, 2.0 * math.pi * f)
        else:  # linear chirp from f0 to f1 over the duration
            f0, f1 = float(seg["f0_hz"]), float(seg["f1_hz"])
            k = (f1 - f0) / dur
            phase = 2.0 * math.pi * (f0 * tau + 0.5 * k * tau * tau)
            rate = 2.0 * math.pi * (f0 + k * tau)
        if "amplitude_m" in seg:
            a = float(seg["amplitude_m"])
        else:
            a = math.radians(seg["amplitude_deg"])
        sn, cs = np.sin(phase), np.cos(phase)
        return a * g * sn, a * (dg * sn + g * rate * cs)

    def _follow_constant(self, seg: dict, tau: np.ndarray):
        """Anchor (p, R) and its exact velocity along the path at constant speed (ramped)."""
        i = self.active
        L = self._path_length(i, seg)
        d, speed = constant_speed_distance(tau, L, float(seg["speed_m_s"]), seg.get("ramp_s", 0.1))
        m = len(tau)
        if "theta" in seg:
            arc = self._arcs[i]
            th = arc.theta_at(d)
            p, R = self._follow_theta(seg, th)
            # the unit tangent the way the anchor goes (theta may decrease along the path)
            tangent = arc.sign * arc.dp(th)
            tangent /= np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)[:, None]
        else:
            p, R = self._follow_batch(seg, d / L)
            pts = np.vstack([np.zeros(3), np.asarray(seg["offsets"], dtype=float)])
            seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            cum = np.cumsum(seglen)
            k = np.minimum(np.searchsorted(cum, d, side="right"), len(seglen) - 1)
            # the piece the anchor is on (a zero-length piece is never on: skip ahead)
            dirs = np.diff(pts, axis=0) / np.where(seglen > 0, seglen, 1.0)[:, None]
            tangent = dirs[k]
            for j in np.flatnonzero(seglen[k] == 0):
                nz = np.flatnonzero(seglen[k[j]:] > 0)
                tangent[j] = dirs[k[j] + nz[0]] if len(nz) else 0.0
        v = speed[:, None] * tangent
        assert v.shape == (m, 3)
        return p, R, v

    def _follow_theta(self, seg: dict, th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Anchor along the mechanism's path at its joint values th (the path moved to start
        at the segment's start)."""
        m = len(th)
        p = np.broadcast_to(self._start_p, (m, 3)).copy()
        R = np.broadcast_to(self._start_R, (m, 3, 3)).copy()
        T0 = self._path0
        Ts = self.mechanism.forward_many(np.asarray(th, dtype=float)[:, None])
        p += Ts[:, :3, 3] - T0[:3, 3]
        if seg.get("orientation", "hold") == "path":
            R = Ts[:, :3, :3] @ (T0[:3, :3].T @ self._start_R)
        return p, R

    def _follow_batch(self, seg: dict, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = len(s)
        p = np.broadcast_to(self._start_p, (m, 3)).copy()
        R = np.broadcast_to(self._start_R, (m, 3, 3)).copy()
        if "theta" in seg:
            a, b = seg["theta"]
            return self._follow_theta(seg, a + s * (b - a))
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
