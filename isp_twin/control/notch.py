"""Discrete notch filter of the rate loop (paper Sect. 4.1: "the notch filter").

The paper gives no notch parameters; it is there to keep the loop off the
gimbal's structural resonance. Here it is the standard second-order notch

    H(s) = (s^2 + 2*zeta_z*w0*s + w0^2) / (s^2 + 2*zeta_p*w0*s + w0^2)

with ``zeta_p = 1/(2*q)`` (q: quality factor, centre / -3 dB width) and
``zeta_z = depth * zeta_p`` (depth: gain at the centre, 0 for a full notch),
discretised by the bilinear transform with the centre frequency pre-warped,
so the digital filter has exactly gain `depth` at `freq_hz` and unit gain at
DC and Nyquist.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["NotchFilter", "notch_coefficients"]


def notch_coefficients(freq_hz: float, q: float, depth: float, dt: float):
    """Biquad coefficients (b0, b1, b2, a1, a2) of the notch, a0 normalised to 1.

    Raises:
        ValueError: centre not strictly between 0 and Nyquist, q <= 0, depth
            outside [0, 1].
    """
    nyquist = 0.5 / dt
    if not 0.0 < freq_hz < nyquist:
        raise ValueError(f"notch freq_hz must lie in (0, {nyquist:g}) (Nyquist), got {freq_hz}")
    if not q > 0.0:
        raise ValueError(f"notch q must be > 0, got {q}")
    if not 0.0 <= depth <= 1.0:
        raise ValueError(f"notch depth must lie in [0, 1], got {depth}")
    w0 = 2.0 * math.pi * freq_hz
    k = w0 / math.tan(w0 * dt / 2.0)  # pre-warped bilinear constant
    zp = 1.0 / (2.0 * q)
    zz = depth * zp
    a0 = k * k + 2 * zp * w0 * k + w0 * w0
    b0 = (k * k + 2 * zz * w0 * k + w0 * w0) / a0
    b1 = (2 * w0 * w0 - 2 * k * k) / a0
    b2 = (k * k - 2 * zz * w0 * k + w0 * w0) / a0
    a1 = b1
    a2 = (k * k - 2 * zp * w0 * k + w0 * w0) / a0
    return b0, b1, b2, a1, a2


class NotchFilter:
    """Direct-form II transposed biquad notch, scalar per sample.

    Args:
        freq_hz: centre frequency [Hz], below Nyquist.
        q: quality factor (centre / bandwidth).
        depth: gain at the centre (0 = full notch).
        dt: sample period [s].
    """

    def __init__(self, freq_hz: float, q: float, depth: float, dt: float):
        self.freq_hz, self.q, self.depth, self.dt = freq_hz, q, depth, dt
        self.b0, self.b1, self.b2, self.a1, self.a2 = notch_coefficients(freq_hz, q, depth, dt)
        self.reset()

    def reset(self) -> None:
        """Zero the filter state."""
        self.z1 = 0.0
        self.z2 = 0.0

    def step(self, x: float) -> float:
        """Filter one sample."""
        y = self.b0 * x + self.z1
        self.z1 = self.b1 * x - self.a1 * y + self.z2
        self.z2 = self.b2 * x - self.a2 * y
        return y

    def gain(self, freq_hz) -> np.ndarray:
        """Magnitude of the frequency response at `freq_hz` (array ok)."""
        z = np.exp(1j * 2 * np.pi * np.asarray(freq_hz, dtype=float) * self.dt)
        num = self.b0 + self.b1 / z + self.b2 / z**2
        den = 1.0 + self.a1 / z + self.a2 / z**2
        return np.abs(num / den)
