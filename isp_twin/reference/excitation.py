"""Open-loop commands for the reference axis [digits].

* ``cosine``: the paper's Eq. 7 form, ``A cos(2 pi f t) + offset``;
* ``multisine``: a sum of sines at log-spaced frequencies with random phases,
  scaled to a peak;
* ``steps``: random levels held for random durations (signs alternate so the
  angle does not run away).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isp_twin.errors import ParameterError

__all__ = ["KINDS", "Excitation"]

#: The excitation kinds.
KINDS: tuple[str, ...] = ("cosine", "multisine", "steps")


@dataclass(frozen=True)
class Excitation:
    """One open-loop run's command and start.

    Attributes:
        kind: one of `KINDS`.
        amplitude_digits: cosine amplitude, multisine/steps peak [digits].
        freq_hz: cosine frequency; multisine lowest frequency; steps: 1 / mean hold [Hz].
        offset_digits: constant added to the command [digits].
        initial_angle_rad: angle at t = 0 [rad].
        n_samples: samples.
        dt: sample period [s].
        seed: phases (multisine) and levels/holds (steps).
        components: multisine: number of sines (spanning freq_hz to 6 freq_hz).
    """

    kind: str
    amplitude_digits: float
    freq_hz: float
    offset_digits: float = 0.0
    initial_angle_rad: float = 0.0
    n_samples: int = 6000
    dt: float = 1e-3
    seed: int = 0
    components: int = 6

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ParameterError(
                f"excitation kind '{self.kind}': expected one of {', '.join(KINDS)}"
            )
        if self.n_samples < 1 or self.dt <= 0.0 or self.freq_hz <= 0.0:
            raise ParameterError("excitation: needs n_samples >= 1, dt > 0 and freq_hz > 0")

    def command(self) -> np.ndarray:
        """u [digits], shape (n_samples,)."""
        t = np.arange(self.n_samples) * self.dt
        if self.kind == "cosine":
            u = self.amplitude_digits * np.cos(2.0 * math.pi * self.freq_hz * t)
        elif self.kind == "multisine":
            rng = np.random.default_rng(self.seed)
            freqs = self.freq_hz * np.geomspace(1.0, 6.0, self.components)
            phases = rng.uniform(0.0, 2.0 * math.pi, self.components)
            u = np.sin(2.0 * math.pi * np.outer(t, freqs) + phases).sum(axis=1)
            u *= self.amplitude_digits / np.max(np.abs(u))
        else:
            rng = np.random.default_rng(self.seed)
            u = np.empty(self.n_samples)
            k, sign = 0, 1.0 if rng.random() < 0.5 else -1.0
            mean_hold = max(1, round(1.0 / (self.freq_hz * self.dt)))
            while k < self.n_samples:
                hold = int(rng.integers(max(1, mean_hold // 2), 3 * mean_hold // 2 + 1))
                u[k : k + hold] = sign * rng.uniform(0.3, 1.0) * self.amplitude_digits
                k += hold
                sign = -sign
        return u + self.offset_digits

    def describe(self) -> dict:
        """Plain-data description (for truth.yaml)."""
        return {
            "kind": self.kind,
            "amplitude_digits": self.amplitude_digits,
            "freq_hz": self.freq_hz,
            "offset_digits": self.offset_digits,
            "initial_angle_deg": math.degrees(self.initial_angle_rad),
            "n_samples": self.n_samples,
            "dt_s": self.dt,
            "seed": self.seed,
            **({"components": self.components} if self.kind == "multisine" else {}),
        }
