"""Which half-plane (side) each sample is in: the angle the model is driven
by (teacher forcing), fused with the integrated gyro rate or as measured,
wrapped, or a fixed side (`SIDE_SOURCES`); why: `isp_twin.identification.fit`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from isp_twin.errors import ParameterError
from isp_twin.estimation.verdict import SCALE_DIFFERENCE, noise_floor_of
from isp_twin.identification.gyro_error import reading_error
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.friction import regime_index
from isp_twin.model.parameters import RATE_LAYOUT
from isp_twin.units import DEG
from isp_twin.vocabulary import SIDE_SOURCES

__all__ = [
    "SIDE_SOURCES",
    "FUSION_WINDOW",
    "fused_angle",
    "fusion_noise",
    "side_angle",
    "with_side_angle",
    "sides_as_read",
    "window_accel",
    "at_boundary",
    "regime_visits",
]

#: Window of the angle/rate fusion [samples] (`fused_angle`).
FUSION_WINDOW = 201
#: Readings of exactly 0 in a row that make a stop on the boundary (`at_boundary`).
BOUNDARY_READINGS = 10


def fused_angle(data: MeasuredData, window: int = FUSION_WINDOW) -> np.ndarray:
    """The measured angle refined by the integrated rate [rad], shape (N,).

    ``integral(omega) + smooth(angle - integral(omega))`` with a centred moving
    average of `window` samples: the rate supplies the fine timing, the angle
    the absolute level (and removes gyro drift slower than the window).

    Where the run's angle shows a gyro bias or scale error (`reading_error`),
    the reading is corrected for it first, if that moves the fused angle by
    more than four of its own noise deviations (`fusion_noise`) somewhere: a
    scale error s leaves ``s (theta - smooth(theta))`` in the fused angle
    (zero crossings of a fast swing a fraction of a sample off), a bias
    ``b t`` is left near the run's ends where the window is cut. Reference
    sensor_bias seed 3 with its true parameters: 1.60 / 1.77 noise floors
    (train / held out) without the correction, 1.11 / 1.06 with it
    (docs/diagnosis.md "Stop 20"). A smaller correction is not applied: on
    the twin's clean runs (models/params/twin_identified.sh) the estimate's
    interval may just exclude 0 and the correction moves the fused angle by
    1e-6 rad, which flipped the side of one sample at a start from rest at 0.
    """
    raw = _fused(data.omega, data, window)
    est = reading_error(data)
    if est is None:
        return raw
    corrected = _fused(est.corrected(data.omega), data, window)
    material = np.max(np.abs(corrected - raw)) > 4.0 * fusion_noise(data, window)
    return corrected if material else raw


def fusion_noise(data: MeasuredData, window: int = FUSION_WINDOW) -> float:
    """Standard deviation of the fused angle's own noise [rad]: the integrated
    gyro noise less its moving average, ``sigma dt sqrt(window / 12)``."""
    sigma = noise_floor_of([data.omega], SCALE_DIFFERENCE)
    return float(sigma * data.dt * np.sqrt(max(1, min(window, len(data.omega))) / 12.0))


def _fused(omega: np.ndarray, data: MeasuredData, window: int) -> np.ndarray:
    integral = np.cumsum(omega) * data.dt
    gap = data.angle - integral
    w = _odd_window(window, gap.shape[0])
    padded = np.pad(gap, w // 2, mode="edge")
    smooth = np.convolve(padded, np.ones(w) / w, mode="valid")
    return integral + smooth


def _odd_window(window: int, n: int) -> int:
    """The fusion's window on a run of n samples: `window`, at most the
    run's length, odd (a centred average)."""
    return max(1, min(window, n if n % 2 else n - 1))


def at_boundary(
    data: MeasuredData, fused: np.ndarray, window: int = FUSION_WINDOW, opening: bool = False
) -> np.ndarray:
    """Samples of an axis at rest on the boundary between the half-planes,
    bool shape (N,).

    There the resolver reads exactly 0 for at least `BOUNDARY_READINGS`
    samples in a row and the fused angle is within four standard deviations
    of its own noise (the integrated gyro noise less its moving average,
    ``sigma dt sqrt(window / 12)``): its sign is only that noise. The side
    angle is 0 there and the direction of the motion picks the side
    (`isp_twin.model.friction.side_of`), as on the real axis; from rest
    there a break towards + passes L+'s level too, Eq. 5's Y = 0
    (`isp_twin.model.substep_model._rest_regime`). A crossing,
    even a slow one, keeps its fused angle: its sign times the crossing to a
    fraction of a sample, and a side one sample early costs a transient of
    the size of the friction change.

    With `opening`, the readings of 0 that open a run are on the boundary whatever their
    number and whatever the fused angle: a run that starts at rest at 0
    (every run of the reference simulator, and a test started from a
    zeroed resolver) breaks away at once, so the rest may be shorter than
    `BOUNDARY_READINGS`, and the fusion's centred window is cut there (its
    level is the mean of the quantization over the first half window, not
    the position). Until the resolver leaves 0 the direction of the motion
    picks the side, which is where the angle goes. Read from the fused
    angle, the first steps took the other side's motor gain and friction
    at random, an error that decays with the pole: the true parameters of
    reference clean axes 140, 159, 170, 174, 177 and 199 stood at
    1.12-2.61 noise sigmas on a training run, and at 0.99-1.01 with this
    rule (docs/identification.md "Stop 41"). A rule of the sub-stepped
    model (`Integration.opens_on_boundary`): a discrete axis stepped once
    per sample (Eq. 6, the twin) takes its first step from angle 0 itself.
    """
    zero = data.angle == 0.0
    if not zero.any():
        return zero
    # Length of the run of zero readings each sample belongs to.
    edges = np.flatnonzero(np.diff(np.concatenate(([0], zero.astype(np.int8), [0]))))
    long_run = np.zeros_like(zero)
    for lo, hi in zip(edges[::2], edges[1::2]):
        if hi - lo >= BOUNDARY_READINGS:
            long_run[lo:hi] = True
    boundary = long_run & (np.abs(fused) <= 4.0 * fusion_noise(data, window))
    if opening and zero[0]:
        boundary[: edges[1]] = True
    return boundary


def side_angle(
    data: MeasuredData, side_source: str = "measured", shift: float = 0.0, opening: bool = False
) -> np.ndarray:
    """The angle [rad] whose sign selects the half-plane of each step (see module doc).

    Entry k picks the regime of the step from sample k to k+1. With
    ``measured`` it is the fused angle at sample ``k + shift`` (linear
    interpolation). Eq. 6 takes the angle at the start of the step
    (``shift = 0``), but a real axis crosses angle 0 between samples and what
    its gyro sample means decides which time is right: a point-sampled rate
    is the rate at the sample, so the regime holding for most of the step is
    the one at mid-step (``shift = 0.5``); a rate averaged over the sample
    period describes the half sample before it (``shift = 0``). A wrong
    choice makes every crossing half a sample early or late, an error of the
    size of the friction change that then decays with the pole (20-30 noise
    sigmas on a 10 ms axis). `identify` picks the shift from the data.

    The fused angle is set to 0 `at_boundary` (an axis at rest where the
    resolver reads 0: there the direction of the motion picks the side).
    """
    if side_source == "measured":
        y = fused_angle(data)
        y[at_boundary(data, y, opening=opening)] = 0.0
        if shift == 0.0:
            return y
        k = np.arange(y.size, dtype=float)
        return np.interp(k + shift, k, y)
    if side_source == "raw":
        return data.angle
    if side_source == "wrap":
        return np.angle(np.exp(1j * data.angle))
    if side_source == "right":
        return np.ones_like(data.angle)
    if side_source == "left":
        return -np.ones_like(data.angle)
    raise ParameterError(f"side source '{side_source}' unknown; allowed: {', '.join(SIDE_SOURCES)}")


def sides_as_read(runs: Sequence[MeasuredData], side_source: str) -> list[MeasuredData]:
    """The runs with an angle whose sign is their side for `side_source`,
    without the fusion (the measured angle as read for ``measured``): a
    constant for a fixed side, the wrapped angle for ``wrap``. For what
    needs the regimes of whole runs, not the sample of each crossing
    (`isp_twin.estimation.coverage.beyond_training`)."""
    source = "raw" if side_source == "measured" else side_source
    return [replace(d, angle=side_angle(d, source)) for d in runs]


def with_side_angle(
    data: MeasuredData, side_source: str, shift: float = 0.0, opening: bool = False
) -> MeasuredData:
    """The run with `side_angle` as its angle; with the fused angle
    (``measured``) the measured one is kept as ``resolver``, whose sign the
    model's side keeps on a two-mass axis
    (`isp_twin.estimation.simulation_error.resolver_sides`), with the
    fusion window's mean acceleration (`window_accel`,
    `isp_twin.model.effects.base.Effect.fusion_gain`)."""
    angle = side_angle(data, side_source, shift, opening)
    if side_source != "measured":
        return replace(data, angle=angle, resolver=None, fusion_accel=None)
    # At rest on the boundary (`at_boundary`) the side angle is 0, not fused.
    accel = np.where(angle == 0.0, 0.0, window_accel(data))
    return replace(data, angle=angle, resolver=data.angle, fusion_accel=accel)


def window_accel(data: MeasuredData, window: int = FUSION_WINDOW) -> np.ndarray:
    """The mean of the rate's derivative over `fused_angle`'s centred window
    [rad/s^2], shape (N,): the rate's change across the window over its span.
    0 within half a window of the run's ends, where the fusion's window is
    padded: an axis starting from rest has not the quasi-static deflection
    `Effect.fusion_gain` assumes (dev resonance seed 1005, a start
    at 0.01 deg under a full step: train2 1.01 -> 1.21 noise floors with it)."""
    n = data.omega.shape[0]
    half = _odd_window(window, n) // 2
    padded = np.pad(np.asarray(data.omega, dtype=float), half, mode="edge")
    accel = (padded[2 * half :] - padded[:n]) / (2 * half * data.dt)
    accel[:half] = 0.0
    accel[n - half :] = 0.0
    return accel


def regime_visits(
    data: Sequence[MeasuredData], side_source: str = "measured", rest_rate_deg_s: float = 0.1
) -> np.ndarray:
    """Moving samples (|rate| above the rest level) per regime, shape (4,)."""
    counts = np.zeros(RATE_LAYOUT.n_regimes, dtype=int)
    for d in data:
        moving = np.abs(d.omega) > rest_rate_deg_s * DEG
        r = regime_index(side_angle(d, side_source), d.omega)[moving]
        counts += np.bincount(r, minlength=RATE_LAYOUT.n_regimes)
    return counts
