"""The simulation error both commands minimize: measured runs simulated side
by side for a batch of model variants.

`identify` (Eq. 9, `isp_twin.identification.fit`) and `diagnose`
(`isp_twin.diagnosis`) both stack their runs here (`stack_runs`) and take
their residuals from `residuals`; they differ only in what they ask of the
stack: `identify` counts every sample after the first and calls a first
rate below a fixed level or within the noise rest, `diagnose` leaves a
warm-up out and calls a first rate within the noise rest.

The runs become rows of one batched call of
`isp_twin.model.substep_model.simulate_substeps` (padded to the longest), so
P parameter sets on R runs cost one time loop of P*R rows: the per-step
overhead, not the batch size, sets the price.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from isp_twin.errors import DataError
from isp_twin.estimation.verdict import SCALE_DIFFERENCE, noise_floor_of
from isp_twin.model.effects import effect_class
from isp_twin.model.effects.base import true_rates
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.parameters import EffectSpec, RateParams
from isp_twin.model.substep_model import (
    DEFAULT_INTEGRATION,
    Integration,
    is_torque,
    simulate_substeps,
)

__all__ = [
    "DIVERGED",
    "JACOBIAN_SUBSTEPS",
    "SAMPLE_PERIOD_TOLERANCE",
    "WARMUP",
    "RunStack",
    "predict",
    "predict_one",
    "residuals",
    "residuals_many",
    "relative_stack",
    "stack_runs",
]

#: Sub-steps per sample of the finite-difference columns both commands'
#: least squares simulate where the model integrates more, and of diagnose's
#: static scan (`relative_stack`; identify's `Settings.jacobian_substeps`
#: default). A column is the slope
#: of the model's response; the truth integrated in 4 sub-steps fits the
#: reference runs within 0.02 noise floors of 10 on 39 of 40 clean dev
#: axes (seeds 1000-1039, docs/identification.md "Stop 83"), and a step the
#: coarser slope proposes is still accepted only on the model's own cost.
#: An effect with `Effect.fine_slopes` keeps the model's own.
JACOBIAN_SUBSTEPS = 4


#: Largest relative difference between a run's measured sample period (the
#: median step of its time column) and the parameter set's sample_time_s,
#: shared by `identify` and `diagnose` (`check_sample_period`). The parameters
#: of Eq. 6 are per sample, so a period off by x scales the model's time
#: constants by x; 1 % is below the spread of identified values between runs
#: and lets a logger clock drifting by tens of ppm through.
SAMPLE_PERIOD_TOLERANCE = 0.01


@dataclass(frozen=True)
class RunStack:
    """Runs padded to a common length. Arrays shape (R, N) unless noted.

    Attributes:
        names: run names, (R,).
        u: command [digits or the file's unit].
        omega: measured rate [rad/s].
        angle: measured angle [rad].
        mask: True on samples that count (not sample 0, not padding).
        dt: sample period [s].
        side: None to pick the half-plane from the measured angle (the
            paper's rule), else a fixed side (`SIDE_R`, `SIDE_L`) for a freely
            spinning motor.
        gyro_average: the model's rate is read as a gyro averaging over the
            sample (`isp_twin.identification.read_out.Timing`).
        integration: how the model integrates a sample
            (`isp_twin.model.substep_model.Integration`).
        first_reading: each run's first measured rate [rad/s], (R,), before
            the rest rule (`stack_runs`); None: ``omega[:, 0]``.
        rest_level: a first rate at most this large is rest [rad/s], (R,);
            None: none is.
        side_follows_gyro: ``angle`` is the fused angle, which follows the
            gyro's integral within its window: with a two-mass payload the
            payload's angle, whose deflection the sub-stepped model takes
            off for the motor side's (`simulate_substeps`); False: a
            motor-side angle (the raw resolver).
        resolver_side: per step, the half-plane the measured (resolver)
            angle settles where ``angle`` is the fused one, int8 (R, N)
            (`resolver_sides`); None: none.
        fusion_accel: there, the fusion window's mean acceleration (R, N)
            [rad/s^2] (`isp_twin.model.effects.base.Effect.fusion_gain`).
        deflection_rate: the rate reading minus the difference quotient of
            the measured angle (the resolver's where ``angle`` is the fused
            one) (R, N) [rad/s], 0 at each run's first sample: the rate of a
            payload's deflection against the motor side as the gyro and the
            resolver see it (`Resonance.deflection_peak`); None: not known.
        angle_step: each run's quantum of that measured angle [rad], (R,):
            its smallest non-zero change, 0 where it never changes
            (`deflection`); None: not known.
        angle_plain: where ``angle`` is the fused one, the side angle of the
            fusion alone, without the zero reading's edge anchors (R, N)
            [rad], for rows with an effect that deflects the gyro from the
            motor side (`_side_angles`); None: the same as ``angle``.
        torque_angle: where ``angle`` is the fused one, the angle a torque
            of the angle reads (R, N) [rad]
            (`isp_twin.identification.side_angle.with_side_angle`: anchored in
            every reading); None: ``angle``.
    """

    names: tuple[str, ...]
    u: np.ndarray
    omega: np.ndarray
    angle: np.ndarray
    mask: np.ndarray
    dt: float
    side: int | None = None
    gyro_average: bool = False
    integration: Integration = DEFAULT_INTEGRATION
    first_reading: np.ndarray | None = None
    rest_level: np.ndarray | None = None
    side_follows_gyro: bool = True
    resolver_side: np.ndarray | None = None
    fusion_accel: np.ndarray | None = None
    deflection_rate: np.ndarray | None = None
    angle_step: np.ndarray | None = None
    angle_plain: np.ndarray | None = None
    torque_angle: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        """Samples that count, summed over the runs."""
        return int(self.mask.sum())

    @property
    def breaks(self) -> list[int]:
        """Where each run starts in `flat`'s vector, and its end: (R+1,)."""
        return [0, *np.cumsum(self.mask.sum(axis=1)).tolist()]

    def flat(self, x: np.ndarray) -> np.ndarray:
        """The counted samples of ``x`` (..., R, N), concatenated: (..., M)."""
        # Boolean indexing of the last axes leaves the result strided along
        # M; sums along M (the costs) then add in another order than over a
        # contiguous row, and a cost would depend on the batch it was in.
        return np.ascontiguousarray(x[..., self.mask])

    def deflection(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The counted samples of `deflection_rate` [rad/s] and, beside them,
        the part of it the measured angle's quantization would make if the
        axis turned at its mean rate reading [rad/s]; None where the
        deflection is not known.

        The resolver's difference quotient carries its quantization, a
        pattern that repeats each quantum the axis turns: where the axis
        holds its rate (a saturated command's plateau), a line at that
        repetition rate (`Resonance.deflection_peak`). Here the rate reading
        averaged over `LINE_WINDOW` samples is integrated, quantized by
        `angle_step` and differenced again: the same lines, at the same
        rates. An angle that is not quantized changes by tiny steps, and its
        rebuild is as small; one that never changes has none (0).
        """
        if self.deflection_rate is None or self.angle_step is None:
            return None
        kernel = np.ones(LINE_WINDOW) / LINE_WINDOW
        lines = np.zeros_like(self.omega)
        for i, (w, step) in enumerate(zip(self.omega, self.angle_step)):
            if step > 0.0:
                mean = np.convolve(w, kernel, "same")
                quantized = step * np.round(np.cumsum(mean) * self.dt / step)
                lines[i, 1:] = np.diff(quantized) / self.dt - mean[1:]
        return self.flat(self.deflection_rate), self.flat(lines)


#: Samples the rate reading is averaged over in `RunStack.deflection` [1]:
#: its error moves the rebuilt line of order k by k times the error over the
#: angle's quantum. With 21 samples (a 14-bit resolver, 0.05 deg/s of gyro
#: noise: 0.5 Hz per order) a line of high order from a rate held for 6 s
#: escaped the rebuild in 1 of 8 noise draws (tests/test_deflection_lines.py);
#: with 51, in none. A rate that changes makes no line, so the longer mean
#: costs nothing.
LINE_WINDOW = 51

#: Rate beyond which a simulated variant has diverged [rad/s]; its reading is
#: held there, so it loses by a large, finite error.
DIVERGED = 1e3
#: Samples at the start of each run that do not count [1]: the simulation
#: starts from the measured (noisy) rate, and which way the first stick/slip
#: decisions go takes a few time constants (1/(1-a) ~ 10 samples) to forget.
WARMUP = 50


def stack_runs(
    runs: Sequence,
    warmup: int = WARMUP,
    side: int | None = None,
    gyro_average: bool = False,
    integration: Integration = DEFAULT_INTEGRATION,
    rest: float | None = None,
    side_follows_gyro: bool | None = None,
) -> RunStack:
    """Stack runs (`isp_twin.identification.measured.MeasuredData` or anything with
    ``name, u, omega, angle, dt``).

    Args:
        runs: the runs; ``angle`` is the angle that chooses the half-plane
            and that angle-dependent effects see.
        warmup: samples at each run's start that do not count (at least 1:
            sample 0 is the initial state).
        side, gyro_average, integration, side_follows_gyro: as `RunStack`'s;
            side_follows_gyro None: whether the runs carry the fused angle
            (a ``resolver`` kept beside it, `side_angle.with_side_angle`):
            a raw resolver's angle is the motor side's already.
        rest: a first measured rate at most this large [rad/s], or at most
            three noise standard deviations (the noise from the run's first
            2000 samples), starts the model at rest; None: the noise's level
            alone (why both: docs/identification.md "Stop 41").

    Raises:
        DataError: no runs, or runs with different sample periods.
    """
    dt = _common_period(runs)
    n = max(len(r.u) for r in runs)
    shape = (len(runs), n)
    u, omega, angle = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    mask = np.zeros(shape, dtype=bool)
    first, levels = np.zeros(len(runs)), np.zeros(len(runs))
    for i, r in enumerate(runs):
        m = len(r.u)
        u[i, :m] = r.u
        omega[i, :m] = r.omega
        angle[i, :m] = r.angle
        angle[i, m:] = r.angle[-1]
        mask[i, min(max(warmup, 1), m - 1) : m] = True
        # The first measured rate is the initial state; a reading within the
        # rest level is rest (the stiction branch of Eq. 5), not a slow
        # motion in the direction of the noise.
        level = 3.0 * noise_floor_of([r.omega[:2000]], SCALE_DIFFERENCE) if m > 8 else -1.0
        if rest is not None:
            level = max(rest, level)
        first[i], levels[i] = r.omega[0], level
        if abs(r.omega[0]) <= level:
            omega[i, 0] = 0.0
    names = tuple(r.name for r in runs)
    stacked = (names, u, omega, angle, mask, dt, side, gyro_average, integration, first, levels)
    known, accel, plain, torque = _resolver_columns(runs, shape, angle)
    fused = known is not None
    follows = fused if side_follows_gyro is None else side_follows_gyro
    slip, steps = _deflection_rates(runs, shape, dt)
    return RunStack(*stacked, follows, known, accel, slip, steps, plain, torque)


def _resolver_columns(runs: Sequence, shape: tuple[int, int], angle: np.ndarray) -> tuple:
    """`RunStack`'s resolver_side, fusion_accel, angle_plain and torque_angle
    (``angle``, the stacked side angles, where a run has no plain or torque
    one), from the runs that carry the fused angle with the resolver's
    beside it (`side_angle.with_side_angle`); four Nones where none does."""
    if all(getattr(r, "resolver", None) is None for r in runs):
        return None, None, None, None
    known, accel = np.zeros(shape, dtype=np.int8), np.zeros(shape)
    plain, torque = angle.copy(), angle.copy()
    for i, r in enumerate(runs):
        if getattr(r, "resolver", None) is not None:
            m = len(r.u)
            known[i, :m] = resolver_sides(r.resolver)
            accel[i, :m] = r.fusion_accel
            for out, given in ((plain, r.fusion_plain), (torque, r.torque_angle)):
                if given is not None:
                    out[i, :m] = given
                    out[i, m:] = given[-1]
    return known, accel, plain, torque


def _deflection_rates(
    runs: Sequence, shape: tuple[int, int], dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """`RunStack.deflection_rate` and `RunStack.angle_step`: each run's rate
    reading minus the difference quotient of its measured angle (the
    resolver's, kept beside a fused angle), 0 at each run's first sample and
    beyond its end; and that angle's smallest non-zero change."""
    slip, steps = np.zeros(shape), np.zeros(shape[0])
    for i, r in enumerate(runs):
        measured = getattr(r, "resolver", None)
        measured = r.angle if measured is None else measured
        m = len(r.u)
        change = np.diff(np.asarray(measured[:m], float))
        slip[i, 1:m] = np.asarray(r.omega[1:m], float) - change / dt
        moved = np.abs(change[change != 0.0])
        steps[i] = moved.min() if moved.size else 0.0
    return slip, steps


def resolver_sides(angle: np.ndarray) -> np.ndarray:
    """Per step k -> k+1, the half-plane the resolver's reading settles, int8 (N,):
    +1 (R) or -1 (L) where it reads a non-zero angle of one sign at both ends,
    else 0 (a reading of 0 holds angles of either sign within its quantum).

    The fused angle follows the gyro, and a gyro on a flexible payload reads
    the payload's ringing: the sub-stepped model takes its own deflection
    off (`isp_twin.model.substep_model`), and where that leaves the side
    the resolver contradicts, the resolver's side holds.
    """
    a = np.sign(np.asarray(angle, dtype=float)).astype(np.int8)
    out = np.zeros_like(a)
    out[:-1] = np.where(a[:-1] == a[1:], a[:-1], 0)
    return out


def _common_period(runs: Sequence) -> float:
    """The runs' sample period [s].

    Raises:
        DataError: no runs, or runs with different sample periods.
    """
    if not runs:
        raise DataError("no data sets given")
    dt = float(runs[0].dt)
    for r in runs:
        if abs(float(r.dt) - dt) > SAMPLE_PERIOD_TOLERANCE * dt:
            raise DataError(
                f"{r.name}: sample period {r.dt} s differs from {runs[0].name}'s {dt} s; "
                "all data sets of one fit need the same period"
            )
    return dt


def _initial_rates(stack: RunStack, effects: Sequence, p: int) -> np.ndarray:
    """The model's rate at sample 0 per row (set-major, (P*R,)) [rad/s].

    The first reading is the initial state. Where a sensor effect says what
    true rate a reading means (`Effect.true_rate`: a gyro bias reads b at
    rest), the reading is mapped back first and the rest rule (`stack_runs`)
    applied to that rate: a biased gyro's first reading is not a motion.
    """
    omega0 = np.tile(stack.omega[:, 0], p)
    if not any(e.maps_readings for e in effects) or stack.first_reading is None:
        return omega0
    rate = true_rates(effects, np.tile(stack.first_reading, p))
    rate = np.broadcast_to(np.asarray(rate, float), omega0.shape).copy()
    rate[np.abs(rate) <= np.tile(stack.rest_level, p)] = 0.0
    return rate


def relative_stack(
    stack: RunStack, effects: Sequence[str], substeps: int | None = JACOBIAN_SUBSTEPS
) -> RunStack | None:
    """`stack` integrated with `substeps` sub-steps per sample, for the
    points the least squares of a model with the `effects` (names) only
    compare among themselves (finite-difference columns, diagnose's static
    scan: `isp_twin.estimation.least_squares.Relative`); None where they
    take the model's own: `substeps` None, not below the stack's, or an
    effect whose slopes need the model's own (`Effect.fine_slopes`)."""
    own = stack.integration.substeps
    if substeps is None or own <= substeps:
        return None
    if any(effect_class(n).fine_slopes for n in effects):
        return None
    return replace(stack, integration=replace(stack.integration, substeps=substeps))


def predict(
    stack: RunStack,
    rate_vectors: np.ndarray,
    effects: Sequence[tuple[str, Mapping[str, np.ndarray]]] = (),
    fixed: Sequence[EffectSpec] = (),
):
    """Simulate P model variants on every run of the stack.

    Args:
        stack: the runs.
        rate_vectors: rate-form parameters, (P, `RATE_LAYOUT.size`) (`RateParams.to_vector`).
        effects: (name, parameter name -> array (P,)) of effects that vary with the set.
        fixed: effects with the same parameters for every set.

    Returns:
        `AxisResponse` with arrays of shape (P, R, N).
    """
    x = np.atleast_2d(rate_vectors)
    p, r, n = x.shape[0], stack.u.shape[0], stack.u.shape[1]
    rows = np.repeat(x, r, axis=0)  # set-major: row = set*R + run
    batch = []
    for name, params in effects:
        batch.append(
            make_batched(
                name, {k: np.repeat(np.asarray(v, float), r) for k, v in params.items()}, stack.dt
            )
        )
    for spec in fixed:
        batch.append(
            make_batched(
                spec.name, {k: np.full(p * r, v) for k, v in spec.params.items()}, stack.dt
            )
        )
    angle, resolver_side, torque = _side_angles(stack, batch, p)
    resp = simulate_substeps(
        RateParams.from_vector(rows),
        np.tile(stack.u, (p, 1)),
        stack.dt,
        omega0=_initial_rates(stack, batch, p),
        angle0=np.tile(stack.angle[:, 0], p),
        angle_measured=angle,
        effects=batch,
        side=stack.side,
        integration=stack.integration,
        gyro_average=stack.gyro_average,
        side_follows_gyro=stack.side_follows_gyro,
        resolver_side=resolver_side,
        torque_angle=torque,
    )
    return _diverged_held(resp).mapped(lambda a: a.reshape(p, r, n))


def _side_angles(stack: RunStack, effects: Sequence, p: int):
    """The angle choosing the half-plane per row (P*R, N), the resolver's
    sides (or None) and the angle a torque of the angle reads (or None:
    the side angle). The stack's angles; where they are the fused ones and
    an effect deflects the gyro from the motor side, the side angle plus
    what the fusion's smoothing took off that deflection
    (`Effect.fusion_gain`), with the sides the resolver settles, and the
    torques read that angle too. Rows without such an effect need neither.
    Rows with one take the fusion alone (`RunStack.angle_plain`): the edge
    anchors assume a gyro on the motor side."""
    angle = np.tile(stack.angle, (p, 1))
    torque = None
    if stack.torque_angle is not None and any(is_torque(e) for e in effects):
        torque = np.tile(stack.torque_angle, (p, 1))
    gains = [g for g in (e.fusion_gain() for e in effects) if np.ndim(g)]
    if stack.fusion_accel is None or not stack.side_follows_gyro or not gains:
        return angle, None, torque
    deflected = np.any([np.asarray(g) != 0.0 for g in gains], axis=0)
    if stack.angle_plain is not None:
        angle[deflected] = np.tile(stack.angle_plain, (p, 1))[deflected]
    accel = np.tile(stack.fusion_accel, (p, 1))
    for gain in gains:
        angle += gain[:, None] * accel
    if torque is not None:
        torque[deflected] = angle[deflected]
    return angle, np.tile(stack.resolver_side, (p, 1)), torque


def _diverged_held(resp):
    """The response with a diverging variant's reading held at `DIVERGED`.

    A diverging variant is a bad parameter set, not an error: it loses by a
    large, finite error (its square must not overflow).
    """
    if np.all(np.abs(resp.omega) <= DIVERGED):  # False on NaN too
        return resp
    held = np.clip(np.nan_to_num(resp.omega, nan=DIVERGED), -DIVERGED, DIVERGED)
    return replace(resp, omega=held)


def predict_one(stack: RunStack, rate_vector: np.ndarray, fixed: Sequence[EffectSpec] = ()):
    """`predict` for one rate vector (`RATE_LAYOUT.size`,) with `fixed`
    effects: an `AxisResponse` of arrays (R, N)."""
    return predict(stack, np.asarray(rate_vector)[None], (), fixed).mapped(lambda a: a[0])


def residuals(stack: RunStack, rate_vectors, effects=(), fixed=()) -> np.ndarray:
    """Measured minus simulated rate on the counted samples, shape (P, M) [rad/s]."""
    resp = predict(stack, rate_vectors, effects, fixed)
    return stack.flat(stack.omega[None] - resp.omega)


def residuals_many(
    stack: RunStack,
    requests: Sequence[tuple[np.ndarray, str | None, Mapping[str, np.ndarray]]],
    fixed: Sequence[EffectSpec] = (),
) -> list[np.ndarray]:
    """Residuals of several model variants with different effects.

    The requests naming the same effect (or none) are simulated together,
    each group with its own effect alone: a row that carried every other
    group's effect at its ``null`` parameters cost what all of them cost
    (diagnose's first refit of the whole library: 9.9 ms a row of 2 x 6000
    samples, 5.9 grouped; a bare row 3.8, a resonance row 9.8).

    Args:
        stack: the runs.
        requests: (rate vectors (P_i, `RATE_LAYOUT.size`), effect name or
            None, effect parameter name -> (P_i,)) per request.
        fixed: effects shared by all.

    Returns:
        One array (P_i, M) per request [rad/s].
    """
    groups: dict[str | None, list[int]] = {}
    for i, (_, name, _) in enumerate(requests):
        groups.setdefault(name, []).append(i)
    out: list[np.ndarray] = [np.empty(0)] * len(requests)
    for name, members in groups.items():
        xs = [np.atleast_2d(requests[i][0]) for i in members]
        effects = [(name, _columns(name, [requests[i][2] for i in members], xs))] if name else []
        res = residuals(stack, np.concatenate(xs), effects, fixed)
        for i, part in zip(members, np.split(res, np.cumsum([x.shape[0] for x in xs])[:-1])):
            out[i] = part
    return out


def _columns(name: str, params: Sequence[Mapping], xs: Sequence[np.ndarray]) -> dict:
    """Effect `name`'s parameter columns over the rows of several requests
    (`params[i]` broadcast over the rows of `xs[i]`)."""
    return {
        p: np.concatenate(
            [np.broadcast_to(q[p], (x.shape[0],)) for q, x in zip(params, xs)]
        ).astype(float)
        for p in effect_class(name).param_names
    }
