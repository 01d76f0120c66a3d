"""The passivity layer's energy tank written out from its definition (docs/theory.md, 8), in
NumPy, for the tests to replay a controller's cycles against:

    q~_k = median(q_{k-1}, q_k, q_{k+1})
    p_k  = clamp(p_{k-1} + dq_k T, q~_k - h, q~_k + h)
    W_k  = tau_{k-1} . (p_k - p_{k-1})             booked at cycle k + 1
    E_0  = min(V_0, E_max);  E_{k+1} = min(E_k - W_k, V_{k+1} + E_max)

(the first interval booked is [0, 1], at cycle 2; at a restart q_{-1} = q_0, p_0 = q_0).
"""

from __future__ import annotations

import numpy as np


class Tank:
    """One run of the tank from a restart: `cycle(q, dq, stored)` before the cycle's torque
    is known returns the level the controller reports; `hold(tau)` after it."""

    def __init__(self, play, period_s: float, max_energy: float):
        self.h = np.asarray(play, dtype=float)
        self.T = period_s
        self.e_max = max_energy
        self.cycles = 0
        self.level = 0.0
        self.capped = False  # the cap lowered the level this cycle

    def cycle(self, q, dq, stored: float) -> float:
        q, dq = np.asarray(q, dtype=float), np.asarray(dq, dtype=float)
        work = 0.0
        if self.cycles == 0:
            self.q_before = self.q_last = self.p = q.copy()
        elif self.cycles >= 2:
            settled = np.median(np.stack([self.q_before, self.q_last, q]), axis=0)
            p = np.clip(self.p + self.dq_last * self.T, settled - self.h, settled + self.h)
            work = float(self.tau_before @ (p - self.p))
            self.p = p
        if self.cycles > 0:
            self.q_before, self.q_last = self.q_last, q.copy()
        self.dq_last = dq.copy()
        if self.cycles == 0:
            self.level = min(stored, self.e_max)
        else:
            self.level -= work
        self.capped = self.level > stored + self.e_max
        self.level = min(self.level, stored + self.e_max)
        return self.level

    def hold(self, tau) -> None:
        self.tau_before = getattr(self, "tau_last", None)
        self.tau_last = np.asarray(tau, dtype=float).copy()
        self.cycles += 1
