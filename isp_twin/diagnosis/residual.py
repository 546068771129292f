"""Residual analysis: what the model leaves unexplained, and how much no model can.

The residual is measured minus simulated rate. `analyse` answers: is it white
(autocorrelation against its 95 % band), is it correlated with the input, how
does it depend on angle, rate, direction, acceleration and time, what is its
spectrum, and what is the noise floor.

Noise floor (`noise_floor`): the standard deviation of the measurement noise,
estimated from the residual's fourth differences
(`isp_twin.estimation.verdict.FLOOR_DIFFERENCE`). For white noise of standard
deviation s the fourth difference has variance ``70 s^2``; the model errors
the library is about, and a payload's ringing well below the Nyquist
frequency, are smooth at the sample rate and add little to it, except at a
few breakaways and steps, which the median absolute deviation ignores. So
``noise = 1.4826 * MAD(fourth difference) / sqrt(70)``. It is the RMS error a
perfect model would leave.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from isp_twin.estimation.simulation_error import predict_one
from isp_twin.estimation.verdict import noise_floor_of
from isp_twin.model.parameters import RATE_LAYOUT

__all__ = [
    "NOISE_METHOD",
    "ResidualAnalysis",
    "ResidualContext",
    "analyse",
    "noise_floor",
    "residual_context",
]

NOISE_METHOD = (
    "1.4826*MAD of the residual's fourth difference / sqrt(70), pooled over runs "
    "(white-noise standard deviation; smooth model errors and the few steps do not count)"
)


def noise_floor(residual_runs) -> float:
    """Measurement-noise standard deviation [rad/s] from per-run residuals (see module doc)."""
    return noise_floor_of(residual_runs)


@dataclass(frozen=True)
class ResidualContext:
    """The residual of a fit with what the candidate effects' `guesses` need.
    Arrays (M,): the counted samples of all runs, concatenated.

    Attributes:
        u: command. angle: measured angle [rad]. rate: measured rate [rad/s].
        residual: measured minus simulated rate [rad/s].
        accel: the residual's one-step innovation over dt [rad/s^2]: the
            extra torque / J a missing torque effect would supply.
        moving: samples where the simulated axis moved on both ends of the step.
        run_id: index of the run of each sample.
        dt: sample period [s].
        coulomb_rad_s2: the model's sliding friction, the median over the
            regimes of its Coulomb level [rad/s^2] (NaN: not known).
        coulomb_digits: the same in command digits, the median over the
            regimes of the Coulomb level over the motor gain (NaN: not
            known): the largest dead zone the model's levels can carry.
        friction_deficit_rad_s2: the sliding friction the model lacks, the
            mean of ``-accel * sign(rate)`` over the moving samples [rad/s^2]
            (0: not known). With `coulomb_rad_s2`, what a guess of a
            friction-like effect (LuGre's bristle force) is scaled by.
        deflection_rate: the gyro minus the resolver's difference quotient
            [rad/s] (`RunStack.deflection`), or None.
        deflection_lines: beside it, the part of it the resolver's
            quantization makes [rad/s] (`RunStack.deflection`), or None.
    """

    u: np.ndarray
    angle: np.ndarray
    rate: np.ndarray
    residual: np.ndarray
    accel: np.ndarray
    moving: np.ndarray
    run_id: np.ndarray
    dt: float
    coulomb_rad_s2: float = float("nan")
    coulomb_digits: float = float("nan")
    friction_deficit_rad_s2: float = 0.0
    deflection_rate: np.ndarray | None = None
    deflection_lines: np.ndarray | None = None


def residual_context(stack, rate_vector: np.ndarray, fixed=()) -> ResidualContext:
    """Context of one model's residual on a `RunStack`.

    Args:
        stack: the runs.
        rate_vector: the model's rate-form parameters (`RATE_LAYOUT.size`,).
        fixed: its effects (`EffectSpec`).
    """
    resp = predict_one(stack, rate_vector, fixed)
    pole = RATE_LAYOUT.column(rate_vector, "pole")
    levels = RATE_LAYOUT.column(rate_vector, "coulomb")
    coulomb = float(np.median(levels)) / stack.dt
    gain = RATE_LAYOUT.column(rate_vector, "gain")
    with np.errstate(divide="ignore", invalid="ignore"):
        digits = float(np.median(levels / gain))
    res = stack.omega - resp.omega
    true = resp.omega if resp.omega_true is None else resp.omega_true
    a = np.asarray(pole)[resp.regime]
    prev = np.concatenate([res[:, :1], res[:, :-1]], axis=1)
    accel = (res - a * prev) / stack.dt
    prev_true = np.concatenate([true[:, :1], true[:, :-1]], axis=1)
    moving = (true != 0.0) & (prev_true != 0.0)
    # The innovation of step k belongs to the state at k-1 (angle, rate).
    angle_prev = np.concatenate([stack.angle[:, :1], stack.angle[:, :-1]], axis=1)
    run_id = np.broadcast_to(np.arange(stack.u.shape[0])[:, None], stack.u.shape)
    f = stack.flat
    rate, innovation, sliding = f(stack.omega), f(accel), f(moving)
    deficit = -float(np.mean(innovation[sliding] * np.sign(rate[sliding])))
    deflection, lines = stack.deflection() or (None, None)
    return ResidualContext(
        u=f(stack.u),
        angle=f(angle_prev),
        rate=rate,
        residual=f(res),
        accel=innovation,
        moving=sliding,
        run_id=f(run_id),
        dt=stack.dt,
        coulomb_rad_s2=coulomb,
        coulomb_digits=digits if np.isfinite(digits) and digits > 0.0 else float("nan"),
        friction_deficit_rad_s2=deficit if sliding.any() else 0.0,
        deflection_rate=deflection,
        deflection_lines=lines,
    )


@dataclass(frozen=True)
class ResidualAnalysis:
    """Statistics of a residual (SI units).

    Attributes:
        rms: RMS residual [rad/s].
        noise_floor: measurement-noise estimate [rad/s] (`noise_floor`).
        noise_method: how it was estimated.
        acf: autocorrelation at lags 1..L, (L,); acf_band: its 95 % band for
            white noise, 1.96/sqrt(M); acf_outside: fraction of lags outside.
        white: acf_outside <= 10 % (5 % expected for white noise).
        xcorr_input: correlation of residual with the command at lags 0..L-1;
            input_correlated: any |xcorr| beyond the band.
        binned: signal name (angle, rate, acceleration, time) -> (bin centres,
            mean residual per bin); direction: mean residual moving +, moving -.
        spectrum: (frequencies [Hz], power spectral density [(rad/s)^2/Hz]).
        peak_hz: frequency of the largest spectral peak above 1 Hz.
    """

    rms: float
    noise_floor: float
    noise_method: str
    acf: np.ndarray
    acf_band: float
    acf_outside: float
    white: bool
    xcorr_input: np.ndarray
    input_correlated: bool
    binned: dict = field(default_factory=dict)
    direction: dict = field(default_factory=dict)
    spectrum: tuple = ()
    peak_hz: float = float("nan")

    def summary(self) -> dict:
        """JSON-ready headline numbers."""
        return {
            "rms_rad_s": self.rms,
            "noise_floor_rad_s": self.noise_floor,
            "noise_method": self.noise_method,
            "white": self.white,
            "acf_outside_band_fraction": self.acf_outside,
            "input_correlated": self.input_correlated,
            "mean_moving_positive_rad_s": self.direction.get("+", float("nan")),
            "mean_moving_negative_rad_s": self.direction.get("-", float("nan")),
            "spectral_peak_hz": self.peak_hz,
        }


def _binned(x: np.ndarray, r: np.ndarray, bins: int = 20):
    if x.size == 0 or np.ptp(x) == 0:
        return np.array([]), np.array([])
    edges = np.linspace(x.min(), x.max(), bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    counts = np.bincount(idx, minlength=bins)
    sums = np.bincount(idx, weights=r, minlength=bins)
    centres = 0.5 * (edges[1:] + edges[:-1])
    ok = counts > 0
    return centres[ok], sums[ok] / counts[ok]


def _correlation(a: np.ndarray, b: np.ndarray, lags: int, start: int) -> np.ndarray:
    a = a - a.mean()
    b = b - b.mean()
    den = np.sqrt((a @ a) * (b @ b)) or 1.0
    n = a.size
    return np.array([(a[k:] @ b[: n - k]) / den for k in range(start, lags + start)])


def analyse(stack, resp, lags: int = 50) -> ResidualAnalysis:
    """Analyse the residual of a model on a `RunStack`.

    Args:
        stack: the runs.
        resp: the model's `AxisResponse`, arrays (R, N).
        lags: number of autocorrelation / cross-correlation lags.
    """
    res_full = stack.omega - resp.omega
    per_run = [res_full[i, stack.mask[i]] for i in range(res_full.shape[0])]
    res = np.concatenate(per_run)
    u = stack.flat(stack.u)
    m = res.size
    lags = min(lags, max(m // 4, 1))
    acf = (
        np.mean([_correlation(r, r, lags, 1) for r in per_run if r.size > 4 * lags], axis=0)
        if any(r.size > 4 * lags for r in per_run)
        else _correlation(res, res, lags, 1)
    )
    band = 1.96 / np.sqrt(m)
    outside = float(np.mean(np.abs(acf) > band))
    xc = _correlation(res, u, lags, 0)
    t = np.concatenate([np.arange(r.size) * stack.dt for r in per_run])
    accel = np.gradient(stack.omega, stack.dt, axis=1)
    binned = {
        "angle": _binned(stack.flat(stack.angle), res),
        "rate": _binned(stack.flat(stack.omega), res),
        "acceleration": _binned(
            np.clip(stack.flat(accel), *np.quantile(stack.flat(accel), [0.01, 0.99])), res
        ),
        "time": _binned(t, res),
    }
    rate = stack.flat(stack.omega)
    direction = {
        "+": float(res[rate > 0].mean()) if np.any(rate > 0) else float("nan"),
        "-": float(res[rate < 0].mean()) if np.any(rate < 0) else float("nan"),
    }
    # Welch: mean periodogram of 1024-sample Hann segments of every run.
    seg = min(1024, max(min(r.size for r in per_run), 8))
    win = np.hanning(seg)
    psd, count = np.zeros(seg // 2 + 1), 0
    for r in per_run:
        for s in range(0, r.size - seg + 1, seg // 2):
            x = r[s : s + seg] - r[s : s + seg].mean()
            psd += np.abs(np.fft.rfft(x * win)) ** 2
            count += 1
    freqs = np.fft.rfftfreq(seg, stack.dt)
    psd = psd / max(count, 1) * 2 * stack.dt / (win @ win)
    above = freqs > 1.0
    peak = float(freqs[above][np.argmax(psd[above])]) if above.any() else float("nan")
    return ResidualAnalysis(
        rms=float(np.sqrt(np.mean(res**2))),
        noise_floor=noise_floor(per_run),
        noise_method=NOISE_METHOD,
        acf=acf,
        acf_band=float(band),
        acf_outside=outside,
        white=outside <= 0.10,
        xcorr_input=xc,
        input_correlated=bool(np.any(np.abs(xc) > band)),
        binned=binned,
        direction=direction,
        spectrum=(freqs, psd),
        peak_hz=peak,
    )
