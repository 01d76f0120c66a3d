"""The sensor model of virtmech.sim.sensors written out in NumPy, one cycle at a time: the
independent reference the C++ simulation loop's sensing is compared with
(tests/python/test_sim_engine.py, reference.sim_loop)."""

from __future__ import annotations

from collections import deque

import numpy as np

from virtmech.sim.sensors import SensorSettings


class Sensors:
    """Stateful sensor model; `read` once per control cycle."""

    def __init__(self, settings: SensorSettings, n: int, period_s: float, rng: np.random.Generator):
        self.s = settings
        self.n = n
        self.T = period_s
        self.rng = rng
        self.step = settings.quantum_rad
        self.alpha = settings.velocity_alpha(period_s)
        self._held: np.ndarray | None = None
        self._queue: deque[np.ndarray] = deque()
        self._prev: np.ndarray | None = None
        self._dq = np.zeros(n)

    def quantise(self, q: np.ndarray) -> np.ndarray:
        if self.step == 0.0:
            return q.copy()
        return np.round(q / self.step) * self.step

    def read(
        self, q_true: np.ndarray, noise: np.ndarray | None = None, dropout: bool | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Measured (q, dq) for this cycle from the true joint values. `noise` (n,) and
        `dropout` are this cycle's draws when given (the simulation draws them ahead, a
        stretch of cycles at a time); otherwise they are drawn here from `rng`."""
        q = q_true
        if noise is not None:
            q = q + noise
        elif self.s.noise_rad > 0.0:
            q = q + self.rng.normal(0.0, self.s.noise_rad, self.n)
        sample = self.quantise(q)
        if self._held is not None:
            if dropout is None and self.s.dropout_probability > 0.0:
                dropout = self.rng.random() < self.s.dropout_probability
            if dropout:
                sample = self._held
        self._held = sample
        self._queue.append(sample)
        while len(self._queue) > self.s.delay_cycles + 1:
            self._queue.popleft()
        received = self._queue[0]
        if self._prev is not None:
            raw = (received - self._prev) / self.T
            self._dq = self._dq + self.alpha * (raw - self._dq)
        self._prev = received
        return received.copy(), self._dq.copy()
