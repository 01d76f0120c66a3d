"""The device's sensors as a real driver sees them (their settings; the loop that applies
them is the C++ simulation loop, virtmech.sim.inner): encoder quantisation, optional noise,
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
from dataclasses import asdict, dataclass


@dataclass
class SensorSettings:
    counts_per_rev: int = 15000  #: encoder counts per joint revolution; 0: ideal
    noise_rad: float = 0.0  #: standard deviation of additive position noise [rad]
    delay_cycles: int = 0  #: transport delay [control cycles]
    dropout_probability: float = 0.0  #: chance that a sample is lost (previous one held)
    velocity_cutoff_hz: float = 100.0  #: cut-off of the velocity filter [Hz]

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def quantum_rad(self) -> float:
        """The encoder's step [rad]; 0: no quantisation."""
        return 2.0 * math.pi / self.counts_per_rev if self.counts_per_rev > 0 else 0.0

    def velocity_alpha(self, period_s: float) -> float:
        """The velocity filter's gain per cycle, alpha = T / (T + 1 / (2 pi f_c)) (1: no
        filter)."""
        fc = self.velocity_cutoff_hz
        return period_s / (period_s + 1.0 / (2.0 * math.pi * fc)) if fc > 0 else 1.0
