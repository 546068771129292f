"""A flexible payload: a lightly damped mode between the motor and the gyro.

The gyro sits on the payload, which flexes against the driven axis. In the
axis's centre-of-mass rate w the payload coordinate y obeys
``y'' + 2*zeta*wn*y' + wn^2*y = -w'`` and the gyro reads ``w + coupling*y'``;
the mode rings after every change of acceleration (breakaway, steps). With
``payload_fraction`` f = J2/J > 0 it is a two-mass system: friction, the
stick test and the resolver act on the motor side's rate ``w - r*y'``
(r = f/(1 - f)), and a motor side held by stiction lets the payload ring at
the clamped frequency ``wn/sqrt(1 + r)``; coupling 1 is a gyro on the
payload's inertia (the reference simulator's payload, docs/reference_simulator.md).
f = 0 is the gyro-only mode of parameter files written before f existed
(docs/diagnosis.md, "Stop 18 R").
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.ndimage import maximum_filter1d

from isp_twin.errors import ParameterError
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


#: How far the deflection's largest peak must stand above its band's median
#: to be taken as the mode (`Resonance._deflection_peak`): at most 3.1 on
#: reference axes without a payload (clean seeds 0-5, LuGre and cogging 0-2,
#: sensor bias 0-1), 5.7-170 on the strong payloads of resonance seeds 30-43;
#: the weak ones (2.5-3.2) are left to the residual's peaks.
DEFLECTION_PROMINENCE = 5.0

#: A peak of the deflection rate where the resolver's quantization alone
#: (`RunStack.deflection`) reaches this share of its smoothed amplitude is
#: the quantization's line, not a mode (`Resonance.deflection_peak`) [1].
#: Saturation seed 4's plateau: 0.92 at its false 383 Hz peak, 0.65-1.0 at
#: the next four; 0.00-0.24 at the modes of resonance seeds 30-33 and their
#: side peaks (a peak 5 times above a floor the quantization makes reads
#: about 0.2).
QUANTIZATION_SHARE = 0.5
#: How far from a peak the rebuilt quantization's spectrum is read, at its
#: largest [Hz]: the distance at which two peaks are told apart
#: (`Resonance._spectrum_peaks`).
LINE_REACH_HZ = 3.0


class Resonance(Effect):
    """A payload mode read by the gyro, two-mass where ``payload_fraction`` > 0.

    Parameters: ``freq_hz`` [Hz] (undamped frequency of the free mode),
    ``damping_ratio`` [1], ``coupling`` [1] (payload deflection rate the gyro
    sees per y'; 1 for a gyro on the payload), ``payload_fraction`` [1]
    (J2/J, 0 <= f < 1; 0 when a parameter file leaves it out).

    The sub-stepped model (m > 1) integrates the mode in its sub-steps
    (`in_substeps`, `substep_columns`, `isp_twin.model.substep_model`);
    Eq. 6, m = 1 and the twin use the hooks, which hold the gyro-only form
    (friction on w): there the payload fraction has no effect
    (`substep_only`).
    """

    name = "resonance"
    param_names = ("freq_hz", "damping_ratio", "coupling", "payload_fraction")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {
        "freq_hz": 100.0,
        "damping_ratio": 0.1,
        "coupling": 0.0,
        "payload_fraction": 0.0,
    }
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "freq_hz": (1.0, 400.0),
        "damping_ratio": (0.002, 0.5),
        "coupling": (-2.0, 2.0),
        "payload_fraction": (0.0, 0.9),
    }
    defaults: ClassVar[dict[str, float]] = {"payload_fraction": 0.0}
    substep_only: ClassVar[tuple[str, ...]] = ("payload_fraction",)
    in_substeps = True
    fine_slopes = True

    @classmethod
    def check_params(cls, params) -> None:
        """`Effect.check_params`, and a payload fraction in [0, 1) (J2 < J).

        Raises:
            ParameterError: a missing or unknown parameter, or a fraction
                outside [0, 1).
        """
        super().check_params(params)
        if "payload_fraction" in params:
            f = np.asarray(params["payload_fraction"], dtype=float)
            ok = (f >= 0.0) & (f < 1.0)
            if not np.all(ok):
                bad = float(f[~ok].flat[0]) if f.ndim else float(f)
                raise ParameterError(
                    f"effect 'resonance': payload_fraction must be in [0, 1) (J2/J), got {bad:g}"
                )

    def fusion_gain(self) -> np.ndarray:
        """`Effect.fusion_gain`: the gyro reads ``w1 + (r + c) y'``,
        so its integral, which the fused angle follows, is the motor side's
        angle plus (r + c) y; the fusion's moving average keeps only the
        resolver's part of the slow deflection, the mode's quasi-static
        ``y = -w'/wn^2`` under the window's mean acceleration (the ringing
        averages out). The model takes (r + c) y off the fused angle
        (`isp_twin.model.substep_model`), so this is added back: without it
        a two-mass axis accelerating through 0 changed sides early by
        ``(r + c) w'/wn^2`` (0.01 deg at 17 Hz, docs/diagnosis.md "Stop 30")."""
        f = np.asarray(self.params["payload_fraction"], dtype=float)
        k = f / (1.0 - f) + np.asarray(self.params["coupling"], dtype=float)
        wn = 2.0 * np.pi * np.asarray(self.params["freq_hz"], dtype=float)
        return -k / (wn * wn)

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

    def substep_columns(self, dt: float, m: int) -> dict[str, object]:
        """J2/J1, the gyro's coupling, the spring's pull on the motor side and
        the mode's sub-step transitions, free and clamped
        (`isp_twin.model.substep_model.STATE_COLUMNS`)."""
        f = np.asarray(self.params["payload_fraction"], dtype=float)
        r = f / (1.0 - f)
        zeta = np.asarray(self.params["damping_ratio"], dtype=float)
        wn = 2.0 * np.pi * np.asarray(self.params["freq_hz"], dtype=float)
        phi, gamma = _discretize(self.params["freq_hz"], zeta, 1.0, dt / m)
        # Motor side clamped: (1 + r) y'' + 2 zeta wn y' + wn^2 y = 0.
        stretch = np.sqrt(1.0 + r)
        clamped, _ = _discretize(self.params["freq_hz"] / stretch, zeta / stretch, 0.0, dt / m)
        cols = {
            "payload_ratio": r,
            # Spring and damper torque on the motor side / J, per y and per y'.
            "spring_y": r / (1.0 + r) * wn * wn,
            "spring_yd": r / (1.0 + r) * 2.0 * zeta * wn,
            "free_g0": gamma[..., 0],
            "free_g1": gamma[..., 1],
            "gyro_coupling": np.asarray(self.params["coupling"], dtype=float),
        }
        for a, b in ((0, 0), (0, 1), (1, 0), (1, 1)):
            cols[f"free_{a}{b}"] = phi[..., a, b]
            cols[f"clamped_{a}{b}"] = clamped[..., a, b]
        return cols

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """The peaks of `_peaks` (the frequency is searched on them, not by
        the local fit), each with a grid of damping ratios and of gyro-only
        couplings (f = 0) and two-mass payloads (coupling 1, f = 0.08 and
        0.2; the peak taken as the free and as the clamped frequency,
        ``free = clamped*sqrt(1 + r)``)."""
        peaks = cls._peaks(ctx)
        if not peaks:
            peaks = [50.0]
        forms = [(c, 0.0, 1.0) for c in (-0.3, -0.05, 0.05, 0.3)]
        for f in (0.08, 0.2):
            stretch = float(np.sqrt(1.0 / (1.0 - f)))  # sqrt(1 + r)
            forms += [(1.0, f, 1.0), (1.0, f, stretch)]
        return [
            {"freq_hz": p * k, "damping_ratio": z, "coupling": c, "payload_fraction": f}
            for p in peaks
            for z in (0.02, 0.08)
            for c, f, k in forms
        ]

    @classmethod
    def _peaks(cls, ctx) -> list[float]:
        """The two largest peaks of the residual's spectrum (`_spectrum_peaks`),
        after the peak of the deflection the sensors see where it stands out
        (`_deflection_peak`)."""
        peaks = cls._deflection_peak(ctx)
        for f in cls._spectrum_peaks(ctx.residual, ctx.dt, 2):
            if all(abs(f - p) > 3.0 for p in peaks):
                peaks.append(f)
        return peaks

    @classmethod
    def _deflection_peak(cls, ctx) -> list[float]:
        """`deflection_peak` of the context's deflection rate, as a list."""
        rate = ctx.deflection_rate
        peak = None if rate is None else cls.deflection_peak(rate, ctx.deflection_lines, ctx.dt)
        return [] if peak is None else [peak]

    @classmethod
    def deflection_peak(cls, rate: np.ndarray, lines: np.ndarray | None, dt: float) -> float | None:
        """The largest peak [Hz] of the payload's deflection rate as the gyro
        and the resolver see it (`RunStack.deflection`, the counted samples),
        where it stands `DEFLECTION_PROMINENCE` times above the band's
        median; else None. A peak is a local maximum inside the band, not
        its lower edge (where the spectrum of slow motion leaks in), nor one
        the resolver's quantization makes: ``lines``, its part of the rate
        (None: not known), reaches `QUANTIZATION_SHARE` of it there.

        The residual's spectrum shows the mode only where the base fits the
        friction: a base left at 1000-2000 noise floors by a strong payload
        peaked at 7-8 Hz on reference seeds 30 and 38 (modes at 25 and 47 Hz),
        and the candidate never met its frequency. The sensors' difference
        peaks between the clamped and the free frequency there.
        """
        spectrum = cls._spectrum(np.asarray(rate, float), dt) if np.size(rate) >= 8 else None
        if spectrum is None:
            return None
        freqs, smooth, band = spectrum
        floor = np.median(smooth[band])
        inner = band[(band > band[0]) & (band < band[-1])]
        inner = inner[(smooth[inner] >= smooth[inner - 1]) & (smooth[inner] >= smooth[inner + 1])]
        if lines is not None:
            # A line of order k (k times the repetition rate, folded) moves k
            # times as fast with the rate, and the rebuilt rate is the gyro's
            # mean: the rebuilt line may sit a few Hz off the measured one.
            reach = 2 * round(LINE_REACH_HZ / (freqs[1] - freqs[0])) + 1
            quantization = maximum_filter1d(cls._spectrum(np.asarray(lines, float), dt)[1], reach)
            inner = inner[quantization[inner] < QUANTIZATION_SHARE * smooth[inner]]
        if inner.size == 0 or not floor > 0.0:
            return None
        i = inner[np.argmax(smooth[inner])]
        if smooth[i] < DEFLECTION_PROMINENCE * floor:
            return None
        return float(freqs[i])

    @classmethod
    def _spectrum_peaks(cls, x: np.ndarray, dt: float, count: int) -> list[float]:
        """The `count` largest peaks of x's spectrum in the band, 3 Hz apart."""
        spectrum = cls._spectrum(x, dt)
        if spectrum is None:
            return []
        freqs, smooth, band = spectrum
        peaks: list[float] = []
        for i in band[np.argsort(smooth[band])[::-1]]:
            if all(abs(freqs[i] - f) > 3.0 for f in peaks):
                peaks.append(float(freqs[i]))
            if len(peaks) == count:
                break
        return peaks

    @classmethod
    def _spectrum(cls, x: np.ndarray, dt: float):
        """x's Hann-windowed amplitude spectrum smoothed over 1 Hz (so a
        single noise bin does not win): (frequencies, smoothed spectrum,
        indices of the band searched: 5 Hz or the lower bound up to 0.45 of
        the sample rate), or None where the band is empty."""
        r = x - x.mean()
        spec = np.abs(np.fft.rfft(r * np.hanning(r.size)))
        freqs = np.fft.rfftfreq(r.size, dt)
        lo, hi = max(5.0, cls.bounds["freq_hz"][0]), min(cls.bounds["freq_hz"][1], 0.45 / dt)
        band = np.flatnonzero((freqs >= lo) & (freqs <= hi))
        if band.size == 0:
            return None
        width = max(1, round(1.0 / (freqs[1] - freqs[0])))
        return freqs, np.convolve(spec, np.ones(width) / width, mode="same"), band
