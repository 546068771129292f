"""Eq. 6 integrated in m sub-steps per sample: the model identification and diagnosis fit.

Eq. 6 holds the friction over the whole sample. On a fast axis (mechanical
time constant of a few ms, a sharp Stribeck drop, a breakaway or reversal
inside a sample) that cannot represent a real axis: on the reference
simulator even the true parameters written in Eq. 6 form leave 3-17 noise
floors on held-out runs (docs/identification.md). This module integrates the
same physics in its continuous form with `Integration.substeps` steps per
sample, the parameters still in the paper's per-sample rate form
(`RateParams`: pole a, gain b·Ke, levels b·Ts, b·Tc per sample, alpha).

Per sub-step of length T/m, regime r (rate form per sample):

    p = a**(1/m),  c = (1 - p) / (1 - a)
    w <- p w + c (b·Ke u + accel T) - c sgn(w) b·Tf(w)

the exact zero-order hold of ``J dw/dt = Km u - eta w - F`` over T/m with F
held over the sub-step, so m sub-steps of a constant drive give exactly
Eq. 6's sample (c -> 1 at m = 1). The command is held over the sample (a
fractional input delay switches it inside the sample, at the sub-step the
switch falls in: `Effect.command_run_split`);
effects (`isp_twin.model.effects`) are evaluated once per sample, at the angle that
selects the half-plane and the rate at the sample's start, and their
acceleration is held over its sub-steps like the command (their command and
measure hooks act per sample too); with ``exact_effect_hold`` the
acceleration gets the exact hold factor ``(1 - p)/(-ln a)`` per sub-step
instead of c (`_substep_table`). LuGre's bristles (`Effect.in_substeps`,
m > 1) are friction, not a held acceleration: their force ``sigma0 z`` is
held over each sub-step beside Eq. 5's (z at mid-travel with the midpoint
friction), z follows ``dz/dtheta = 1 - sgn(w) z / z_max`` exactly over the
sub-step's travel, it is held at rest, and a breakaway that passes the
Karnopp test but whose rate the bristle force turns back stays stuck (the
reference simulator's stick logic, `isp_twin.reference.axis`). The stick test
of Eq. 5 is made at every sub-step. With ``midpoint_friction`` the sliding friction is taken at the mean
of the sub-step's start rate and a predicted end rate (second order in the
sub-step), the sub-step that breaks away included (its start rate is 0,
`_breakaway_friction`); with ``split_reversals`` a sub-step in which the rate reaches zero
ends there and the rest of it is spent on the stick/breakaway decision
(a Karnopp band that cannot swallow part of a sub-step of motion). At rest
the motor gain is the command's sign's regime's (Eq. 6), or with
``rest_drive_gain`` the regime the total drive breaks towards: they differ
only where an effect's torque opposes the command (`_rest_regime`). The gyro
reading is the rate at the sample instant, or its mean over the sample's
sub-steps (trapezoid; with m = 1 the mean of both ends, `gyro_reading`).
The half-plane of sub-step j of the step into sample k is read from the given
angle at ``k - 1 + j/m`` (linear interpolation), or from the model's own
angle ``y += (T/m) w``; with ``split_sides`` a sub-step whose angle crosses 0
by its end takes each side's regime for its part of it.

`EQ6` (m = 1, every option off) is Eq. 6 exactly as
`isp_twin.model.axis_model.simulate` computes it, up to the last bit of ``exp``
(numpy's vectorized exp and the C library's differ by one ulp on a few
per cent of arguments; with alpha = 0 the two agree bit for bit,
`tests/test_substep_model.py`).

The kernel is compiled with numba: a stick-slip loop over (rows, samples,
sub-steps) that numpy cannot vectorize along time. Its rows (parameter sets x
runs) are independent: it advances `GROUP_ROWS` of them side by side, one
sub-step at a time (the processor overlaps their dependency chains: 0.67x the
CPU time of a row-by-row loop, `benchmarks/substep_speed.py`), and a large
batch is split in blocks over numba's threads (``NUMBA_NUM_THREADS``; 1 turns
it off). Every row does the same operations in the same order whatever the
grouping or the threads: the numbers are the row-by-row loop's, bit for bit
(`tests/test_substep_model.py`).
"""

from __future__ import annotations

import cmath
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from isp_twin.errors import ParameterError
from isp_twin.model import friction_compiled as law
from isp_twin.model.axis_model import AxisResponse
from isp_twin.model.effects import Effect
from isp_twin.model.friction_compiled import law_probe_cases, python_law
from isp_twin.model.parameters import RateParams
from isp_twin.vocabulary import check_side

__all__ = ["Integration", "EQ6", "DEFAULT_INTEGRATION", "simulate_substeps", "is_torque"]


#: Bits of the kernel's ``split`` mask (`Integration.kernel_flags`).
SPLIT_REVERSALS = 1
SPLIT_SIDES = 2


@dataclass(frozen=True)
class Integration:
    """How the model integrates one sample (see module doc).

    Attributes:
        substeps: m, integration steps per sample [1] (>= 1).
        midpoint_friction: sliding friction at the sub-step's mean rate,
            the breakaway's sub-step included.
        split_reversals: a sub-step that reaches rate 0 decides stick or
            breakaway for its remaining part.
        exact_effect_hold: an effect's acceleration (torque/J) held over the
            sample moves the rate by its exact zero-order hold,
            ``accel*T*(1 - a)/(-ln a)``, instead of Eq. 6's ``accel*T`` (the
            twin's explicit-Euler convention, docs/axis_model.md): 5 % apart
            for a 10 ms axis, which left the true cable spring of a reference
            axis at 3.7 noise sigmas.
        midstep_angle: a torque of the measured angle (cogging, spring,
            unbalance) taken at the step's mean angle, the mean of the
            angles at its two ends, instead of the angle at its start: held
            from the start, a spring lags by half a sample, a drive error of
            ``k w T / 2`` that the pole integrates (reference cable_spring
            seed 2 with its true parameters: 3.10 -> 1.00 noise floors on
            train1; docs/diagnosis.md "Stop 20").
        rest_drive_gain: at rest, the motor gain of the regime the total
            drive breaks towards (+ where ``g+ u + e`` passes Ts+, else -
            where ``g- u + e`` passes -Ts-), as a physical axis does,
            instead of the gain of the command's sign (Eq. 6 and the twin,
            `axis_model.simulate`). The two differ only where an effect's
            torque e opposes the command (reference cable_spring seed 3
            with its true parameters: 3.91 -> 1.13 noise floors on train2;
            docs/diagnosis.md "Stop 21"). At angle 0 a break towards +
            must also pass L+'s level, Eq. 5's Y = 0 (`_rest_regime`).
        split_sides: a sub-step in which the angle choosing the half-plane
            crosses 0 takes the regime of each side for its part of the
            sub-step (pole, drive and friction weighted by time), instead
            of the start's regime for all of it: read at the start, the
            switch lags by half a sub-step on average, and a jump of the
            motor gain between the sides then drives the wrong impulse at
            every crossing (reference resonance seed 79 with its true
            parameters: 1.38 -> 1.01 noise sigmas on train1, its payload
            rung by the jump; docs/diagnosis.md "Stop 34"). On by default
            since stop 38 (``--no-split-sides`` turns it off): on the
            low-noise reference axes the lag alone put the truth at 1.4
            noise sigmas, and the fits bent the friction levels to absorb
            it (docs/diagnosis.md "Stop 38").
    """

    substeps: int = 10
    midpoint_friction: bool = True
    split_reversals: bool = True
    exact_effect_hold: bool = True
    midstep_angle: bool = True
    rest_drive_gain: bool = True
    split_sides: bool = True

    def __post_init__(self):
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ParameterError(f"substeps must be an integer >= 1, got {self.substeps}")

    @property
    def opens_on_boundary(self) -> bool:
        """A run whose resolver reads 0 at its start starts on the boundary
        (`isp_twin.identification.side_angle.at_boundary`): sub-steps follow
        a continuous axis, which enters the side of its motion at once; one
        step per sample (Eq. 6, the twin) takes its first step from angle 0
        itself, on Eq. 5's side of 0 (docs/identification.md "Stop 41")."""
        return self.substeps > 1

    def kernel_flags(self) -> tuple[bool, int, bool]:
        """The sub-step kernel's switches, in its argument order (`_advance`):
        the splits as a mask of `SPLIT_REVERSALS` and `SPLIT_SIDES`."""
        split = SPLIT_REVERSALS * bool(self.split_reversals) + SPLIT_SIDES * bool(self.split_sides)
        return self.midpoint_friction, split, self.rest_drive_gain

    def to_json(self) -> dict:
        """The ``integration`` block of identify's and diagnose's JSON records."""
        return {
            "substeps_per_sample": self.substeps,
            "midpoint_friction": self.midpoint_friction,
            "split_reversals": self.split_reversals,
            "exact_effect_hold": self.exact_effect_hold,
            "midstep_angle": self.midstep_angle,
            "rest_drive_gain": self.rest_drive_gain,
            "split_sides": self.split_sides,
        }

    def describe(self) -> str:
        if self == EQ6:
            return "Eq. 6 (friction held over the sample)"
        extras = [
            s
            for s, on in (
                ("midpoint friction", self.midpoint_friction),
                ("reversals split", self.split_reversals),
                ("exact hold of effects", self.exact_effect_hold),
                ("angle torques at mid-step", self.midstep_angle),
                ("rest gain of the drive", self.rest_drive_gain),
                ("side changes split", self.split_sides),
            )
            if on
        ]
        return f"{self.substeps} sub-steps per sample" + (
            f" ({', '.join(extras)})" if extras else ""
        )


#: Eq. 6 as the paper writes it.
EQ6 = Integration(1, False, False, False, False, False, False)
#: The model identification and diagnosis fit by default (docs/identification.md).
DEFAULT_INTEGRATION = Integration()


#: Columns of the per-row coefficients of effects integrated in the sub-steps
#: (`Effect.in_substeps`; ``sfx`` of `_advance_group`): LuGre's bristle drive
#: ``accel_rad_s2 * T`` [rad/s per sample] and its pre-sliding distance [rad];
#: a two-mass payload's J2/J1 [1], the spring's acceleration on the motor
#: side per payload coordinate y [1/s^2] and per y' [1/s], and the mode's
#: transition over a sub-step, free (Phi, Gamma) and with the motor side
#: clamped (Phi), and the gyro's coupling c: it reads ``w + (r + c) y'``
#: (`isp_twin.model.effects.resonance.Resonance`).
STATE_COLUMNS: tuple[str, ...] = (
    "bristle_drive",
    "presliding_rad",
    "payload_ratio",
    "spring_y",
    "spring_yd",
    *(f"free_{c}" for c in ("00", "01", "10", "11", "g0", "g1")),
    *(f"clamped_{c}" for c in ("00", "01", "10", "11")),
    "gyro_coupling",
)
#: `use_side` of the kernel when the measured angle is the fused one (`simulate_substeps`).
SIDE_FOLLOWS_GYRO = 2

#: Defaults of the columns no effect gives (no bristle force).
_COLUMN_DEFAULTS = {"bristle_drive": 0.0, "presliding_rad": 1.0}


@njit(cache=True, nogil=True)
def _part_before(a, a_end):  # pragma: no cover - compiled
    """The part of a sub-step before its angle, going from `a` to `a_end`
    (linear in time), crosses 0."""
    if a == a_end:
        return 1.0
    return min(max(a / (a - a_end), 0.0), 1.0)


@njit(cache=True, nogil=True)
def _sliding_in(table, i, ix, w):  # pragma: no cover - compiled
    """Eq. 5's sliding friction of regime `ix` at rate `w` [rate per sub-step]."""
    return law.sliding(w, table[i, ix, 2], table[i, ix, 3], table[i, ix, 4])


@njit(cache=True, nogil=True)
def _breakaway_friction(table, i, ix, w_end):  # pragma: no cover - compiled
    """The sliding friction of a sub-step that breaks away in regime `ix`:
    Eq. 5's at the mean of its rates, 0 and the end rate `w_end` that Ts
    over all of it gives (`Integration.midpoint_friction`). Ts over all of
    it, a steep Stribeck curve (alpha times the sub-step's rate change of
    order 1) left the breakaway of a 6 ms reference axis 9 noise sigmas
    slow at the first sample (docs/identification.md "Stop 42")."""
    return law.sliding(0.5 * w_end, table[i, ix, 2], table[i, ix, 3], table[i, ix, 4])


@njit(cache=True, nogil=True)
def _rigid_row(coef, bristles, payload):  # pragma: no cover - compiled
    """Whether a row's breakaway is the rigid axis' alone: no LuGre bristles
    and no payload mode on the motor side (those rows break away through
    `_break_through_bristles` and `_payload_motion`)."""
    return not (bristles and coef[0] != 0.0) and not (payload and coef[2] != 0.0)


@njit(cache=True, nogil=True)
def _across_sides(table, i, ix2, q, w, uk, ek, p, drive, slide):  # pragma: no cover - compiled
    """(pole, drive, sliding friction) of a sub-step whose angle changes side
    after its part `q`: the start regime's (`p`, `drive`, `slide`) over q, the
    regime `ix2` of the other side over the rest, weighted by time (to first
    order in the sub-step, as the reference ends its step at the crossing)."""
    r = 1.0 - q
    p2 = table[i, ix2, 0]
    drive2 = table[i, ix2, 1] * uk + table[i, ix2, 5] * ek
    return q * p + r * p2, q * drive + r * drive2, q * slide + r * _sliding_in(table, i, ix2, w)


@njit(cache=True, nogil=True)
def _payload_motion(coef, yp, ydp, w1, w_rigid, h):  # pragma: no cover - compiled
    """A sub-step of the motor side (rate ``w1``) with the payload's mode.

    ``w_rigid`` is the motor rate the sub-step would reach on a rigid axis
    (friction and viscous torque at ``w1``); ``w_rigid - w1`` is then the
    centre-of-mass rate's increment (the spring is internal), which drives
    the mode ``y'' + 2 zeta wn y' + wn^2 y = -w'`` held over the sub-step.
    Returns the motor rate ``w_rigid - r (y'_new - y')`` and (y, y') new.
    """
    a = (w_rigid - w1) / h
    y_new = coef[5] * yp + coef[6] * ydp + coef[9] * a
    yd_new = coef[7] * yp + coef[8] * ydp + coef[10] * a
    return w_rigid - coef[2] * (yd_new - ydp), y_new, yd_new


@njit(cache=True, nogil=True)
def _regime_at(angle, direction, fixed_side):  # pragma: no cover - compiled
    """The regime for a motion in `direction` at `angle` (`law.side_of`),
    the side `fixed_side` instead when it is >= 0."""
    side = fixed_side if fixed_side >= 0 else law.side_of(angle, direction)
    return law.regime_of(side, direction)


@njit(cache=True, nogil=True)
def _rest_regime(table, i, a, uk, ek, fixed_side, by_drive):  # pragma: no cover - compiled
    """At rest, the regime whose motor gain drives the step, or -1 where the
    axis stays stuck whatever the command's sign says (`by_drive` only).

    Without `by_drive` the command's sign picks it (`axis_model.simulate`).
    With it, the axis breaks towards + where the + regime's drive ``g+ u +
    f e`` passes Ts+, else towards - where ``g- u + f e`` passes -Ts-
    (`Integration.rest_drive_gain`); ek is the extra drive in effect units.
    At angle 0 (on the boundary) a break towards + must pass L+'s level
    too: Eq. 5 puts Y = 0 in L, and the motion then enters Y > 0, where R+
    holds (the reference simulator's continuous axis; docs/identification.md
    "Stop 42").
    """
    if not by_drive:
        return _regime_at(a, uk, fixed_side)
    rp = _regime_at(a, 1.0, fixed_side)
    if table[i, rp, 1] * uk + table[i, rp, 5] * ek > table[i, rp, 2]:
        if a != 0.0 or fixed_side >= 0:
            return rp
        rl = _regime_at(-1.0, 1.0, -1)  # L+, Eq. 5's regime of Y = 0
        if table[i, rl, 1] * uk + table[i, rl, 5] * ek > table[i, rl, 2]:
            return rp
    rm = _regime_at(a, -1.0, fixed_side)
    if table[i, rm, 1] * uk + table[i, rm, 5] * ek < -table[i, rm, 2]:
        return rm
    return -1


@njit(cache=True, nogil=True)
def _rest_drive(
    table, i, a, uk, ek, dt, spring, fixed_side, by_drive
):  # pragma: no cover - compiled
    """At rest: whether the axis may break away (`_rest_regime`), the drive
    ``d`` of the regime whose gain acts [rate per sub-step], the motor side's
    drive ``dd`` with a payload spring's pull ``spring`` [rad/s^2] (0 on a
    rigid axis) and the regime it breaks towards."""
    r0 = _rest_regime(table, i, a, uk, ek + dt * spring, fixed_side, by_drive)
    free = r0 >= 0
    if not free:
        r0 = _regime_at(a, uk, fixed_side)
    d = table[i, r0, 1] * uk + table[i, r0, 5] * ek
    dd = d + table[i, r0, 5] * dt * spring
    return free, d, dd, _regime_at(a, dd, fixed_side)


@njit(cache=True, nogil=True)
def _payload_clamped(coef, yp, ydp):  # pragma: no cover - compiled
    """The payload ringing over a sub-step with the motor side stuck:
    ``(1 + r) y'' + 2 zeta wn y' + wn^2 y = 0`` (the clamped frequency)."""
    return coef[11] * yp + coef[12] * ydp, coef[13] * yp + coef[14] * ydp


@njit(cache=True, nogil=True)
def _mode_over(wn, zeta, t, y, yd, a):  # pragma: no cover - compiled
    """The mode ``y'' + 2 zeta wn y' + wn^2 y = -a`` (a held) over any span t:
    (y, y') after it, exactly (``Phi = c0 I + c1 A`` from the two roots, as
    `isp_twin.model.effects.resonance._discretize` over a sub-step)."""
    if abs(zeta - 1.0) < 1e-6:  # repeated roots make the formula 0/0
        zeta = 1.0 + 1e-6
    root = cmath.sqrt(complex(zeta * zeta - 1.0, 0.0))
    l1 = wn * (-zeta + root)
    l2 = wn * (-zeta - root)
    e1 = cmath.exp(l1 * t)
    e2 = cmath.exp(l2 * t)
    c0 = ((l1 * e2 - l2 * e1) / (l1 - l2)).real
    c1 = ((e1 - e2) / (l1 - l2)).real
    y_ss = -a / (wn * wn)  # the deflection the held acceleration settles at
    e = y - y_ss
    return y_ss + c0 * e + c1 * yd, c0 * yd - c1 * (wn * wn * e + 2.0 * zeta * wn * yd)


@njit(cache=True, nogil=True)
def _payload_stop(
    table, i, a, uk, ek, fixed_side, by_drive, coef, wb, w_new, ydp, ydn, yp, h, dt
):  # pragma: no cover - compiled
    """The motor side of a two-mass axis (r > 0) stops inside a sub-step.

    ``w_new`` and ``ydn`` are the sub-step taken whole from the rate ``wb``
    (`_payload_motion`). The stop falls at the part ``wb / (wb - w_new)`` of
    it (the rate linear in time, as a rigid axis's split); the payload moves
    free up to it under the centre-of-mass acceleration, and the rest of the
    sub-step starts at rest: a breakaway where the drive with the spring's
    pull passes the static level (the payload driven again), else the
    payload rings with the motor side clamped. As the reference integrates
    its payload between events (`isp_twin.reference.axis`). Returns the
    motor rate and the payload's (y, y') at the sub-step's end.
    """
    r = coef[2]
    wn = np.sqrt(coef[3] * (1.0 + r) / r)  # spring_y = r/(1+r) wn^2
    zeta = coef[4] * (1.0 + r) / (2.0 * r * wn)  # spring_yd = r/(1+r) 2 zeta wn
    part = wb / (wb - w_new)
    accel = (w_new + r * (ydn - ydp) - wb) / h  # the centre of mass's, while moving
    y1, yd1 = _mode_over(wn, zeta, part * h, yp, ydp, accel)
    left = (1.0 - part) * h
    spring = coef[3] * y1 + coef[4] * yd1  # its pull on the motor side
    free, d, dd, ix = _rest_drive(table, i, a, uk, ek, dt, spring, fixed_side, by_drive)
    if free and abs(dd) > table[i, ix, 2] and left > 0.0:
        wc = (1.0 - part) * (d - law.stiction(dd, table[i, ix, 2]))
        y2, yd2 = _mode_over(wn, zeta, left, y1, yd1, wc / left)
        w1 = wc - r * (yd2 - yd1)
        if w1 * dd > 0.0:
            return w1, y2, yd2
    stretch = np.sqrt(1.0 + r)
    y2, yd2 = _mode_over(wn / stretch, zeta / stretch, left, y1, yd1, 0.0)
    return 0.0, y2, yd2


@njit(cache=True, nogil=True)
def _bristles(z, direction, travel, zmax):  # pragma: no cover - compiled
    """LuGre's bristle deflection after ``travel`` [rad] in ``direction``:
    ``dz/dtheta = 1 - sgn(w) z / z_max`` solved exactly (the reference's form)."""
    z_ss = zmax if direction > 0.0 else -zmax
    return z_ss + (z - z_ss) * np.exp(-abs(travel) / zmax)


@njit(cache=True, nogil=True)
def _break_through_bristles(w_new, d, part, hold, coef, z, b, h):  # pragma: no cover - compiled
    """A breakaway from rest against the bristle force: the rate ``w_new``
    reached over ``part`` of a sub-step past the Karnopp test, less ``sigma0 z``
    held over it (``hold``: the sub-step's exact-hold factor); none if the
    bristles hold the axis (the rate would not follow the drive ``d``, as in
    the reference). Moves z over the travel (the rate rising linearly)."""
    w_new -= part * hold * coef[0] * z[b] / coef[1]
    if w_new * d <= 0.0:
        return 0.0
    z[b] = _bristles(z[b], w_new, 0.5 * h * part * w_new, coef[1])
    return w_new


@njit(cache=True, nogil=True)
def _advance_group(
    table,
    u,
    extra,
    side_y,
    use_side,
    fixed_side,
    k_lo,
    k_hi,
    m,
    dt,
    mid,
    split,
    by_drive,
    w_state,
    y_state,
    point,
    reading,
    angle,
    regime,
    r_lo,
    r_hi,
    frac,
    scratch,
    idx,
    sfx,
    kstate,
    lead,
    known,
):  # pragma: no cover - compiled
    """Advance rows r_lo..r_hi-1 from sample k_lo-1 to k_hi-1 (writes columns k_lo..k_hi-1).

    table: (S, 4, 6) per-sub-step (p, c·gain, c·static, c·coulomb, alpha,
    effect factor) (`_substep_table`); u, extra: (S, N) per-sample command
    and extra drive [rate form per sample]; side_y: (S, N) angle choosing the
    half-plane, used when use_side is 1 (a motor-side angle: the resolver) or
    `SIDE_FOLLOWS_GYRO` (the fused angle, which follows the gyro's integral
    within its window); 0: the model's own angle; fixed_side: -1 none, else
    the side index; frac: (m,) j/m; scratch: (10, >= rows) floats, idx:
    (>= rows,) ints (work space,
    allocated once per call of `_advance_rows`: per-sample calls are many);
    sfx: (S, 2) bristle drive [rate per sample] and pre-sliding distance
    [rad] of LuGre integrated in the sub-steps, (S, 16) with a two-mass
    payload (`STATE_COLUMNS`), or (., 0): none; kstate: (S, 3) the bristle
    deflection z [rad] and the payload's y [rad], y' [rad/s]; lead: (S,)
    the fraction of each sample over which the previous sample's command
    still acts (a fractional input delay, `Effect.command_run_split`; the
    sub-step the switch falls in gets the two commands' time-weighted
    mean). With a payload w is the motor side's rate (friction, stick,
    resolver) and the gyro reads the payload's ``w + (r + c) y'`` (c = 1: a
    gyro on the payload); known: (S, N) int8, per step the side the
    resolver settles (`simulate_substeps`'s resolver_side), or (1, 1): none.

    The rows are the innermost loop: one sub-step of a row is a chain of
    dependent operations (two exp of the Stribeck curve), so the processor
    overlaps the independent chains of neighbouring rows. Each row does the
    same operations in the same order as a row-by-row loop (bit for bit,
    `tests/test_substep_model.py`).
    """
    nb = r_hi - r_lo
    h = dt / m
    step_part = 1.0 / m
    reversals = (split & SPLIT_REVERSALS) != 0
    sides = (split & SPLIT_SIDES) != 0
    w = scratch[0]  # rate, angle and reading sum of each row
    y = scratch[1]
    acc = scratch[2]
    uk = scratch[3]  # the sample's command, extra drive, angle and its step
    ek = scratch[4]
    y0 = scratch[5]
    dy = scratch[6]
    z = scratch[7]  # bristle deflection [rad]
    yp = scratch[8]  # payload coordinate and its rate
    ydp = scratch[9]
    u_now = scratch[10]  # the sample's command and the one before it
    u_before = scratch[11]
    bristles = sfx.shape[1] >= 2
    payload = sfx.shape[1] >= 16
    resolver = known.shape[1] > 1
    switching = False  # a command switch inside the sample in any row
    for b in range(nb):
        switching = switching or lead[r_lo + b] > 0.0
    for b in range(nb):
        w[b] = w_state[r_lo + b]
        y[b] = y_state[r_lo + b]
        if bristles:
            z[b] = kstate[r_lo + b, 0]
        if payload:
            yp[b] = kstate[r_lo + b, 1]
            ydp[b] = kstate[r_lo + b, 2]
    for k in range(k_lo, k_hi):
        for b in range(nb):
            i = r_lo + b
            uk[b] = u[i, k - 1]
            if switching:
                u_now[b] = uk[b]
                u_before[b] = u[i, k - 2] if k >= 2 else u[i, 0]
            ek[b] = extra[i, k - 1]
            acc[b] = 0.5 * (w[b] + (sfx[i, 2] + sfx[i, 15]) * ydp[b] if payload else w[b])
            idx[b] = 0
            if use_side:
                y0[b] = side_y[i, k - 1]
                dy[b] = side_y[i, k] - y0[b]
        for j in range(m):
            fj = frac[j]
            for b in range(nb):
                i = r_lo + b
                wb = w[b]
                if switching and lead[i] > 0.0:
                    part = min(max(lead[i] * m - j, 0.0), 1.0)
                    uk[b] = (1.0 - part) * u_now[b] + part * u_before[b]
                # The angle choosing the half-plane; at exactly 0 the side
                # also depends on the direction (`law.side_of`).
                if use_side:
                    a = y0[b] if j == 0 else y0[b] + fj * dy[b]
                    a_end = y0[b] + (fj + step_part) * dy[b]
                    if payload and use_side == SIDE_FOLLOWS_GYRO:
                        # The fused angle follows the gyro's integral, the
                        # payload's angle, within the fusion's window; the
                        # side is the motor side's: less the payload's
                        # deflection (r + c) y. Where the resolver settles
                        # the side (`known`), its side holds: the model's
                        # ringing is not the payload's to a fraction of it.
                        deflection = (sfx[i, 2] + sfx[i, 15]) * yp[b]
                        a -= deflection
                        kn = known[i, k - 1] if resolver else 0
                        a_end -= deflection
                        if kn != 0 and kn * a <= 0.0 and deflection != 0.0:
                            a = kn * max(abs(a), 1e-12)
                            a_end = a  # the resolver's side holds over the sub-step
                else:
                    a = y[b]
                    a_end = y[b] + h * wb
                if wb != 0.0:
                    ix = _regime_at(a, wb, fixed_side)
                    p = table[i, ix, 0]
                    drive = table[i, ix, 1] * uk[b] + table[i, ix, 5] * ek[b]
                    ts = table[i, ix, 2]
                    tc = table[i, ix, 3]
                    al = table[i, ix, 4]
                    slide = law.sliding(wb, ts, tc, al)
                    # The angle changes side inside the sub-step: the part
                    # before the crossing in this regime, the rest in the
                    # other side's (`Integration.split_sides`).
                    ix2 = _regime_at(a_end, wb, fixed_side) if sides else ix
                    q = 1.0 if ix2 == ix else _part_before(a, a_end)
                    if q < 1.0:
                        p, drive, slide = _across_sides(table, i, ix2, q, wb, uk[b], ek[b],
                                                        p, drive, slide)  # fmt: skip
                    if bristles:
                        # LuGre's sigma0 z, held over the sub-step like friction.
                        unit = table[i, ix, 5] * sfx[i, 0] / sfx[i, 1]
                        slide += unit * z[b]
                    w_new = p * wb + drive - slide
                    if payload:
                        w_new, yn, ydn = _payload_motion(sfx[i], yp[b], ydp[b], wb, w_new, h)
                    if mid and w_new * wb > 0.0:
                        wm = 0.5 * (wb + w_new)
                        slide = law.sliding(wm, ts, tc, al)
                        if q < 1.0:
                            slide = q * slide + (1.0 - q) * _sliding_in(table, i, ix2, wm)
                        if bristles:  # z at mid-travel, as the friction at the mean rate
                            slide += unit * _bristles(z[b], wb, 0.25 * h * (wb + w_new), sfx[i, 1])
                        w_new = p * wb + drive - slide
                        if payload:
                            # The viscous torque acts on the motor side's rate,
                            # which the mode moves by -r dy' over the sub-step:
                            # at its mean, -r dy'/2 (first pass's dy'), not at
                            # its start (a first-order error in the mode's
                            # damping, `tests/test_two_mass_payload.py`).
                            w_new += (1.0 - p) * 0.5 * sfx[i, 2] * (ydn - ydp[b])
                            w_new, yn, ydn = _payload_motion(sfx[i], yp[b], ydp[b], wb, w_new, h)
                    if w_new * wb <= 0.0:
                        rest_part = 0.0
                        # A payload on the motor side (r > 0) is split at the
                        # stop with the mode (`_payload_stop`; with LuGre's
                        # bristles on the same row the stop ends the sub-step);
                        # without one (r = 0: a gyro-only mode, or the null
                        # rows of other candidates in one batch) as on a rigid axis.
                        two_mass = payload and sfx[i, 2] != 0.0
                        if reversals and w_new != 0.0 and not two_mass:
                            rest_part = 1.0 - wb / (wb - w_new)
                        if bristles:  # travel to the stop: the rate falls linearly
                            part = wb / (wb - w_new) if w_new != 0.0 else 1.0
                            z[b] = _bristles(z[b], wb, 0.5 * h * part * wb, sfx[i, 1])
                        if reversals and w_new != 0.0 and two_mass and sfx[i, 0] == 0.0:
                            w_new, yn, ydn = _payload_stop(table, i, a, uk[b], ek[b], fixed_side,
                                by_drive, sfx[i], wb, w_new, ydp[b], ydn, yp[b], h, dt)  # fmt: skip
                        else:
                            w_new = 0.0
                        if rest_part > 0.0:
                            # The rest of the sub-step starts at rest.
                            free, _, d, ix = _rest_drive(table, i, a, uk[b], ek[b], dt, 0.0,
                                                         fixed_side, by_drive)  # fmt: skip
                            ts2 = table[i, ix, 2]
                            if free and abs(d) > ts2:
                                w_new = rest_part * (d - law.stiction(d, ts2))
                                if mid and _rigid_row(sfx[i], bristles, payload):
                                    w_new = rest_part * (d - _breakaway_friction(table, i, ix,
                                                                                 w_new))  # fmt: skip
                                if bristles:
                                    w_new = _break_through_bristles(
                                        w_new, d, rest_part, table[i, ix, 5], sfx[i], z, b, h
                                    )
                    elif bristles:
                        z[b] = _bristles(z[b], wb, 0.5 * h * (wb + w_new), sfx[i, 1])
                    if payload:
                        yp[b], ydp[b] = yn, ydn
                    wb = w_new
                else:
                    # At rest the gain of the regime a breakaway takes
                    # (`_rest_regime`) and the total drive's sign the
                    # breakaway level.
                    spring = 0.0  # the payload's spring pulls on the motor side
                    if payload:
                        spring = sfx[i, 3] * yp[b] + sfx[i, 4] * ydp[b]
                    free, d, dd, ix = _rest_drive(table, i, a, uk[b], ek[b], dt, spring,
                                                  fixed_side, by_drive)  # fmt: skip
                    ts = table[i, ix, 2]
                    if free and abs(dd) > ts:
                        wb = d - law.stiction(dd, ts)
                        if mid and _rigid_row(sfx[i], bristles, payload):
                            wb = d - _breakaway_friction(table, i, ix, wb)
                        # Only a bristle force can hold the axis here: a
                        # two-mass axis's centre of mass may move against
                        # the motor side's breakaway (the spring's pull).
                        if bristles and sfx[i, 0] != 0.0:
                            wb = _break_through_bristles(
                                wb, dd, 1.0, table[i, ix, 5], sfx[i], z, b, h
                            )
                        if payload:
                            wb, yn, ydn = _payload_motion(sfx[i], yp[b], ydp[b], 0.0, wb, h)
                            if wb * dd <= 0.0:
                                wb = 0.0
                                yn, ydn = _payload_clamped(sfx[i], yp[b], ydp[b])
                            yp[b], ydp[b] = yn, ydn
                    else:
                        wb = 0.0
                        if payload:
                            yp[b], ydp[b] = _payload_clamped(sfx[i], yp[b], ydp[b])
                w[b] = wb
                idx[b] = ix
                y[b] = y[b] + h * wb
                if payload:
                    wb = wb + (sfx[i, 2] + sfx[i, 15]) * ydp[b]  # the gyro on the payload
                if j < m - 1:
                    acc[b] += wb
                else:
                    acc[b] += 0.5 * wb
        for b in range(nb):
            i = r_lo + b
            point[i, k] = w[b] + (sfx[i, 2] + sfx[i, 15]) * ydp[b] if payload else w[b]
            reading[i, k] = acc[b] / m
            angle[i, k] = y[b]
            regime[i, k] = idx[b]
    for b in range(nb):
        w_state[r_lo + b] = w[b]
        y_state[r_lo + b] = y[b]
        if bristles:
            kstate[r_lo + b, 0] = z[b]
        if payload:
            kstate[r_lo + b, 1] = yp[b]
            kstate[r_lo + b, 2] = ydp[b]


#: Rows advanced together (`_advance_group`): enough independent chains to
#: keep the processor busy, few enough that their samples stay in L1 cache.
GROUP_ROWS = 16


@njit(cache=True, nogil=True)
def _advance_rows(
    table,
    u,
    extra,
    side_y,
    use_side,
    fixed_side,
    k_lo,
    k_hi,
    m,
    dt,
    mid,
    split,
    by_drive,
    w_state,
    y_state,
    point,
    reading,
    angle,
    regime,
    r_lo,
    r_hi,
    sfx=None,
    kstate=None,
    lead=None,
    known=None,
):  # pragma: no cover - compiled
    """`_advance_group` on rows r_lo..r_hi-1, `GROUP_ROWS` at a time (no
    effect in the sub-steps when sfx, kstate are omitted, the command held
    over the whole sample when lead is, no resolver side when known is)."""
    if sfx is None:
        sfx_, kstate_ = np.zeros((1, 0)), np.zeros((1, 0))
    else:
        sfx_, kstate_ = sfx, kstate
    if lead is None:
        lead_ = np.zeros(u.shape[0])
    else:
        lead_ = lead
    if known is None:
        known_ = np.zeros((1, 1), dtype=np.int8)
    else:
        known_ = known
    frac = np.empty(m)
    for j in range(m):
        frac[j] = j / m
    scratch = np.zeros((12, GROUP_ROWS))
    idx = np.zeros(GROUP_ROWS, dtype=np.int64)
    for g in range(r_lo, r_hi, GROUP_ROWS):
        g_hi = min(g + GROUP_ROWS, r_hi)
        _advance_group(table, u, extra, side_y, use_side, fixed_side, k_lo, k_hi, m, dt, mid,
                       split, by_drive, w_state, y_state, point, reading, angle, regime, g, g_hi, frac,
                       scratch, idx, sfx_, kstate_, lead_, known_)  # fmt: skip


@njit(cache=True, nogil=True, parallel=True)
def _advance_blocks(
    table,
    u,
    extra,
    side_y,
    use_side,
    fixed_side,
    k_lo,
    k_hi,
    m,
    dt,
    mid,
    split,
    by_drive,
    w_state,
    y_state,
    point,
    reading,
    angle,
    regime,
    n_blocks,
    sfx=None,
    kstate=None,
    lead=None,
    known=None,
):  # pragma: no cover - compiled
    """`_advance_rows` on `n_blocks` blocks of rows in parallel (rows are independent)."""
    n_rows = u.shape[0]
    for c in prange(n_blocks):
        r_lo, r_hi = c * n_rows // n_blocks, (c + 1) * n_rows // n_blocks
        _advance_rows(table, u, extra, side_y, use_side, fixed_side, k_lo, k_hi, m, dt, mid, split,
                      by_drive, w_state, y_state, point, reading, angle, regime, r_lo, r_hi, sfx,
                      kstate, lead, known)  # fmt: skip


#: Sub-steps (rows x samples x m) below which a call stays on one thread:
#: waking the threads costs tens of microseconds, the work per sub-step ~10 ns
#: (the per-sample calls of the effects path are ~10**3).
PARALLEL_MIN_SUBSTEPS = 200_000


def _advance(table, u, extra, side_y, use_side, fixed_side, k_lo, k_hi, m, dt, mid, split,
             by_drive, w_state, y_state, point, reading, angle, regime, sfx, kstate, lead,
             known):  # fmt: skip
    """Advance every row from sample k_lo-1 to k_hi-1 (`_advance_rows`), on all
    of numba's threads when the call is large enough; the same numbers either way."""
    n_rows = u.shape[0]
    blocks = min(numba.get_num_threads(), n_rows)
    args = (table, u, extra, side_y, use_side, fixed_side, k_lo, k_hi, m, dt, mid, split,
            by_drive, w_state, y_state, point, reading, angle, regime)  # fmt: skip
    if blocks > 1 and n_rows * (k_hi - k_lo) * m >= PARALLEL_MIN_SUBSTEPS:
        _advance_blocks(*args, blocks, sfx, kstate, lead, known)
    else:
        _advance_rows(*args, 0, n_rows, sfx, kstate, lead, known)


@njit(cache=True)
def _law_probe(cases):  # pragma: no cover - compiled
    """`friction_compiled.probe`, cached with `_advance` (stale with it)."""
    return law.probe(cases)


def compiled_law_is_current() -> bool:
    """Whether the cached kernel's Eq. 5 is friction.py's, bit for bit, on the probe.

    numba's cache checks only this file's time stamp: an edit to friction.py
    alone would leave `_advance` on the old law (`isp_twin.model.friction_compiled`).
    """
    cases = law_probe_cases()
    return bool(np.array_equal(_law_probe(cases), python_law(cases)))


_LAW_CHECKED = False


def _ensure_current_law() -> None:
    """Recompile a stale cached kernel, once per process, at the first simulation.

    Not at import: every command imports this module (its `Integration`), and
    loading the cached kernel costs ~0.1 s that only identify/diagnose need.
    """
    global _LAW_CHECKED
    if _LAW_CHECKED:
        return
    if not compiled_law_is_current():
        # Stale cache: compile afresh (this rewrites the cache).
        for kernel in (_law_probe, _advance_group, _advance_rows, _advance_blocks):
            kernel.recompile()
        if not compiled_law_is_current():
            raise RuntimeError("substep_model: the compiled friction law differs from friction.py")
    _LAW_CHECKED = True


def _substep_table(
    params: RateParams, n_rows: int, m: int, exact_effect_hold: bool = True
) -> np.ndarray:
    """Per-row, per-regime sub-step coefficients, shape (S, 4, 6).

    Columns: p, c·gain, c·static, c·coulomb, alpha (see module doc), and the
    factor of an effect's ``accel*T`` per sub-step: ``(1 - p)/(-ln a)``, the
    exact hold of a constant acceleration over T/m (m of them sum to
    ``(1 - a)/(-ln a)``, the zero-order-hold factor of the sample), or with
    ``exact_effect_hold`` off, c (Eq. 6's ``accel*T`` per sample; 1 at m = 1).
    """
    cols = [
        np.broadcast_to(np.atleast_2d(np.asarray(x, dtype=float)), (n_rows, 4))
        for x in (params.pole, params.gain, params.static, params.coulomb, params.alpha)
    ]
    a, g, s, c_, al = cols
    if m == 1:
        p = a.copy()
        c = np.ones_like(a)
    else:
        p = a ** (1.0 / m)
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.where(a < 1.0, (1.0 - p) / (1.0 - a), 1.0 / m)
    table = np.empty((n_rows, 4, 6))
    table[..., 0] = p
    table[..., 1] = c * g if m > 1 else g
    table[..., 2] = c * s if m > 1 else s
    table[..., 3] = c * c_ if m > 1 else c_
    table[..., 4] = al
    if exact_effect_hold:
        with np.errstate(divide="ignore", invalid="ignore"):
            hold = np.where(a < 1.0, (1.0 - p) / -np.log(a), 1.0 / m)
        table[..., 5] = hold
    else:
        table[..., 5] = c
    return table


def simulate_substeps(
    params: RateParams,
    u: np.ndarray,
    dt: float,
    omega0: float | np.ndarray = 0.0,
    angle0: float | np.ndarray = 0.0,
    angle_measured: np.ndarray | None = None,
    effects: Sequence[Effect] = (),
    side: int | None = None,
    integration: Integration = DEFAULT_INTEGRATION,
    gyro_average: bool = False,
    side_follows_gyro: bool = False,
    resolver_side: np.ndarray | None = None,
    torque_angle: np.ndarray | None = None,
) -> AxisResponse:
    """Simulate the sub-stepped Eq. 6 for a batch of parameter sets.

    Args:
        params: rate-form parameters, arrays (4,) or (P, 4).
        u: command [digits], shape (N,) or (P, N).
        dt: sample period T [s].
        omega0: rate at sample 0 [rad/s], float or (P,).
        angle0: angle at sample 0 [rad], float or (P,).
        angle_measured: (N,) or (P, N) angle [rad] choosing the half-plane; None: the model's.
        effects: extra effects (reset here), parameters floats or arrays (P,).
        side: fix the half-plane (`SIDE_R` or `SIDE_L`) whatever the angle.
        integration: sub-steps and options (`Integration`).
        gyro_average: the reading is the rate averaged over the sample.
        side_follows_gyro: `angle_measured` follows the gyro (`RunStack`).
        resolver_side: (P, N) int8, per step the side the resolver settles
            (+1 R, -1 L, 0 open; `RunStack.resolver_side`), or None.
        torque_angle: (N,) or (P, N) angle [rad] torques of the angle read.

    Returns:
        `AxisResponse` ((N,) unbatched, else (P, N)): ``omega`` the gyro reading (averaged
        when asked, sensor effects applied), ``omega_true`` the point rate where they differ.
    """
    _ensure_current_law()
    u = np.asarray(u, dtype=float)
    single = np.ndim(params.pole) == 1 and u.ndim < 2
    n = u.shape[-1]
    n_rows = _batch_rows(params, u, omega0, angle0, angle_measured)
    m = int(integration.substeps)
    table = _substep_table(params, n_rows, m, integration.exact_effect_hold)
    u_rows, side_y, known = _input_rows(u, angle_measured, resolver_side, n_rows, n)
    fixed = -1 if check_side(side) is None else side
    outputs = _state_and_outputs(n_rows, n, omega0, angle0)
    sfx, kstate, effects = _substep_effects(effects, n_rows, dt, m)
    args = (m, float(dt), *integration.kernel_flags())
    use_side = 0 if angle_measured is None else SIDE_FOLLOWS_GYRO if side_follows_gyro else 1
    at_y = _torque_angle(side_y, torque_angle, integration.midstep_angle, use_side, effects)
    before = _effects_before_the_run(effects, u_rows, at_y, use_side, dt, m)
    commands, torques, u_eff, extra, lead = before
    if not (commands or torques):
        _advance(table, u_eff, extra, side_y, use_side, fixed, 1, n, *args, *outputs, sfx, kstate,
                 lead, known)  # fmt: skip
    else:
        kernel_args = (table, side_y, use_side, fixed, args, outputs, sfx, kstate, lead, known)
        _run_per_sample(kernel_args, commands, torques, u_rows, u_eff, extra, dt, at_y)
    return _response(_measured(outputs[3 if gyro_average else 2], effects), outputs, single)


def _response(out, outputs, single: bool) -> AxisResponse:
    """The reading `out` with the point rate (where they differ), angle and regime."""
    _, _, point, _, angle, regime = outputs
    true = None if out is point else point
    if single:
        return AxisResponse(out[0], angle[0], regime[0], None if true is None else true[0])
    return AxisResponse(out, angle, regime, true)


def _state_and_outputs(n_rows: int, n: int, omega0, angle0) -> tuple[np.ndarray, ...]:
    """Rate and angle state (rows,), and the point rate, reading, angle and
    regime outputs (rows, N), sample 0 set."""
    w = np.broadcast_to(np.asarray(omega0, dtype=float), (n_rows,)).copy()
    y = np.broadcast_to(np.asarray(angle0, dtype=float), (n_rows,)).copy()
    point = np.empty((n_rows, n))
    reading = np.empty((n_rows, n))
    angle = np.empty((n_rows, n))
    regime = np.zeros((n_rows, n), dtype=np.int64)
    point[:, 0] = w
    reading[:, 0] = w
    angle[:, 0] = y
    return w, y, point, reading, angle, regime


def is_torque(e: Effect) -> bool:
    """Whether effect `e` adds an acceleration (a torque over the inertia)."""
    return type(e).acceleration is not Effect.acceleration


def _torque_angle(side_y: np.ndarray, given, midstep: bool, use_side: int, effects) -> np.ndarray:
    """The measured angle the torques of step k see, (rows, N): the `given`
    torque angle (`simulate_substeps`'s torque_angle) where there is one and
    the angle is measured, else the side angle `side_y`; the mean of the
    angles at the step's ends (`Integration.midstep_angle`), else the angle
    at its start; the last column (no step follows) as given. Without a
    torque among `effects` nothing reads it: `side_y` itself, no copy."""
    if not use_side or not any(is_torque(e) for e in effects):
        return side_y
    if given is not None:
        side_y = np.broadcast_to(np.asarray(given, dtype=float), side_y.shape)
    if not midstep or side_y.shape[-1] < 2:
        return np.ascontiguousarray(side_y)
    out = side_y.copy()
    out[:, :-1] = 0.5 * (side_y[:, :-1] + side_y[:, 1:])
    return out


def _run_per_sample(kernel_args, commands, torques, u_rows, u_eff, extra, dt, at_y) -> None:
    """Effects that need the model's own state: evaluated per sample, their
    command and acceleration held over the sub-steps of one kernel call each
    (a torque of the measured angle at `at_y`)."""
    table, side_y, use_side, fixed, args, outputs, sfx, kstate, lead, known = kernel_args
    w, y = outputs[0], outputs[1]
    n_rows, n = u_rows.shape
    if commands:
        u_eff = u_rows.copy()
    for k in range(1, n):
        if commands:
            uk = u_rows[:, k - 1]
            for e in commands:
                uk = e.command(uk)
            u_eff[:, k - 1] = uk
        if torques:
            at = at_y[:, k - 1] if use_side else y
            extra[:, k - 1] = sum(e.acceleration(at, w) for e in torques) * dt
        _advance_rows(table, u_eff, extra, side_y, use_side, fixed, k, k + 1, *args,
                      *outputs, 0, n_rows, sfx, kstate, lead, known)  # fmt: skip


def _substep_effects(effects, n_rows: int, dt: float, m: int):
    """Reset the effects; the kernel's coefficients (rows, 2 or 16 of
    `STATE_COLUMNS`) and initial state (rows, 3) of those integrated in the
    sub-steps (`Effect.in_substeps`), or (1, 0) arrays when there is none,
    and the effects left to their hooks. At m = 1 there is none: Eq. 6 holds
    every effect per sample, as `isp_twin.model.axis_model.simulate` does.

    Raises:
        ParameterError: two effects that give the same kernel state.
    """
    for e in effects:
        e.reset()
    inside = [e for e in effects if e.in_substeps] if m > 1 else []
    if not inside:
        return np.zeros((1, 0)), np.zeros((1, 0)), list(effects)
    columns = dict(_COLUMN_DEFAULTS)
    given: set[str] = set()
    for e in inside:
        cols = e.substep_columns(dt, m)
        if given & set(cols):
            raise ParameterError(f"effect {e.name}: another effect holds the same kernel state")
        given |= set(cols)
        columns.update(cols)
    names = STATE_COLUMNS if "payload_ratio" in given else STATE_COLUMNS[:2]
    sfx = np.empty((n_rows, len(names)))
    for c, name in enumerate(names):
        sfx[:, c] = np.broadcast_to(np.asarray(columns[name], dtype=float), (n_rows,))
    # Bristles relaxed, payload at rest on the motor side (as the reference).
    return sfx, np.zeros((n_rows, 3)), [e for e in effects if not e.in_substeps]


def _input_rows(u, angle_measured, resolver_side, n_rows: int, n: int) -> tuple[np.ndarray, ...]:
    """The command, the half-plane angle and the resolver's sides, (rows, N)
    each, contiguous ((1, 1) placeholders for an angle when the model's own
    angle chooses, and for sides when none are given)."""
    u_rows = np.ascontiguousarray(np.broadcast_to(u, (n_rows, n)), dtype=float)
    known = _resolver_rows(resolver_side, n_rows, n)
    if angle_measured is None:
        return u_rows, np.zeros((1, 1)), known
    side_y = np.broadcast_to(np.asarray(angle_measured, dtype=float), (n_rows, n))
    return u_rows, np.ascontiguousarray(side_y), known


def _resolver_rows(resolver_side, n_rows: int, n: int) -> np.ndarray:
    """`simulate_substeps`'s resolver sides, (rows, N) int8, or a (1, 1) placeholder."""
    if resolver_side is None:
        return np.zeros((1, 1), dtype=np.int8)
    known = np.broadcast_to(np.asarray(resolver_side, dtype=np.int8), (n_rows, n))
    return np.ascontiguousarray(known)


def _batch_rows(params: RateParams, u, omega0, angle0, angle_measured) -> int:
    """Rows of the batch: the largest of the arguments' leading sizes."""
    sizes = [np.atleast_2d(np.asarray(x)).shape[0] for x in (params.pole, params.gain)]
    return max(
        *sizes,
        u.shape[0] if u.ndim == 2 else 1,
        np.size(omega0),
        np.size(angle0),
        np.atleast_2d(angle_measured).shape[0] if angle_measured is not None else 1,
    )


def _effects_before_the_run(effects, u_rows, side_y, use_side, dt, m):
    """Evaluate what can be evaluated over the whole run before the kernel.

    Returns (command effects, torque effects) still to run per sample, the
    command [digits] and the extra drive [rate per sample], (rows, N) each,
    and the kernel's `lead` (rows,): with sub-steps (m > 1) a command hook's
    switch inside the sample (`Effect.command_run_split`), else 0 (Eq. 6:
    the sample's mean command, `Effect.command_run`).

    Raises:
        ParameterError: two command hooks that each switch inside the sample.
    """
    n_rows, n = u_rows.shape
    commands = [e for e in effects if type(e).command is not Effect.command]
    torques = [e for e in effects if is_torque(e)]
    extra = np.zeros((n_rows, n))
    lead = np.zeros(n_rows)
    u_eff = u_rows
    if commands and not set(commands) & set(torques):
        # A command hook sees only the command: run it over the whole run
        # first, hook after hook (`Effect.command_run`; the sample loop
        # calls them in the same order). The last sample drives no step.
        u_eff = u_rows.copy()
        for e in commands:
            lead = _command_hook(e, u_eff, lead, m)
        commands = []
    if torques and use_side and not any(e.acceleration_uses_rate for e in torques):
        # Accelerations of the measured angle alone (cogging, springs,
        # unbalance, offsets) are known before the run: elementwise in the
        # angle, the whole run in one call each (parameters (rows,) broadcast
        # along the last axis, hence (N - 1, rows)), then one kernel call.
        at = side_y[:, : n - 1].T
        extra[:, : n - 1] = sum(e.acceleration(at, None) for e in torques).T * dt
        torques = []
    return commands, torques, u_eff, extra, lead


def _command_hook(e: Effect, u_eff: np.ndarray, lead: np.ndarray, m: int) -> np.ndarray:
    """Effect `e`'s command hook over the run in place on `u_eff` (the last
    sample drives no step); the kernel's `lead`, `e`'s where it has one."""
    n = u_eff.shape[1]
    if m == 1:
        u_eff[:, : n - 1] = e.command_run(u_eff[:, : n - 1])
        return lead
    u_eff[:, : n - 1], own = e.command_run_split(u_eff[:, : n - 1])
    if not np.any(own):
        return lead
    if np.any(lead):
        raise ParameterError(f"effect {e.name}: a second command switch inside the sample")
    return np.broadcast_to(np.asarray(own, dtype=float), lead.shape).copy()


def _measured(out: np.ndarray, effects) -> np.ndarray:
    """The reading through the effects' `measure` hooks (sensor errors), per sample."""
    sensors = [e for e in effects if type(e).measure is not Effect.measure]
    if not sensors:
        return out
    measured = out
    for e in sensors:
        measured = e.measure_run(measured)
    return measured
