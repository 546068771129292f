"""A lightly damped structural mode between the motor and the gyro.

The gyro sits on the payload, which flexes against the driven axis: the
payload deflection x obeys ``x'' + 2*zeta*wn*x' + wn^2*x = -coupling * a``
(a = the axis's angular acceleration) and the gyro reads ``rate + x'``.
The mode rings after every change of acceleration (breakaway, steps).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


def _discretize(freq_hz, damping_ratio, coupling, dt):
    """Zero-order-hold transition matrices, shapes (..., 2, 2) and (..., 2).

    Closed form of expm(A*dt) for the 2x2 mode (Sylvester's formula with the
    two eigenvalues) and ``Gamma = A^-1 (Phi - I) B``, vectorized over sets.
    """
    freq, zeta, gain = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (freq_hz, damping_ratio, coupling))
    )
    wn = 2.0 * np.pi * freq
    # Repeated roots (zeta = 1) make the formula 0/0: nudge them apart.
    zeta = np.where(np.abs(zeta - 1.0) < 1e-6, 1.0 + 1e-6, zeta)
    root = np.sqrt((zeta * zeta - 1.0).astype(complex))
    l1 = wn * (-zeta + root)
    l2 = wn * (-zeta - root)
    e1, e2 = np.exp(l1 * dt), np.exp(l2 * dt)
    c0 = ((l1 * e2 - l2 * e1) / (l1 - l2)).real
    c1 = ((e1 - e2) / (l1 - l2)).real
    a = np.zeros(freq.shape + (2, 2))
    a[..., 0, 1] = 1.0
    a[..., 1, 0] = -wn * wn
    a[..., 1, 1] = -2.0 * zeta * wn
    phi = c0[..., None, None] * np.eye(2) + c1[..., None, None] * a
    # Gamma = A^-1 (Phi - I) B with B = (0, -coupling); det A = wn^2.
    m = phi - np.eye(2)
    inv = np.zeros_like(a)
    inv[..., 0, 0] = a[..., 1, 1]
    inv[..., 0, 1] = -1.0
    inv[..., 1, 0] = wn * wn
    inv = inv / (wn * wn)[..., None, None]
    gamma = np.einsum("...ij,...j->...i", inv @ m, np.stack([np.zeros_like(gain), -gain], axis=-1))
    return phi, gamma


class Resonance(Effect):
    """Gyro reading ``rate + x'`` of a payload mode excited by the axis acceleration.

    Parameters: ``freq_hz`` [Hz] (undamped natural frequency),
    ``damping_ratio`` [1], ``coupling`` [1] (payload deflection per axis
    deflection at low frequency).
    """

    name = "resonance"
    param_names = ("freq_hz", "damping_ratio", "coupling")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"freq_hz": 100.0, "damping_ratio": 0.1, "coupling": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "freq_hz": (1.0, 400.0),
        "damping_ratio": (0.002, 0.5),
        "coupling": (-2.0, 2.0),
    }

    def reset(self) -> None:
        self._phi, self._gamma = _discretize(
            self.params["freq_hz"], self.params["damping_ratio"], self.params["coupling"], self.dt
        )
        self._state = np.zeros(self._gamma.shape)
        self._last = None

    def measure(self, rate):
        rate = np.asarray(rate, dtype=float)
        accel = np.zeros_like(rate) if self._last is None else (rate - self._last) / self.dt
        self._last = rate
        s = self._state
        self._state = np.einsum("...ij,...j->...i", self._phi, s) + self._gamma * accel[..., None]
        return rate + self._state[..., 1]

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """The two largest peaks of the residual's spectrum above 5 Hz, with a
        grid of damping ratios and couplings."""
        r = ctx.residual - ctx.residual.mean()
        spec = np.abs(np.fft.rfft(r * np.hanning(r.size)))
        freqs = np.fft.rfftfreq(r.size, ctx.dt)
        lo, hi = max(5.0, cls.bounds["freq_hz"][0]), min(cls.bounds["freq_hz"][1], 0.45 / ctx.dt)
        band = np.flatnonzero((freqs >= lo) & (freqs <= hi))
        if band.size == 0:
            return [{"freq_hz": 50.0, "damping_ratio": 0.05, "coupling": 0.1}]
        # Smooth over 1 Hz so a single noise bin does not win.
        width = max(1, round(1.0 / (freqs[1] - freqs[0])))
        smooth = np.convolve(spec, np.ones(width) / width, mode="same")
        peaks = []
        for i in band[np.argsort(smooth[band])[::-1]]:
            if all(abs(freqs[i] - f) > 3.0 for f in peaks):
                peaks.append(float(freqs[i]))
            if len(peaks) == 2:
                break
        return [
            {"freq_hz": f, "damping_ratio": z, "coupling": c}
            for f in peaks
            for z in (0.02, 0.08)
            for c in (-0.3, -0.05, 0.05, 0.3)
        ]
