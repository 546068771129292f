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
    "resolver_step",
    "zero_cell_anchors",
    "reading_anchors",
    "anchored_angle",
    "regime_visits",
]

#: Window of the angle/rate fusion [samples] (`fused_angle`).
FUSION_WINDOW = 201
#: Readings of exactly 0 in a row that make a stop on the boundary (`at_boundary`).
BOUNDARY_READINGS = 10


def fused_angle(
    data: MeasuredData, window: int = FUSION_WINDOW, anchored: bool = True
) -> np.ndarray:
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

    With `anchored`, in the zero reading the angle carried from the edges
    where the reading entered or left it (`zero_cell_anchors`) replaces the
    fusion's level; without, the fusion alone (what an effect that deflects
    the gyro from the resolver's side needs, `with_side_angle`). The angle
    a torque of the angle reads is `anchored_angle`.
    """
    omega, fused = _corrected_fusion(data, window)
    return _zero_anchored(data, omega, fused) if anchored else fused


def _zero_anchored(data: MeasuredData, omega: np.ndarray, fused: np.ndarray) -> np.ndarray:
    """The fusion `fused` of the reading `omega` with the zero reading's
    anchors in place of its level (`fused_angle`), a new array."""
    at, _ = zero_cell_anchors(data, omega)
    return np.where(np.isfinite(at), at, fused)


def anchored_angle(data: MeasuredData, window: int = FUSION_WINDOW) -> np.ndarray:
    """The angle a torque of the angle reads [rad], shape (N,): the fused
    angle (`fused_angle`, the reading corrected the same way) weighed, in
    every reading, with the angle the edges where the reading entered and
    left it carry (`reading_anchors`), by their variances
    (`fusion_level_variance`: the fusion's level is the mean of the
    quantization over its window, a fraction of a step off at a rest, sharp
    where the motion crosses many steps within the window; an edge is as
    sharp as the motion over its sample), and kept within the reading's
    half step.

    A cogging of a 0.05 rad period as strong as the Coulomb levels turns
    1e-4 rad into a drive error of several noise floors on a 5 ms axis:
    reference cogging 471 with its true parameters stood at 2.59 noise
    floors on a training run at the fusion's level, 1.07 at this angle
    (docs/identification.md "Stop 80"). The side of each step keeps
    `side_angle`: anchored everywhere, it moved no side but the crossings'
    parts of a sample, and two global refits of LuGre axes (reference 337
    and 428, whose pinned tests then failed) ended in other basins.
    """
    return _weighed(data, *_corrected_fusion(data, window), window)


def _weighed(data: MeasuredData, omega: np.ndarray, fused: np.ndarray, window: int) -> np.ndarray:
    """The fusion `fused` of the reading `omega` weighed with every
    reading's anchors (`anchored_angle`), a new array."""
    at, sd = reading_anchors(data, omega)
    known = np.isfinite(at)
    if not known.any():
        return fused.copy()
    step = resolver_step(data.angle)
    v_fused = fusion_level_variance(data, step, window)[known]
    share = v_fused / (v_fused + sd[known] ** 2)  # the anchor's weight
    out = fused.copy()
    out[known] = fused[known] + share * (at[known] - fused[known])
    half = step / 2.0
    out[known] = np.clip(out[known], data.angle[known] - half, data.angle[known] + half)
    return out


def _corrected_fusion(data: MeasuredData, window: int) -> tuple[np.ndarray, np.ndarray]:
    """The rate reading the fusion integrates (corrected for a gyro error
    where that moves the fused angle and the runs agree on it, `fused_angle`,
    `MeasuredData.gyro_error_fused`) and the fused angle."""
    omega = data.omega
    fused = _fused(omega, data, window)
    est = reading_error(data) if data.gyro_error_fused else None
    if est is not None:
        corrected = _fused(est.corrected(data.omega), data, window)
        if np.max(np.abs(corrected - fused)) > 4.0 * fusion_noise(data, window):
            omega, fused = est.corrected(data.omega), corrected
    return omega, fused


def fusion_level_variance(data: MeasuredData, step: float, window: int = FUSION_WINDOW):
    """Variance of the fused angle's level [rad^2], shape (N,): the mean of
    the quantization errors (uniform over a step, ``step^2 / 12`` each) over
    the centred window, those of one visit to a reading taken as one error
    (a rest repeats its error, a motion across many steps averages them
    out), plus the integrated gyro noise's (`fusion_noise`). Each sample
    counts its visit's length, at most the window: the window's sum of
    those over the window's length squared is the share of one error's
    variance left in the mean."""
    n = data.angle.shape[0]
    w = _odd_window(window, n)
    bounds = np.concatenate(([0], np.flatnonzero(np.diff(data.angle)) + 1, [n]))
    lengths = np.repeat(np.minimum(np.diff(bounds), w), np.diff(bounds)).astype(float)
    padded = np.pad(lengths, w // 2, mode="edge")
    shared = np.convolve(padded, np.ones(w), mode="valid") / float(w) ** 2
    return step**2 / 12.0 * shared + fusion_noise(data, window) ** 2


#: Largest motion over the sample of a crossing, as a share of the
#: resolver's step, that anchors the angle in the zero reading
#: (`zero_cell_anchors`): a faster crossing times the edge no better than
#: the fusion does.
ANCHOR_SPAN = 0.5


#: How far off a whole number of steps a reading may lie [steps] and still be
#: on the resolver's grid (`resolver_step`): a file's printed digits round
#: it (the benchmark's CSV keeps 10 significant digits: 1.2e-6 steps at 1 deg
#: with a 0.022 deg step); a reading off the grid lies up to half a step off.
GRID_TOLERANCE = 0.01


def resolver_step(angle: np.ndarray) -> float | None:
    """The resolver's step [rad]: the smallest gap between distinct readings,
    if every reading is a whole multiple of it within `GRID_TOLERANCE`; None
    for an angle that is not read on such a grid (unquantized, noisy,
    offset) or never leaves one level."""
    levels = np.unique(angle)
    if levels.size < 2:
        return None
    step = float(np.min(np.diff(levels)))
    if step <= 0.0:
        return None
    # The span of the levels over its whole number of steps: the smallest gap
    # alone carries the printed digits' rounding, times the step count.
    span = float(levels[-1] - levels[0])
    step = span / round(span / step)
    k = angle / step
    if np.max(np.abs(k - np.round(k))) > GRID_TOLERANCE:
        return None
    return step


def zero_cell_anchors(data: MeasuredData, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`reading_anchors` inside the visits to the zero reading alone (NaN elsewhere).

    The sign of the angle in the zero reading is the side, and the reading
    does not give it. The fusion's level there is the mean of the
    quantization over its window, which a rest near 0 or a run's end biases
    by a fraction of a step: on reference clean axis 328 the fused angle
    stood 0.002 deg below the truth at a rest at +0.004 deg, and the truth's
    held-out error was 1.52 noise floors, all of it at that rest and the
    crossings beside it (docs/identification.md "Stop 49"). The boundary
    rule reads the side's uncertainty there (`_sign_unknown`).
    """
    return reading_anchors(data, omega, zero_only=True)


def reading_anchors(
    data: MeasuredData, omega: np.ndarray, zero_only: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """The angle [rad] inside each visit to a reading, carried by the
    integrated rate from the edges where the reading entered and left it,
    and its standard deviation [rad], shape (N,) each; NaN where no edge
    anchors it (or, with `zero_only`, outside the zero reading).

    An edge is exact: the reading changes where the angle passes half a
    step (a resolver that rounds to the nearest step, as the reference's
    and the twin's; the fusion assumes the same), within the motion over
    that sample (`_edges`). On each side of the visit the nearest edges
    intersect their intervals (`_offset_at`); the two sides' anchors are
    weighed by their variances (the interval's width, uniform, and the
    integrated gyro noise since) and must agree within four deviations,
    else the visit keeps the fusion. The result is clipped to the reading's
    half step. Inside any reading, not the zero one alone: a torque of the
    angle (cogging of a 0.05 rad period) turns the fusion's level error, up
    to a fraction of a step at a rest, into a drive error; reference
    cogging axis 471 with its true parameters stood at 2.59 noise floors on
    a training run with the fusion's level, 0.99 with the true angle
    (docs/identification.md "Stop 80"). A run that opens in the zero
    reading opens at rest there, and the rules of stop 41 read its side
    (`at_boundary`'s opening; Eq. 6 stepped once per sample keeps the
    fusion's): anchored too, the shipped twin model's inner_el R+ breakaway
    went from 2.197 (truth 2.194) to 5.49 (models/params/twin_identified.sh).
    """
    n = omega.shape[0]
    est, sd = np.full(n, np.nan), np.full(n, np.nan)
    step = resolver_step(data.angle)
    if step is None or (zero_only and not np.any(data.angle == 0.0)):
        return est, sd
    integral = np.cumsum(omega) * data.dt
    walk = noise_floor_of([omega], SCALE_DIFFERENCE) * data.dt  # per-sample deviation
    edges = _edges(data.angle, integral, step)
    bounds = np.concatenate(([0], np.flatnonzero(np.diff(data.angle)) + 1, [n]))
    lo, hi = bounds[:-1], bounds[1:]
    level = data.angle[lo]
    keep = (lo != 0) | (level != 0.0)
    if zero_only:
        keep &= level == 0.0
    visit = np.repeat(np.arange(lo.size), hi - lo)
    (a1, v1), (a2, v2) = _carried(edges, integral, lo, hi, visit, walk)
    one, two = np.isfinite(a1), np.isfinite(a2)
    both = one & two
    # The two sides must agree at the visit's first sample.
    apart = np.abs(a1[lo] - a2[lo]) > 4.0 * np.sqrt(v1[lo] + v2[lo])
    keep &= ~(both[lo] & apart)
    with np.errstate(invalid="ignore", divide="ignore"):
        var = np.where(both, 1.0 / (1.0 / v1 + 1.0 / v2), np.where(one, v1, v2))
        at = np.where(both, var * (a1 / v1 + a2 / v2), np.where(one, a1, a2))
    used = keep[visit] & (one | two)
    half = step / 2.0
    est[used] = np.clip(at[used], data.angle[used] - half, data.angle[used] + half)
    sd[used] = np.sqrt(var[used])
    return est, sd


def _carried(edges, integral, lo, hi, visit, walk: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per sample (N,), the angle carried from the edges before its visit
    to a reading (lo..hi-1; `visit`: each sample's) and its variance, and
    the same from the edges after it; NaN where no edge anchors it."""
    k = np.arange(integral.shape[0])
    sides = []
    for c, distance in (
        (_offset_at(edges, lo, True, walk), k - lo[visit] + 1),
        (_offset_at(edges, hi - 1, False, walk), hi[visit] - k),
    ):
        width = (c[1] - c[0])[visit]
        sides.append((integral + 0.5 * (c[0] + c[1])[visit], width**2 / 12.0 + walk**2 * distance))
    return sides


#: Edges on each side of a visit to a reading whose intervals
#: `reading_anchors` intersects, and how far they may lie [samples].
EDGES_PER_SIDE = 3
EDGE_REACH = FUSION_WINDOW


def _edges(angle: np.ndarray, integral: np.ndarray, step: float) -> tuple[np.ndarray, ...]:
    """The reading's changes by one step whose sample's integrated rate moved
    the same way by at most `ANCHOR_SPAN` steps: their samples j and the
    interval [lo, hi] of the offset c where the angle is ``integral + c``
    (it passed the half step between the readings within sample j)."""
    j = np.flatnonzero(np.diff(angle)) + 1
    change = (angle[j] - angle[j - 1]) / step
    span = integral[j] - integral[j - 1]
    one = (np.abs(np.abs(change) - 1.0) < 1e-6) & (span * change > 0.0)
    j = j[one & (np.abs(span) <= ANCHOR_SPAN * step)]
    level = 0.5 * (angle[j] + angle[j - 1])
    a, b = level - integral[j], level - integral[j - 1]
    return j, np.minimum(a, b), np.maximum(a, b)


def _offset_at(edges, at: np.ndarray, before: bool, walk: float) -> tuple[np.ndarray, np.ndarray]:
    """The interval (lo, hi) of the offset c at each sample of `at` from the
    nearest `EDGES_PER_SIDE` edges at or before it (``before``) or after
    it, within `EDGE_REACH` samples: each widened by four deviations of the
    integrated noise between it and `at`, intersected from the nearest out
    while they agree; NaN where there is no edge."""
    j, c_lo, c_hi = edges
    out_lo, out_hi = np.full(at.shape, np.nan), np.full(at.shape, np.nan)
    if j.size == 0:
        return out_lo, out_hi
    first = np.searchsorted(j, at, side="right")  # the first edge after `at`
    going = np.ones(at.shape, dtype=bool)  # the intersection goes on
    for nth in range(EDGES_PER_SIDE):
        i = first - 1 - nth if before else first + nth
        valid = going & (i >= 0) & (i < j.size)
        i = np.clip(i, 0, j.size - 1)
        distance = np.abs(at - j[i])
        valid &= (distance < EDGE_REACH) if before else (distance <= EDGE_REACH)
        if nth == 0:
            out_lo[valid], out_hi[valid] = c_lo[i[valid]], c_hi[i[valid]]
            going = valid
            continue
        widen = 4.0 * walk * np.sqrt(distance + 1.0)
        lo = np.maximum(c_lo[i] - widen, out_lo)
        hi = np.minimum(c_hi[i] + widen, out_hi)
        going = valid & (lo < hi)
        out_lo[going], out_hi[going] = lo[going], hi[going]
    return out_lo, out_hi


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
    data: MeasuredData,
    fused: np.ndarray,
    window: int = FUSION_WINDOW,
    opening: bool = False,
    anchored: bool = True,
) -> np.ndarray:
    """Samples of an axis at rest on the boundary between the half-planes,
    bool shape (N,).

    There the resolver reads exactly 0 for at least `BOUNDARY_READINGS`
    samples in a row and the fused angle is within four standard deviations
    of its own noise (the integrated gyro noise less its moving average,
    ``sigma dt sqrt(window / 12)``): its sign is only that noise. Where the
    reading's edges anchor the angle (`zero_cell_anchors`, with `anchored`)
    only a rest counts, with the anchor's deviation (`_sign_unknown`). The side
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
    boundary = long_run & _sign_unknown(data, fused, window, anchored)
    if opening and zero[0]:
        boundary[: edges[1]] = True
    return boundary


def _sign_unknown(data: MeasuredData, fused: np.ndarray, window: int, anchored: bool) -> np.ndarray:
    """Samples whose angle is within four of its own deviations of 0, bool
    (N,): the fusion's noise (`fusion_noise`); where the edges anchor it
    (`zero_cell_anchors`), the anchor's deviation if larger, and only at a
    rest (`_resting`): a crossing, even a slow one, keeps its angle's sign.
    Without `anchored`, the rule before stop 49 (the fusion's noise alone)."""
    spread = np.full(fused.shape, 4.0 * fusion_noise(data, window))
    if not anchored:
        return np.abs(fused) <= spread
    _, sd = zero_cell_anchors(data, data.omega)
    known = np.isfinite(sd)
    spread[known] = np.maximum(spread[known], 4.0 * sd[known])
    return _resting(data) & (np.abs(fused) <= spread)


def _resting(data: MeasuredData, span: int = BOUNDARY_READINGS) -> np.ndarray:
    """Samples where the integrated rate moves, over the `span` samples
    centred on them, by less than four deviations of its noise over them
    (bool shape (N,)): a rest, not a creep through 0 (reference clean axis
    173 creeps through the zero reading at 0.1 deg/s, 4 noise deviations)."""
    n = data.omega.shape[0]
    integral = np.concatenate(([0.0], np.cumsum(data.omega) * data.dt))
    half = span // 2
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    walk = noise_floor_of([data.omega], SCALE_DIFFERENCE) * data.dt * np.sqrt(hi - lo)
    return np.abs(integral[hi] - integral[lo]) <= 4.0 * walk


def side_angle(
    data: MeasuredData,
    side_source: str = "measured",
    shift: float = 0.0,
    opening: bool = False,
    anchored: bool = True,
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
        y = fused_angle(data, anchored=anchored)
        y[at_boundary(data, y, opening=opening, anchored=anchored)] = 0.0
        return _at_step(y, shift)
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
    `isp_twin.model.effects.base.Effect.fusion_gain`) and the side angle of
    the fusion alone (``fusion_plain``, no edge anchors in the zero reading,
    `zero_cell_anchors`): the anchors carry the resolver's edge by the
    gyro's integral, the motor side's angle only where the gyro reads the
    motor side; with the truth held, a payload mode on reference resonance
    axis 50 went from 1.41 to 2.46 noise floors on a training run with them
    (docs/identification.md "Stop 49"); and the angle a torque of the angle
    reads (``torque_angle``: `anchored_angle` at the side angle's time, 0
    where the side angle is on the boundary; docs/identification.md "Stop 80")."""
    if side_source != "measured":
        return replace(
            data,
            angle=side_angle(data, side_source, shift, opening),
            resolver=None,
            fusion_accel=None,
            fusion_plain=None,
            torque_angle=None,
        )
    # One fusion for the three angles: the side's (`side_angle`), the
    # fusion alone (its own boundary rule) and the torque's
    # (`anchored_angle`, 0 where the side's is on the boundary).
    omega, fused = _corrected_fusion(data, FUSION_WINDOW)
    angle = _zero_anchored(data, omega, fused)
    boundary = at_boundary(data, angle, opening=opening)
    angle[boundary] = 0.0
    plain = fused.copy()
    plain[at_boundary(data, plain, opening=opening, anchored=False)] = 0.0
    plain = _at_step(plain, shift)
    torque = _weighed(data, omega, fused, FUSION_WINDOW)
    torque[boundary] = 0.0
    # At rest on the boundary (`at_boundary`) the side angle is 0, not fused.
    accel = np.where(plain == 0.0, 0.0, window_accel(data))
    return replace(
        data,
        angle=_at_step(angle, shift),
        resolver=data.angle,
        fusion_accel=accel,
        fusion_plain=plain,
        torque_angle=_at_step(torque, shift),
    )


def _at_step(y: np.ndarray, shift: float) -> np.ndarray:
    """`y` read at sample ``k + shift`` (linear interpolation; `y` itself at 0)."""
    if shift == 0.0:
        return y
    k = np.arange(y.size, dtype=float)
    return np.interp(k + shift, k, y)


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
