"""The identification's start (stage 3 of `isp_twin.identification.fit`):
one-step-ahead (equation-error) least squares per regime, and jointly with
an effect's parameters (`joint_equation_error_estimate`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from isp_twin.identification.cost import rate_noise
from isp_twin.identification.gyro_error import gyro_error_estimate, rate_behind_gyro_error
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.motor_side import motor_side_rates, payload_mode
from isp_twin.identification.side_angle import side_angle
from isp_twin.model.effects import Effect, effect_class, make_effect
from isp_twin.model.effects.base import true_rates
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.friction import regime_index
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    EffectSpec,
    RateParams,
    sample_hold_factor,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.units import DEG

__all__ = [
    "equation_error_estimate",
    "JOINT_FORMS",
    "JointEstimate",
    "joint_equation_error_estimate",
    "sensor_bias_joint_starts",
]


def equation_error_estimate(
    data: Sequence[MeasuredData],
    prior: RateParams,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    min_samples: int = 50,
    effects: Sequence[EffectSpec] = (),
) -> RateParams:
    """One-step-ahead least squares per regime (see module doc, step 3).

    For each alpha of a grid spanning four decades of ``alpha*|omega|`` (from
    a Stribeck part that is a straight line over the measured speeds to one
    that has decayed after the first sample), Eq. 6 is linear in (a, b·Ke,
    b·Tc, b·(Ts-Tc)); the fit is solved with the physical bounds (0 <= a < 1,
    b·Ke >= 0, b·Tc >= 0, Ts >= Tc), so a nearly collinear Stribeck column
    (small alpha: ``exp(-alpha|w|)`` ~ ``1 - alpha|w|``, a mix of sign(w)
    and w) cannot push the levels to unphysical values. Regimes with fewer
    than `min_samples` usable samples keep the prior. Known `effects` are
    driven by the measured angle and rate (`_effect_drive`) and taken out of
    the regression; a known sensor error is taken out of the readings first
    (`_true_readings`). The rest level used to pick moving samples is at least
    four times the rate noise (`rate_noise`): noisy samples of an axis at rest
    would otherwise enter as motion.
    """
    data = _true_readings(data, effects)
    noise = rate_noise(data)
    rest = max(rest_rate_deg_s * DEG, 4.0 * noise)
    tables, speed = _regime_tables(data, side_source, rest, effects)
    x = RATE_LAYOUT.as_table(prior.to_vector()).copy()
    if speed.size == 0:
        return RateParams.from_vector(RATE_LAYOUT.from_table(x))
    typical = float(np.sqrt(np.mean(speed**2)))
    grid = np.geomspace(1e-2, 1e2, 41) / typical
    for r, table in enumerate(tables):
        if table.shape[0] >= min_samples:
            x[r] = _fit_regime(table, grid)
    return RateParams.from_vector(RATE_LAYOUT.from_table(x))


def _true_readings(data: Sequence[MeasuredData], effects: Sequence[EffectSpec]):
    """The runs with the gyro readings mapped back to the rates they mean by
    the known sensor errors among `effects` (`true_rates`), or `data`
    itself when there is none.

    A gyro bias read as motion makes every sample at rest a moving one (a
    bias of 0.48 deg/s against a rest level of 0.1 deg/s on benchmark
    sensor_bias seed 1), and the regression then fits the bias into the
    friction levels: `identify` with the true bias held ended at 1.35 and
    1.52 noise floors on training, 6.4 held out.
    """
    if not any(effect_class(e.name).maps_readings for e in effects):
        return data
    out = []
    for d in data:
        built = [make_effect(e, d.dt) for e in effects]
        omega = true_rates(built, np.asarray(d.omega, dtype=float))
        out.append(replace(d, omega=np.asarray(omega, dtype=float)))
    return out


def _regime_tables(
    data: Sequence[MeasuredData], side_source: str, rest: float, effects: Sequence[EffectSpec]
) -> tuple[list[np.ndarray], np.ndarray]:
    """One-step-ahead regression rows per regime, and the moving speeds [rad/s].

    The rows of `_regression_rows` split by regime, as tables (K_r, 6) of
    columns (rate before, command, sign, speed, 1 on breakaway rows, rate
    after), each run's moving rows before its breakaway rows; and the |rate|
    of all moving samples (K,). `rest` [rad/s] is the level at or below which
    a sample counts as at rest.
    """
    rows = _regression_rows(data, side_source, rest, effects)
    starts = np.cumsum([0] + [d.omega.size - 1 for d in data])
    run = np.searchsorted(starts, rows.step, side="right") - 1
    order = np.lexsort((rows.step, rows.brk, run))
    columns = np.column_stack([rows.w0, rows.u0, rows.sgn, rows.speed, rows.brk, rows.w1])[order]
    regime = rows.regime[order]
    tables = [columns[regime == r] for r in range(RATE_LAYOUT.n_regimes)]
    return tables, rows.speed[rows.brk == 0]


def _fit_regime(table: np.ndarray, grid: np.ndarray) -> tuple[float, ...]:
    """One regime's rate form (pole, gain, static, coulomb, alpha) from its rows.

    For each alpha of `grid` [s/rad] the bounded linear fit of
    `equation_error_estimate`; the alpha of least squared error is kept.
    `table`: the regime's rows (K, 6) from `_regime_tables`.
    """
    from scipy.optimize import lsq_linear

    w0, u0, sgn, speed_r, brk, w1 = table.T
    # Columns scaled to unit norm: u is in digits, the rest in rad/s.
    best = None
    for alpha in grid:
        shape = np.where(brk > 0, 1.0, np.exp(-alpha * speed_r))
        a_mat = np.column_stack([w0, u0, -sgn, -sgn * shape])
        norm = np.linalg.norm(a_mat, axis=0)
        norm = np.where(norm > 0, norm, 1.0)
        fit = lsq_linear(
            a_mat / norm,
            w1,
            bounds=(np.zeros(4), np.array([1.0 - 1e-9, np.inf, np.inf, np.inf]) * norm),
            method="bvls",
        )
        sse = float(np.sum(fit.fun**2))
        if best is None or sse < best[0]:
            best = (sse, fit.x / norm, alpha)
    _, (a, g, c, s_minus_c), alpha = best
    a = min(max(a, 1e-6), 1.0 - 1e-9)
    return (a, max(g, 1e-12), c + s_minus_c + 1e-12, c + 1e-12, alpha)


#: Effects whose acceleration is linear in its strengths for given shape
#: parameters: name -> (shape parameters searched on a grid, strength columns).
_LINEAR_TORQUES = ("cogging", "unbalance", "cable_spring")
#: Effects whose acceleration is linear in one strength for a given state
#: parameter, that parameter searched on a grid: LuGre's bristle force
#: ``accel_rad_s2`` for each pre-sliding distance ``presliding_rad``
#: (`_joint_lugre_pass`).
_STATE_TORQUES = ("lugre",)
#: Effects acting on the command, their one parameter searched on a grid.
_COMMAND_EFFECTS = {
    "input_delay": "delay_s",
    "deadzone": "width_digits",
    "saturation": "limit_digits",
}


@dataclass(frozen=True)
class _Rows:
    """The one-step-ahead regression rows of the runs (`equation_error_estimate`).

    Arrays of shape (K,) over the usable samples of all runs: the regime, the
    rate before and after the step [rad/s], the sign, the speed, 1 on
    breakaway rows, the angle of the half-plane [rad], and the index of the
    sample in the concatenated (N-1)-long steps of the runs (to pick command
    columns transformed by a command effect).
    """

    regime: np.ndarray
    w0: np.ndarray
    w1: np.ndarray
    u0: np.ndarray
    sgn: np.ndarray
    speed: np.ndarray
    brk: np.ndarray
    y: np.ndarray
    step: np.ndarray


def _regression_rows(data, side_source, rest, effects) -> _Rows:
    """Moving and breakaway samples of all runs, known `effects` taken out."""
    parts = []
    offset = 0
    payload = payload_mode(effects) if side_source == "measured" else None
    for d in data:
        w0, w1 = d.omega[:-1], d.omega[1:]
        y = side_angle(d, side_source)[:-1]
        u0, more = _effect_drive(d, y, effects)
        change, rest_d = None, rest
        if payload is not None:
            # A two-mass axis: the motor side's rows, the centre of mass's
            # change in the target (`_payload_rows`).
            w0, w1, change, y, rest_d = _payload_rows(d, payload, rest)
        # Motion, rest and breakaway are read from the measured rates (on a
        # two-mass axis the smoothed motor side's); only the regression's
        # target has the known effects taken out. Read
        # from the target, a stuck axis held by a strong spring (the effect's
        # rate change per sample above the rest level) counted as a
        # breakaway, against the spring: reference cable spring seed 14
        # (23.9 1/s^2) started regimes R+ and L- at no friction and no gain
        # with the true spring held (docs/identification.md "Stop 27").
        moving = (np.abs(w0) > rest_d) & (np.abs(w1) > rest_d) & (np.sign(w1) == np.sign(w0))
        # A breakaway moves the way the total drive (command and known
        # effects) pushes: its direction is that of the motion it starts.
        breakaway = (np.abs(w0) <= rest_d) & (np.abs(w1) > rest_d)
        use = moving | breakaway
        regime = np.where(moving, regime_index(y, w0), regime_index(y, w1))
        sgn = np.where(moving, np.sign(w0), np.sign(w1))
        before = np.where(moving, w0, 0.0)
        target = (w1 if change is None else before + change) - more
        parts.append(
            (
                regime[use],
                before[use],
                target[use],
                u0[use],
                sgn[use],
                np.where(moving, np.abs(w0), 0.0)[use],
                breakaway[use].astype(float),
                y[use],
                offset + np.flatnonzero(use),
            )
        )
        offset += w0.size
    cols = [np.concatenate([p[i] for p in parts]) if parts else np.empty(0) for i in range(9)]
    return _Rows(*cols)


def _payload_rows(d: MeasuredData, payload: EffectSpec, rest: float):
    """A two-mass run's rows (`motor_side_rates`): the motor side's rate
    before and after each step (friction, viscous torque and the stick
    test act on it), the centre of mass's rate change over each step (the
    target is the rate before plus that change: the total torque over J
    against the motor side's rate), the resolver's angle for the side,
    and the rest level, at least four of the smoother's standard deviations.
    """
    est = motor_side_rates(d, payload)
    angle = d.angle if d.resolver is None else d.resolver
    rest = max(rest, 4.0 * est.motor_sd)
    return est.motor[:-1], est.motor[1:], np.diff(est.centre), angle[:-1], rest


#: Effects `joint_equation_error_estimate` estimates with the base.
JOINT_FORMS: tuple[str, ...] = _LINEAR_TORQUES + tuple(_COMMAND_EFFECTS) + _STATE_TORQUES


@dataclass(frozen=True)
class JointEstimate:
    """Base and one effect estimated together (`joint_equation_error_estimate`).

    Attributes:
        rate: rate-form parameters of Eq. 6 (`RateParams`).
        effect: the effect with its estimated parameters (None: base alone).
        sse: one-step-ahead sum of squared errors with the effect [(rad/s)^2].
        sse_base: the same without the effect (same rows and alphas) [(rad/s)^2].
    """

    rate: RateParams
    effect: EffectSpec | None
    sse: float
    sse_base: float


def joint_equation_error_estimate(
    data: Sequence[MeasuredData],
    prior: RateParams,
    candidate: EffectSpec,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    min_samples: int = 50,
    effects: Sequence[EffectSpec] = (),
    passes: int = 2,
    integration: Integration = DEFAULT_INTEGRATION,
) -> JointEstimate:
    """Base and candidate effect estimated together by one-step-ahead least squares.

    `equation_error_estimate` fits each regime alone with known effects taken
    out; here the candidate's unknown parameters join the regression, so
    they are not estimated on a base that has absorbed the effect into its
    friction levels. One block problem (`_solve_block`): each regime's
    columns with the regime's alpha fixed at its best of the per-regime
    grid, the effect's columns shared by all rows; torque effects linear in
    their strengths by `_joint_torque_pass`, command effects on a grid of
    their parameter by `_joint_command_pass`; others (no linear form):
    `candidate` held, base re-estimated.

    Alphas and effect are estimated in turn `passes` times (alphas with the
    effect held, then the block problem; torque columns with `integration`'s
    hold, `_hold_factor`). Returns the rate parameters, the candidate with the
    estimated parameters (others as given) and both costs (`JointEstimate`).
    """
    name = candidate.name
    current = EffectSpec(name, dict(candidate.params))
    fixed = tuple(effects)
    if name not in JOINT_FORMS:
        x = equation_error_estimate(
            data, prior, side_source, rest_rate_deg_s, min_samples, fixed + (current,)
        )
        return JointEstimate(x, current, float("nan"), float("nan"))
    problem = _joint_problem(data, side_source, rest_rate_deg_s, min_samples, fixed)
    if problem is None:
        return JointEstimate(prior, current, float("nan"), float("nan"))
    x = RATE_LAYOUT.as_table(prior.to_vector()).copy()
    cls = make_effect(current, problem.dt).__class__
    for _ in range(max(passes, 1)):
        # Alphas (and a first base) with the current effect held.
        base = equation_error_estimate(
            data, prior, side_source, rest_rate_deg_s, min_samples, fixed + (current,)
        )
        alpha = RATE_LAYOUT.column(base.to_vector(), "alpha")
        sse, reg, params = _joint_pass(problem, data, side_source, current, base, integration, cls)
        for i, r in enumerate(problem.regimes):
            a, g, c, s_minus_c = reg[i]
            a = min(max(a, 1e-6), 1.0 - 1e-9)
            x[r] = (a, max(g, 1e-12), c + s_minus_c + 1e-12, c + 1e-12, alpha[r])
        bounded = {p: float(np.clip(v, *cls.bounds[p])) for p, v in params.items()}
        current = EffectSpec(name, bounded)
    sse_base = _base_only_sse(problem, alpha)
    return JointEstimate(RateParams.from_vector(RATE_LAYOUT.from_table(x)), current, sse, sse_base)


def _joint_pass(problem, data, side_source, current: EffectSpec, base, integration, cls):
    """One pass of the joint estimate for `current`'s form (torque columns, a
    state torque, or a command-side grid): (sse, per-regime regression, params)."""
    name, params = current.name, current.params
    alpha = RATE_LAYOUT.column(base.to_vector(), "alpha")
    if name in _LINEAR_TORQUES:
        hold = _hold_factor(RATE_LAYOUT.column(base.to_vector(), "pole"), integration)
        return _joint_torque_pass(problem, name, alpha, params, hold)
    if name in _STATE_TORQUES:
        return _joint_lugre_pass(problem, data, side_source, alpha, params)
    return _joint_command_pass(problem, data, name, alpha, params, cls)


@dataclass(frozen=True)
class _JointProblem:
    """The regression rows of `joint_equation_error_estimate` and what every pass reuses.

    Attributes:
        rows: the usable samples (`_Rows`), K rows.
        regimes: the regimes with enough rows, in regime order.
        u_all: the command of every step after the fixed effects [digits], (sum N-1,).
        u_peak: its largest magnitude (1 if all zero) [digits].
        dt: sample period [s].
        use: rows in those regimes, (K,).
        in_regime: per regime of `regimes`, its rows among the used ones.
    """

    rows: _Rows
    regimes: list[int]
    u_all: np.ndarray
    u_peak: float
    dt: float
    use: np.ndarray
    in_regime: list[np.ndarray]


def _joint_problem(data, side_source, rest_rate_deg_s, min_samples, fixed) -> _JointProblem | None:
    """The rows with the fixed effects taken out; None when no regime has `min_samples`."""
    noise = rate_noise(data)
    rest = max(rest_rate_deg_s * DEG, 4.0 * noise)
    rows = _regression_rows(data, side_source, rest, fixed)
    regimes = [r for r in range(RATE_LAYOUT.n_regimes) if np.sum(rows.regime == r) >= min_samples]
    if not regimes:
        return None
    u_all = np.concatenate(
        [_effect_drive(d, side_angle(d, side_source)[:-1], fixed)[0] for d in data]
    )
    u_peak = float(np.max(np.abs(u_all))) or 1.0
    use = np.isin(rows.regime, regimes)
    in_regime = [rows.regime[use] == r for r in regimes]
    return _JointProblem(rows, regimes, u_all, u_peak, data[0].dt, use, in_regime)


def _base_only_sse(problem: _JointProblem, alpha: np.ndarray) -> float:
    """The block problem's sse without the effect (same rows and alphas) [(rad/s)^2]."""
    rows = problem.rows
    cols = _fixed_columns(problem, alpha, rows.w1)
    return _solve_block(problem, cols, problem.u_all[rows.step], np.zeros((rows.w0.size, 0)))[0]


def _torque_columns(name: str, y: np.ndarray, shape: float, dt: float) -> np.ndarray:
    """A torque effect's columns per unit strength at angles `y` [rad], (K, 1 or 2).

    Cogging ``(sin, cos)(2 pi y / shape)``, unbalance ``(sin, cos)(y)``, cable
    spring ``-y``; times the sample period (rate change per step).
    """
    if name == "cogging":
        ph = 2.0 * np.pi * y / shape
        return dt * np.column_stack([np.sin(ph), np.cos(ph)])
    if name == "unbalance":
        return dt * np.column_stack([np.sin(y), np.cos(y)])
    return dt * (-y)[:, None]


def _command_columns(name: str, data, u_all: np.ndarray, values: np.ndarray, dt: float):
    """The command after a command effect for each grid value, (G, sum N-1)."""
    pname = _COMMAND_EFFECTS[name]
    out = np.empty((values.size, u_all.size))
    start = 0
    for d in data:
        n = len(d) - 1
        eff = make_batched(name, {pname: values}, dt)
        seg = u_all[start : start + n]
        for k in range(n):
            out[:, start + k] = eff.command(np.full(values.size, seg[k]))
        start += n
    return out


@dataclass(frozen=True)
class _FixedColumns:
    """The block problem's columns fixed by the alphas (`_fixed_columns`).

    Attributes:
        f_mat: per regime rate, -sign, -sign * Stribeck shape, unit-norm, (K_used, 3 n_r).
        f_norm: their norms before scaling, (3 n_r,).
        target: the rate after the step on the used rows [rad/s], (K_used,).
        ff, ft, tt: Gram blocks ``F^T F``, ``F^T target``, ``target^T target``.
    """

    f_mat: np.ndarray
    f_norm: np.ndarray
    target: np.ndarray
    ff: np.ndarray
    ft: np.ndarray
    tt: float


def _fixed_columns(problem: _JointProblem, alpha: np.ndarray, w1: np.ndarray) -> _FixedColumns:
    """The columns that do not vary over an effect's grid, their Gram matrix formed once.

    Columns are scaled to unit norm (u in digits, the rest rad/s).
    """
    rows, use, regimes = problem.rows, problem.use, problem.regimes
    f_mat = np.zeros((int(use.sum()), 3 * len(regimes)))
    w0, sgn, speed, brk = rows.w0[use], rows.sgn[use], rows.speed[use], rows.brk[use]
    for i, r in enumerate(regimes):
        m = problem.in_regime[i]
        shape = np.where(brk[m] > 0, 1.0, np.exp(-alpha[r] * speed[m]))
        f_mat[m, 3 * i : 3 * i + 3] = np.column_stack([w0[m], -sgn[m], -sgn[m] * shape])
    f_norm = np.linalg.norm(f_mat, axis=0)
    f_norm = np.where(f_norm > 0, f_norm, 1.0)
    f_mat /= f_norm
    target = w1[use]
    return _FixedColumns(
        f_mat, f_norm, target, f_mat.T @ f_mat, f_mat.T @ target, float(target @ target)
    )


def _solve_block(problem: _JointProblem, cols: _FixedColumns, u0: np.ndarray, extra: np.ndarray):
    """The bounded block problem with command `u0` (K,) and effect columns `extra` (K, k_e).

    Solved on the Cholesky factor of the Gram matrix of ``[A | w1]``
    (``||A x - w1||^2 = ||R x - q||^2 + rest^2``: ~20 rows instead of ~10^4),
    a relative 1e-12 ridge keeping it defined for collinear columns; bounds
    as in `equation_error_estimate` (bvls on unit-norm columns). Returns
    (sse, regime coefficients (n_r, 4) as (a, gain, Tc, Ts - Tc), effect
    coefficients (k_e,)).
    """
    from scipy.optimize import lsq_linear

    use, in_regime, n_r = problem.use, problem.in_regime, len(problem.regimes)
    f_mat, f_norm = cols.f_mat, cols.f_norm
    k_e = extra.shape[1]
    v_mat = np.zeros((f_mat.shape[0], n_r + k_e))
    u0 = u0[use]
    for i in range(n_r):
        v_mat[in_regime[i], i] = u0[in_regime[i]]
    v_mat[:, n_r:] = extra[use]
    v_norm = np.linalg.norm(v_mat, axis=0)
    v_norm = np.where(v_norm > 0, v_norm, 1.0)
    v_mat /= v_norm
    fv, vv, vt = f_mat.T @ v_mat, v_mat.T @ v_mat, v_mat.T @ cols.target
    n_c = 4 * n_r + k_e
    gram = np.empty((n_c + 1, n_c + 1))
    nf = 3 * n_r
    gram[:nf, :nf], gram[:nf, nf:n_c], gram[nf:n_c, nf:n_c] = cols.ff, fv, vv
    gram[nf:n_c, :nf] = fv.T
    gram[:nf, n_c], gram[nf:n_c, n_c], gram[n_c, n_c] = cols.ft, vt, cols.tt
    gram[n_c, :n_c] = gram[:n_c, n_c]
    gram[np.diag_indices_from(gram)] += 1e-12 * np.trace(gram)
    tri = np.linalg.cholesky(gram).T
    norm = np.r_[f_norm, v_norm]
    lo = np.r_[np.zeros(nf + n_r), np.full(k_e, -np.inf)]
    hi = np.full(n_c, np.inf)
    hi[0:nf:3] = 1.0 - 1e-9
    fit = lsq_linear(tri[:n_c, :n_c], tri[:n_c, n_c], bounds=(lo * norm, hi * norm), method="bvls")
    coef = fit.x / norm
    sse = float(np.sum(fit.fun**2) + tri[n_c, n_c] ** 2)
    fixed_c = coef[:nf].reshape(n_r, 3)
    reg = np.column_stack([fixed_c[:, 0], coef[nf : nf + n_r], fixed_c[:, 1], fixed_c[:, 2]])
    return sse, reg, coef[nf + n_r :]


def _hold_factor(pole: np.ndarray, integration: Integration) -> np.ndarray:
    """Per regime, what a constant acceleration held over a sample moves the
    rate by, over accel*T: ``(1 - a)/(-ln a)`` at the regime's pole a with
    `integration`'s exact effect hold, else 1 (Eq. 6's ``accel*T``), (n_regimes,).

    A continuous axis moves the rate by that much, so without it a joint
    estimate's strength comes out low by it on a fast axis.
    """
    if not integration.exact_effect_hold:
        return np.ones_like(pole)
    return sample_hold_factor(pole)


def _joint_torque_pass(
    problem: _JointProblem,
    name: str,
    alpha: np.ndarray,
    params: dict[str, float],
    hold: np.ndarray | None = None,
) -> tuple[float, np.ndarray, dict[str, float]]:
    """One block solve of a torque effect linear in its strengths; (sse, regimes, params).

    Cogging ``T (s sin(2 pi y/P) + c cos(2 pi y/P))`` with the period P on a
    grid of +-3 % around the given one (a residual periodogram finds it; the
    strengths come from here), unbalance ``T (s sin y + c cos y)``, cable
    spring ``-T k y`` (its offset is a constant torque, exactly a shift of
    the per-direction friction levels: held at the given value). `hold`:
    per regime, the rate change per sample of a unit acceleration over T
    (`_hold_factor`; None: 1).
    """
    rows, dt, params = problem.rows, problem.dt, dict(params)
    # Each row's torque columns scaled by its regime's hold factor: the
    # strengths are then accelerations, as the model applies them.
    row_hold = (np.ones(RATE_LAYOUT.n_regimes) if hold is None else hold)[rows.regime]
    w1 = rows.w1.copy()
    if name == "cable_spring":
        w1 = w1 - dt * row_hold * params["offset_rad_s2"]
    u0 = problem.u_all[rows.step]
    if name == "cogging":
        shapes = params["period_rad"] * (1.0 + np.linspace(-0.03, 0.03, 61))
    else:
        shapes = np.array([0.0])
    cols = _fixed_columns(problem, alpha, w1)
    best = None
    for shape in shapes:
        extra = _torque_columns(name, rows.y, shape, dt) * row_hold[:, None]
        sse, reg, eff = _solve_block(problem, cols, u0, extra)
        if best is None or sse < best[0]:
            best = (sse, reg, eff, shape)
    sse, reg, eff, shape = best
    if name == "cogging":
        amp, ph = float(np.hypot(*eff)), float(np.arctan2(eff[1], eff[0]))
        params.update(amplitude_rad_s2=amp, period_rad=float(shape), phase_rad=ph)
    elif name == "unbalance":
        amp, ph = float(np.hypot(*eff)), float(np.arctan2(eff[1], eff[0]))
        params.update(amplitude_rad_s2=amp, phase_rad=ph)
    else:
        params.update(stiffness_1_s2=float(eff[0]))
    return sse, reg, params


#: Pre-sliding distances tried by `_joint_lugre_pass` [rad]: 15 per decade
#: over the effect's range of interest (the reference draws 0.2-5 mrad).
_LUGRE_PRESLIDING_GRID = np.geomspace(2e-5, 2e-2, 46)


def _lugre_columns(data, zmax: np.ndarray, side_source: str) -> np.ndarray:
    """LuGre's acceleration per unit bristle force along the measured runs,
    times T, for each pre-sliding distance: (sum N-1, G).

    The library's own effect (`isp_twin.model.effects.lugre`) run on the
    measured rate, one sample late as `simulate` feeds it (`_effect_drive`).
    """
    parts = []
    for d in data:
        eff = make_batched(
            "lugre", {"accel_rad_s2": np.ones_like(zmax), "presliding_rad": zmax}, d.dt
        )
        y = side_angle(d, side_source)
        col = np.empty((len(d) - 1, zmax.size))
        for k in range(len(d) - 1):
            col[k] = eff.acceleration(y[k], np.full(zmax.size, d.omega[k])) * d.dt
        parts.append(col)
    return np.concatenate(parts)


def _joint_lugre_pass(
    problem: _JointProblem, data, side_source: str, alpha: np.ndarray, params: dict[str, float]
) -> tuple[float, np.ndarray, dict[str, float]]:
    """LuGre with the base: the pre-sliding distance on a grid (`_LUGRE_PRESLIDING_GRID`
    and the given value), the bristle force linear for each; (sse, regimes, params).

    In steady sliding the bristle force is a constant per direction, exactly
    a shift of the Coulomb levels; what sets it apart is the turn-round over
    about ``z_max`` of travel after each reversal or breakaway, which the
    rows after a reversal hold. A negative force is not physical: such grid
    points are skipped (the given parameters are kept when all are).
    """
    rows, params = problem.rows, dict(params)
    grid = np.union1d(_LUGRE_PRESLIDING_GRID, [params["presliding_rad"]])
    lo_b, hi_b = effect_class("lugre").bounds["presliding_rad"]
    grid = grid[(grid >= lo_b) & (grid <= hi_b)]
    columns = _lugre_columns(data, grid, side_source)[rows.step]
    u0 = problem.u_all[rows.step]
    cols = _fixed_columns(problem, alpha, rows.w1)
    best = None
    for i, zmax in enumerate(grid):
        sse, reg, eff = _solve_block(problem, cols, u0, columns[:, i : i + 1])
        if eff[0] > 0.0 and (best is None or sse < best[0]):
            best = (sse, reg, eff, zmax)
    if best is None:
        sse, reg, _ = _solve_block(problem, cols, u0, np.zeros((rows.w0.size, 0)))
        return sse, reg, params
    sse, reg, eff, zmax = best
    params.update(accel_rad_s2=float(eff[0]), presliding_rad=float(zmax))
    return sse, reg, params


def _joint_command_pass(
    problem: _JointProblem, data, name: str, alpha: np.ndarray, params, cls
) -> tuple[float, np.ndarray, dict[str, float]]:
    """One grid of a command effect's parameter (delay, dead zone, saturation); (sse, regimes, params).

    The command column is transformed by the effect at each grid value
    (within the effect class `cls`'s bounds, the given value included).
    """
    pname = _COMMAND_EFFECTS[name]
    dt, u_peak, rows = problem.dt, problem.u_peak, problem.rows
    if name == "input_delay":
        grid = np.arange(0.0, 40.5, 0.5) * dt
    elif name == "deadzone":
        grid = np.linspace(0.0, 0.4, 81) * u_peak
    else:
        grid = np.linspace(0.3, 1.0, 71) * u_peak
    grid = np.union1d(grid, [params[pname]])
    lo_b, hi_b = cls.bounds[pname]
    grid = grid[(grid >= lo_b) & (grid <= hi_b)]
    columns = _command_columns(name, data, problem.u_all, grid, dt)
    cols = _fixed_columns(problem, alpha, rows.w1)
    best = None
    for value, u_col in zip(grid, columns):
        sse, reg, eff = _solve_block(problem, cols, u_col[rows.step], np.zeros((rows.w0.size, 0)))
        if best is None or sse < best[0]:
            best = (sse, reg, eff, value)
    sse, reg, _, value = best
    return sse, reg, {**params, pname: float(value)}


def _effect_drive(
    d: MeasuredData, side_y: np.ndarray, effects: Sequence[EffectSpec]
) -> tuple[np.ndarray, np.ndarray]:
    """Command and extra rate drive of known effects along a run, shapes (N-1,).

    Returns the command after the effects' `command` hooks [digits] and the
    effects' acceleration times T [rad/s per sample], both evaluated on the
    measured angle and rate (as `simulate` feeds them, one step late). Sensor
    effects are not inverted: they only bias the start.
    """
    u = np.array(d.u[:-1], dtype=float)
    more = np.zeros_like(u)
    if not effects:
        return u, more
    built = [make_effect(e, d.dt) for e in effects]
    if all(type(e).reset is Effect.reset for e in built):
        # Effects without state are plain functions of the sample: whole run at once.
        for e in built:
            u = np.asarray(e.command(u), dtype=float) * np.ones_like(more)
        for e in built:
            more = more + np.asarray(e.acceleration(side_y[: u.size], d.omega[: u.size])) * d.dt
        return u, more
    for e in built:
        e.reset()
    for k in range(u.size):
        for e in built:
            u[k] = e.command(u[k])
        more[k] = sum(float(e.acceleration(side_y[k], d.omega[k])) for e in built) * d.dt
    return u, more


def sensor_bias_joint_starts(
    data: Sequence[MeasuredData],
    base: RateParams,
    side_source: str = "measured",
    effects: Sequence[EffectSpec] = (),
) -> tuple[JointEstimate, ...]:
    """The `sensor_bias` effect and the base together, two ways: the gyro
    error from the angle (`gyro_error_estimate`) with (1) the base fitted to
    the gyro reading mapped back to the true rate (`rate_behind_gyro_error`),
    and (2) the base estimated by equation error from the readings with that
    error taken out (`equation_error_estimate`, `effects` held).

    (1) keeps what a base that converged on the reading knows (in motion it
    absorbed the error exactly); (2) does not inherit a base the error threw
    off: a bias reads as motion where the axis is at rest, and on reference
    sensor_bias seed 100 (a bias of 17 noise sigmas) `identify` left the
    first training run at 146 noise floors; mapped back, that base restarted
    to a bias 3.8x the measured one, from (2) to the noise
    (docs/diagnosis.md "Stop 37").

    Returns both starts, or none when the estimate's 95 % intervals contain
    the exact gyro (b = 0 and s = 0): the angle shows no gyro error to start from.
    """
    est = gyro_error_estimate(data)
    if est.contains_null():
        return ()
    spec = EffectSpec("sensor_bias", {"bias_rad_s": est.bias_rad_s, "scale": est.scale})
    fresh = equation_error_estimate(data, base, side_source, effects=(*effects, spec))
    nan = float("nan")
    return (
        JointEstimate(rate_behind_gyro_error(base, est), spec, nan, nan),
        JointEstimate(fresh, spec, nan, nan),
    )
