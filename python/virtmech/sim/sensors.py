"""The device's sensors as a real driver sees them: encoder quantisation, optional noise,
delay and dropouts, and a velocity estimate from quantised positions.

Per control cycle (all joints alike; the Omni's gimbal is read the same way, a
simplification: real gimbals use potentiometers):

1. q_noisy = q_true + N(0, noise_rad²)                (optional)
2. q_counts = round(q_noisy / step), step = 2 pi / counts_per_rev (0: no quantisation)
3. dropout: with probability `dropout_probability` the new sample is lost and the driver
   keeps its previous one (held sample)
4. delay: the controller receives the sample from `delay_cycles` cycles ago
5. velocity: dq = low-pass( (q_k - q_{k-1}) / T ) with a first-order filter of cut-off
   `velocity_cutoff_hz` (alpha = T / (T + 1 / (2 pi f_c))) on the received positions,
   the simple filtered difference most drivers use.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np


@dataclass
class SensorSettings:
    counts_per_rev: int = 15000  #: encoder counts per joint revolution; 0: ideal
    noise_rad: float = 0.0  #: standard deviation of additive position noise [rad]
    delay_cycles: int = 0  #: transport delay [control cycles]
    dropout_probability: float = 0.0  #: chance that a sample is lost (previous one held)
    velocity_cutoff_hz: float = 100.0  #: cut-off of the velocity filter [Hz]

    def to_dict(self) -> dict:
        return asdict(self)


class Sensors:
    """Stateful sensor model; `read` once per control cycle."""

    def __init__(self, settings: SensorSettings, n: int, period_s: float, rng: np.random.Generator):
        self.s = settings
        self.n = n
        self.T = period_s
        self.rng = rng
        self.step = 2.0 * math.pi / settings.counts_per_rev if settings.counts_per_rev > 0 else 0.0
        fc = settings.velocity_cutoff_hz
        self.alpha = period_s / (period_s + 1.0 / (2.0 * math.pi * fc)) if fc > 0 else 1.0
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
