"""The passivity layer's energy tank written out from its definition (docs/theory.md, 8), in
NumPy, for the tests to replay a controller's cycles against:

    q~_k = median(q_{k-1}, q_k, q_{k+1})
    p_k  = clamp(p_{k-1}, q~_k - h, q~_k + h)     (h: half an encoder count)
    W_k  = sum_i m_i (p_k,i - p_{k-1},i)           booked at cycle k + 1
    R_k  = max(0, sum_i m'_i (q~_k,i - p_k,i))    the play's pending motor work

where m_i is the mean of joint i's torques tau_{j-1,i} over the intervals since its p last
moved, up to and including [k - 1, k] (a running mean of the last WINDOW where it stood
still longer), and m'_i that mean with tau_k,i as well
    E_0  = min(V_0, E_start) at the start, 0 after a fault
    E_{k+1} = min(E_k - W_k, V_{k+1} + E_max)

(the first interval booked is [0, 1], at cycle 2; at a restart q_{-1} = q_0, p_0 = q_0),
and the range term's factor: its share of the wrench limits r_k follows the range term's own
share l_k = min(1, |f_r| / F_max, |m_r| / M_max) while the aim is 1, else moves toward
a_k l_k by at most Delta = T / t_fade a cycle (never above l_k), with

    a_k = clamp(1 + (E_k - R_k - P_k T ceil(r_{k-1} / Delta) + B) / E_fade, 0, 1),
    P_k = max(0, s_{k-1} f_r . v_R)         (the range term's power, looked ahead)

and the factor on the range term is r_k / (its share before the limit).
"""

from __future__ import annotations

import math

import numpy as np

WINDOW = 100  # the most intervals a joint's booked torque is averaged over


class Tank:
    """One run of the tank from a restart: `cycle(q, stored)` before the cycle's torque
    is known returns the level the controller reports; `hold(tau)` after it."""

    def __init__(self, play, max_energy: float, springs: bool = True,
                 start_energy: float = 0.001):
        self.h = np.asarray(play, dtype=float)
        self.e_max = max_energy
        self.e_start = start_energy
        self.springs = springs  # the start (True) or a restart after a fault (False)
        self.cycles = 0
        self.level = 0.0
        self.capped = False  # the cap lowered the level this cycle
        self.pending = 0.0  # R_k

    def cycle(self, q, stored: float) -> float:
        q = np.asarray(q, dtype=float)
        work = 0.0
        self.pending = 0.0
        if self.cycles == 0:
            self.q_before = self.q_last = self.p = q.copy()
            self.sums, self.counts = np.zeros_like(q), np.zeros_like(q)
        elif self.cycles >= 2:
            # each joint's torque since its p last moved: a mean over at most WINDOW intervals
            full = self.counts >= WINDOW
            self.sums = np.where(full, self.sums * (WINDOW - 1) / WINDOW, self.sums)
            self.counts = np.where(full, self.counts, self.counts + 1)
            self.sums = self.sums + self.tau_before
            settled = np.median(np.stack([self.q_before, self.q_last, q]), axis=0)
            p = np.clip(self.p, settled - self.h, settled + self.h)
            moved = p != self.p
            work = float(np.sum(np.where(moved, self.sums / self.counts * (p - self.p), 0.0)))
            self.sums = np.where(moved, 0.0, self.sums)
            self.counts = np.where(moved, 0.0, self.counts)
            mean = (self.sums + self.tau_last) / (self.counts + 1)
            self.pending = max(0.0, float(mean @ (settled - p)))
            self.p = p
        if self.cycles > 0:
            self.q_before, self.q_last = self.q_last, q.copy()
        if self.cycles == 0:
            self.level = min(stored, self.e_start) if self.springs else 0.0
        else:
            self.level -= work
        self.capped = self.level > stored + self.e_max
        self.level = min(self.level, stored + self.e_max)
        return self.level

    def hold(self, tau) -> None:
        self.tau_before = getattr(self, "tau_last", None)
        self.tau_last = np.asarray(tau, dtype=float).copy()
        self.cycles += 1


class Factor:
    """The range term's factor from the start: `cycle(level, wrench_range, twist, pending)`
    returns (passivity_scale, wrench_passivity) as the controller reports them."""

    def __init__(self, model: dict):
        self.F, self.M = model["max_force"], model["max_torque"]
        self.step = model["passivity_fade_step"]
        self.fade, self.budget = model["passivity_fade_j"], model["passivity_budget_j"]
        self.T = model["period_s"]
        self.rendered, self.factor, self.following = 1.0, 1.0, True

    def cycle(self, level: float, wrench_range, twist, pending: float = 0.0):
        w = np.asarray(wrench_range, dtype=float)
        f, m = np.linalg.norm(w[:3]), np.linalg.norm(w[3:])
        share = max(f / self.F if f > 0 else 0.0, m / self.M if m > 0 else 0.0)
        limited = min(share, 1.0)
        power = max(0.0, self.factor * float(w @ np.asarray(twist, dtype=float)))
        ahead = power * self.T * math.ceil(self.rendered / self.step)
        aim = min(max(1.0 + (level - pending - ahead + self.budget) / self.fade, 0.0), 1.0)
        if self.following and aim >= 1.0:
            self.rendered = limited
        else:
            move = min(max(aim * limited - self.rendered, -self.step), self.step)
            self.rendered = min(max(self.rendered + move, 0.0), limited)
            self.following = aim >= 1.0 and self.rendered >= limited
        if share > 0.0:
            self.factor = self.rendered / share
        elif aim >= 1.0:
            self.factor = 1.0
        scale = 1.0 if self.following else (self.rendered / limited if limited > 0 else 0.0)
        return scale, (self.factor - 1.0) * w
