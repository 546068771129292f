"""The rate gyro of an inner gimbal (the paper's "flexible gyro").

The paper does not describe its gyro beyond "flexible gyro ... in deg/sec".
A dynamically tuned (flexible) gyro is modelled here as:

1. first-order low-pass of the true inertial rate omega_1, bandwidth
   `bandwidth_hz` (rebalance loop bandwidth);
2. plus white noise of standard deviation `noise_deg_s` per sample;
3. sampled every `sample_every` controller samples and held in between;
4. quantised to whole counts of ``1/scale_count_per_deg_s`` deg/s: the
   controller sees counts, and the paper's PI gains are digits per count.

The noise comes from a `numpy.random.Generator` owned by the gyro (seeded by
the scenario seed), so the same seed gives identical readings.
"""

from __future__ import annotations

import math

import numpy as np

from isp_twin.units import DEG

__all__ = ["Gyro"]


class Gyro:
    """Rate gyro: low-pass, noise, sample-and-hold, quantisation.

    Args:
        scale_count_per_deg_s: counts per deg/s (the gyro/ADC scale).
        noise_deg_s: white noise standard deviation per sample [deg/s].
        bandwidth_hz: -3 dB bandwidth of the first-order response [Hz]
            (math.inf: none).
        sample_every: a new reading every this many controller samples.
        dt: controller sample period [s].
        rng: noise source.
    """

    def __init__(
        self,
        scale_count_per_deg_s: float,
        noise_deg_s: float,
        bandwidth_hz: float,
        sample_every: int,
        dt: float,
        rng: np.random.Generator,
    ):
        if not scale_count_per_deg_s > 0:
            raise ValueError(f"gyro scale must be > 0, got {scale_count_per_deg_s}")
        if noise_deg_s < 0:
            raise ValueError(f"gyro noise must be >= 0, got {noise_deg_s}")
        if not bandwidth_hz > 0:
            raise ValueError(f"gyro bandwidth must be > 0, got {bandwidth_hz}")
        if sample_every < 1:
            raise ValueError(f"gyro sample_every must be >= 1, got {sample_every}")
        self.scale = scale_count_per_deg_s / DEG  # counts per rad/s
        self.noise = noise_deg_s * DEG
        # Exact discretisation of the first-order lag.
        self.smoothing = 1.0 - math.exp(-2 * math.pi * bandwidth_hz * dt)
        self.sample_every = int(sample_every)
        self.rng = rng
        self.reset()

    def reset(self) -> None:
        """Start from rest."""
        self.filtered = 0.0
        self.count = 0.0
        self.phase = 0

    def read(self, omega: float) -> float:
        """One controller sample: the reading [counts] for the true rate [rad/s]."""
        self.filtered += self.smoothing * (omega - self.filtered)
        if self.phase == 0:
            noisy = self.filtered + (self.noise * self.rng.standard_normal() if self.noise else 0.0)
            self.count = float(round(noisy * self.scale))
        self.phase = (self.phase + 1) % self.sample_every
        return self.count

    def to_rate(self, counts: float) -> float:
        """Counts back to rad/s (for recording)."""
        return counts / self.scale
