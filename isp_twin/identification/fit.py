"""Identification of the per-regime parameters of Eq. 6 from open-loop runs.

The pipeline (Eq. 8-9 of the paper, made identifiable):

1. **What the data determine.** Rate data fix only the rate form of Eq. 6
   (`RateParams`): per regime the pole a, the gain b·Ke, the static and
   Coulomb levels b·Ts, b·Tc and the curve factor alpha (20 numbers per
   axis). b alone is the paper's "multi-value problem": scaling b up and
   Ke, Ts, Tc down leaves every response unchanged. b is therefore **fixed to
   its prior** (default the paper's Table 2) and Ke, Ts, Tc follow from the
   identified products; b gets no confidence interval.
2. **Which regimes the data visit.** A regime (side of the angle x direction)
   with fewer than `Settings.min_regime_samples` moving samples is not
   identified: its five numbers are frozen at the prior, it is written with
   ``identified: false`` and gets no interval.
3. **Initial estimate.** One-step-ahead (equation-error) least squares per
   regime, with the physical bounds: for a fixed alpha, Eq. 6 is linear in
   (a, b·Ke, b·Tc, b·(Ts-Tc)), and break-away samples add b·Ke and b·Ts;
   alpha is found by a grid. Nothing comes from the prior's values.
4. **Local refinement.** `scipy.optimize.least_squares` on Eq. 9's residual
   vector in log variables (`_to_z`) with limits from the data
   (`_z_limits`), a batched finite-difference Jacobian; then the read-out
   timing (`Timing`) is chosen from the data and the fit refined with it.
5. **Global search**, only when the fit is still above
   `Settings.converged_ratio` noise floors: differential evolution (scipy,
   seeded, vectorized: the population is the batch dimension of
   `isp_twin.model.axis_model.simulate`) in a box around the best point, then
   least squares again. The result is taken in the form the parameter file
   stores (6 digits), moved off a stick/slip threshold if the rounding would
   spoil the fit (`_robust_to_storage`).
6. **Confidence intervals** (`isp_twin.estimation.intervals`): ``cov = s^2 (J^T J)^-1``,
   inflated by ``(1 + rho)/(1 - rho)`` for a lag-1 residual correlation
   rho > 0 (effective sample size), with the Student t quantile. A
   quantity is reported identifiable when its regime is visited and its
   interval, computed with a noise floor of 0.1 % of the rate RMS, is below
   half its value (so noise-free data does not make everything "identifiable").

The simulation is driven by the measured angle (teacher forcing) to pick the
half-plane: the friction depends on where the gimbal really is, and a
simulated angle that drifts by a fraction of a degree would switch regimes at
the wrong time and make the cost jump. Eq. 6 switches regime exactly at
angle 0, so even resolver quantization matters: one LSB (0.0055 deg) at
3 deg/s moves the crossing by two samples, and the L and R dynamics differ so
much that the rate error then lasts tens of samples. The side is therefore
taken from the angle fused with the integrated gyro rate (`fused_angle`);
``side_source="raw"`` uses the angle as measured. For a free-spinning motor
(angle of many turns) the half-plane split has no meaning: the side source
(`Settings.side_source`, CLI ``--side``) can fix the side (``right``/``left``)
or wrap the angle to (-pi, pi] (``wrap``). A side source says where the side
is read from; the side itself is `isp_twin.vocabulary`'s `SIDE_R`/`SIDE_L`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from isp_twin.errors import DataError, ParameterError
from isp_twin.estimation.intervals import confidence_intervals
from isp_twin.estimation.parameter_file import fitted_axis, stored_form
from isp_twin.estimation.simulation_error import RunStack, predict_one, stack_runs
from isp_twin.estimation.simulation_error import residuals as simulation_residuals
from isp_twin.estimation.verdict import noise_floor_of
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.effects import Effect, effect_class, make_effect
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.friction import regime_index
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    AxisParams,
    EffectSpec,
    FittedWith,
    RateParams,
    sample_hold_factor,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.units import DEG

__all__ = [
    "RATE_FIELDS",
    "SIDE_SOURCES",
    "TIMINGS",
    "Timing",
    "fitted_with",
    "recorded_model",
    "gyro_reading",
    "rate_noise",
    "Settings",
    "IdentificationResult",
    "IdentificationStatus",
    "SearchStep",
    "fused_angle",
    "side_angle",
    "regime_visits",
    "equation_error_estimate",
    "JOINT_FORMS",
    "JointEstimate",
    "joint_equation_error_estimate",
    "simulate_data",
    "residuals",
    "rmse",
    "identify",
    "to_axis_params",
]

#: Names of the rate-form quantities per regime, `RateParams.to_vector` order
#: (`RATE_LAYOUT.fields`, kept under this name for callers of this module).
RATE_FIELDS: tuple[str, ...] = RATE_LAYOUT.fields
#: Side sources: where each step's side (R/L half-plane) is read from (the
#: fused or raw measured angle, the wrapped angle, or a fixed side).
SIDE_SOURCES: tuple[str, ...] = ("measured", "raw", "wrap", "right", "left")
#: Window of the angle/rate fusion [samples] (`fused_angle`).
FUSION_WINDOW = 201

#: Noise floor for the identifiability test, relative to the rate RMS.
_REFERENCE_NOISE = 1e-3
#: Largest relative 95 % half-width of an identifiable quantity.
_MAX_RELATIVE_CI = 0.5


@dataclass(frozen=True)
class Timing:
    """What a sample of the data means in time, for the model's read-out.

    Attributes:
        side_shift: when in each step the half-plane is read [steps after
            the step's start; a step is a sample for Eq. 6, a sub-step for
            the sub-stepped model] (`side_angle`).
        gyro_average: the gyro reports the rate averaged over the sample
            period (most rate sensors integrate or filter), modelled as the
            mean of the model's rate at both ends of the step; else the rate
            at the sample instant (Eq. 6 as written).
    """

    side_shift: float = 0.0
    gyro_average: bool = False

    def describe(self) -> str:
        kind = "averaged over the sample" if self.gyro_average else "at the sample"
        return f"gyro rate {kind}, half-plane read at step start + {self.side_shift:g} step"


#: Read-out timings tried by `identify` (``side_source="measured"``); the paper's Eq. 6 first.
TIMINGS: tuple[Timing, ...] = tuple(
    Timing(shift, avg) for avg in (False, True) for shift in (0.0, 0.25, 0.5, 0.75)
)


def fitted_with(integration: Integration, timing: Timing) -> FittedWith:
    """The parameter file's record (`FittedWith`) of a fit's model and read-out timing."""
    return FittedWith(
        substeps=int(integration.substeps),
        midpoint_friction=bool(integration.midpoint_friction),
        split_reversals=bool(integration.split_reversals),
        exact_effect_hold=bool(integration.exact_effect_hold),
        gyro_average=bool(timing.gyro_average),
        side_shift_steps=float(timing.side_shift),
    )


def recorded_model(record: FittedWith) -> tuple[Integration, Timing]:
    """The model integration and read-out timing a `FittedWith` record names."""
    integration = Integration(
        record.substeps,
        record.midpoint_friction,
        record.split_reversals,
        record.exact_effect_hold,
    )
    return integration, Timing(record.side_shift_steps, record.gyro_average)


@dataclass(frozen=True)
class Settings:
    """Identification settings.

    Attributes:
        seed: seed of the evolutionary search (same seed -> same result).
        generations: differential-evolution generations (0: skip the search).
        population: population size per generation.
        refine: run the least-squares refinement.
        refine_evaluations: budget of the refinement [Jacobian evaluations].
        min_regime_samples: moving samples below which a regime is not identified.
        rest_rate_deg_s: |rate| at or below this counts as "at rest" [deg/s].
        side_source: where the side is read from, one of `SIDE_SOURCES`.
        confidence: level of the intervals.
        converged_ratio: the global search runs when the least-squares fit
            from the data's own start ends above this multiple of the rate
            noise (`rate_noise`).
        prior_in_search: also start from the prior's values (by default the
            prior only supplies b, unvisited regimes and held effects).
        timing: the data's read-out timing (`Timing`); None: the one of
            `TIMINGS` that fits best (``side_source="measured"``; else Eq. 6's).
        integration: how the model integrates a sample
            (`isp_twin.model.substep_model.Integration`; `EQ6` is the paper's Eq. 6).
    """

    seed: int = 0
    generations: int = 20
    population: int = 40
    refine: bool = True
    refine_evaluations: int = 200
    min_regime_samples: int = 50
    rest_rate_deg_s: float = 0.1
    side_source: str = "measured"
    confidence: float = 0.95
    converged_ratio: float = 1.2
    prior_in_search: bool = False
    timing: Timing | None = None
    integration: Integration = DEFAULT_INTEGRATION

    def __post_init__(self):
        if self.side_source not in SIDE_SOURCES:
            raise ParameterError(
                f"side source '{self.side_source}' unknown; allowed: {', '.join(SIDE_SOURCES)}"
            )
        if self.population < 5 or self.generations < 0:
            raise ParameterError("population >= 5 and generations >= 0 required")


class IdentificationStatus(Enum):
    """How an identification ended (`IdentificationResult.outcome`).

    AT_NOISE: the fit is within `Settings.converged_ratio` noise floors.
    CONVERGED: above that, the last least-squares refinement met its
    tolerance (a local optimum the model cannot improve on: the data may
    hold an effect the model lacks). MAX_EVALUATIONS: above that, the last
    refinement ran out of its budget. NOT_AT_NOISE: above that, and no
    refinement ran (refinement off: the equation-error estimate or the
    global search's best point).
    """

    AT_NOISE = "at_noise"
    CONVERGED = "converged"
    MAX_EVALUATIONS = "max_evaluations"
    NOT_AT_NOISE = "not_at_noise"


@dataclass(frozen=True)
class SearchStep:
    """One entry of an identification's per-iteration log.

    Attributes:
        stage: "start" (the equation-error estimate), "refine" (after a
            least-squares refinement), "timing" (the read-out timing chosen
            at the best point) or "search" (a differential-evolution generation).
        evaluations: simulated parameter sets so far.
        best_cost: the best Eq. 9 cost so far [rad/s] (the `history` entry).
    """

    stage: str
    evaluations: int
    best_cost: float

    def to_json(self) -> dict:
        return {
            "stage": self.stage,
            "evaluations": self.evaluations,
            "best_cost_deg_s": self.best_cost / DEG,
        }


@dataclass(frozen=True)
class IdentificationResult:
    """The outcome of `identify` for one axis.

    Vectors of shape (20,) follow `RateParams.to_vector` order: per regime
    (R+, R-, L+, L-) the quantities of `RATE_FIELDS`, SI rate form.

    Attributes:
        rate: identified rate-form parameters, arrays (4,).
        ci95: 95 % half-widths, shape (20,); NaN where not identifiable.
        identifiable: shape (20,), True where the data determine the quantity.
        visits: moving samples per regime, shape (4,).
        regime_identified: per regime, False where the prior was kept.
        rmse_train: per training set, RMS rate error [rad/s].
        cost: Eq. 9 over all training sets [rad/s].
        history: best cost per generation, then per refinement step [rad/s].
        initial_cost: Eq. 9 at the equation-error estimate [rad/s].
        rho: lag-1 autocorrelation of the residuals.
        evaluations: simulated parameter sets in total.
        wall_time_s: duration [s].
        status: short text on how the search ended.
        settings: the settings used.
        effects: the prior's extra effects, held fixed in every simulation
            of the fit (and of the report).
        timing: the read-out timing the fit used (`Timing`).
        noise: white rate-noise standard deviation of the data (`rate_noise`),
            the error a perfect model leaves [rad/s].
        integration: how the fitted model integrates a sample (`Integration`).
        outcome: how the search ended (`IdentificationStatus`).
        log: per-iteration log, one `SearchStep` per `history` entry.
    """

    rate: RateParams
    ci95: np.ndarray
    identifiable: np.ndarray
    visits: np.ndarray
    regime_identified: tuple[bool, ...]
    rmse_train: dict[str, float]
    cost: float
    history: tuple[float, ...]
    initial_cost: float
    rho: float
    evaluations: int
    wall_time_s: float
    status: str
    settings: Settings = field(default_factory=Settings)
    effects: tuple[EffectSpec, ...] = ()
    timing: Timing = Timing()
    noise: float = float("nan")
    integration: Integration = DEFAULT_INTEGRATION
    outcome: IdentificationStatus = IdentificationStatus.NOT_AT_NOISE
    log: tuple[SearchStep, ...] = ()

    @property
    def vector(self) -> np.ndarray:
        return self.rate.to_vector()


# ------------------------------------------------------------ data views


def fused_angle(data: MeasuredData, window: int = FUSION_WINDOW) -> np.ndarray:
    """The measured angle refined by the integrated rate [rad], shape (N,).

    ``integral(omega) + smooth(angle - integral(omega))`` with a centred moving
    average of `window` samples: the rate supplies the fine timing, the angle
    the absolute level (and removes gyro drift slower than the window).
    """
    integral = np.cumsum(data.omega) * data.dt
    gap = data.angle - integral
    n = gap.shape[0]
    w = max(1, min(window, n if n % 2 else n - 1))
    padded = np.pad(gap, w // 2, mode="edge")
    smooth = np.convolve(padded, np.ones(w) / w, mode="valid")
    return integral + smooth


def side_angle(data: MeasuredData, side_source: str = "measured", shift: float = 0.0) -> np.ndarray:
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
    """
    if side_source == "measured":
        y = fused_angle(data)
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


def run_stack(
    data: Sequence[MeasuredData],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> RunStack:
    """The runs as Eq. 9 sees them, stacked for the shared simulation error
    (`isp_twin.estimation.simulation_error`): the half-plane from the
    `side_source` angle read at `timing`, every sample after the first
    counted, a first rate within `rest_rate_deg_s` [deg/s] taken as rest."""
    shift = timing.side_shift / integration.substeps
    runs = [replace(d, angle=side_angle(d, side_source, shift)) for d in data]
    return stack_runs(
        runs,
        warmup=1,
        gyro_average=timing.gyro_average,
        integration=integration,
        rest=rest_rate_deg_s * DEG,
    )


def simulate_data(
    rate: RateParams,
    d: MeasuredData,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
):
    """The model (Eq. 6 in `integration`'s sub-steps) driven by the run's
    command and measured angle; `AxisResponse`.

    `effects` (a parameter file's ``effects:``) are held fixed. With
    ``timing.gyro_average`` the returned rate is what a gyro averaging over
    each sample period reads (`Timing`).
    """
    stack = run_stack([d], side_source, rest_rate_deg_s, timing, integration)
    resp = predict_one(stack, rate.to_vector(), tuple(effects))
    return type(resp)(
        *(
            None if a is None else a[0]
            for a in (resp.omega, resp.angle, resp.regime, resp.omega_true)
        )
    )


def gyro_reading(omega: np.ndarray, average: bool) -> np.ndarray:
    """What the gyro reads of the model's rate, shape (..., N) along time.

    ``average``: the mean of the rate at both ends of each step (a gyro that
    averages over the sample period); else the rate itself.
    """
    if not average:
        return omega
    out = np.array(omega, dtype=float, copy=True)
    out[..., 1:] = 0.5 * (omega[..., 1:] + omega[..., :-1])
    return out


def residuals(
    rate: RateParams,
    data: Sequence[MeasuredData] | RunStack,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> np.ndarray:
    """Simulated minus measured rate [rad/s], sample 0 of each set left out.

    Shape (P, M) for batched params (M = total samples), else (M,). The
    shared simulation error (`isp_twin.estimation.simulation_error.residuals`)
    on `run_stack`'s stack; ``data`` may be that stack already (then the
    side source, rest level, timing and integration are the stack's).
    """
    single = np.ndim(rate.pole) == 1
    stack = (
        data
        if isinstance(data, RunStack)
        else run_stack(data, side_source, rest_rate_deg_s, timing, integration)
    )
    out = -simulation_residuals(stack, np.atleast_2d(rate.to_vector()), fixed=tuple(effects))
    return out[0] if single else out


def rmse(
    rate: RateParams,
    data: Sequence[MeasuredData],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> float | np.ndarray:
    """Eq. 9: RMS rate error over all sets at once [rad/s]."""
    e = residuals(rate, data, side_source, rest_rate_deg_s, effects, timing, integration)
    return np.sqrt(np.mean(e**2, axis=-1))


# ------------------------------------------------------------ initial estimate


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
    the regression. The rest level used to pick moving samples is at least
    four times the rate noise (`rate_noise`): noisy samples of an axis at rest
    would otherwise enter as motion.
    """
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
    for d in data:
        w0, w1 = d.omega[:-1], d.omega[1:]
        y = side_angle(d, side_source)[:-1]
        u0, more = _effect_drive(d, y, effects)
        w1 = w1 - more
        moving = (np.abs(w0) > rest) & (np.abs(w1) > rest) & (np.sign(w1) == np.sign(w0))
        # A breakaway moves the way the total drive (command and known
        # effects) pushes: its direction is that of the motion it starts.
        breakaway = (np.abs(w0) <= rest) & (np.abs(w1) > rest)
        use = moving | breakaway
        regime = np.where(moving, regime_index(y, w0), regime_index(y, w1))
        parts.append(
            (
                regime[use],
                np.where(moving, w0, 0.0)[use],
                w1[use],
                u0[use],
                np.where(moving, np.sign(w0), np.sign(w1))[use],
                np.where(moving, np.abs(w0), 0.0)[use],
                breakaway[use].astype(float),
                y[use],
                offset + np.flatnonzero(use),
            )
        )
        offset += w0.size
    cols = [np.concatenate([p[i] for p in parts]) if parts else np.empty(0) for i in range(9)]
    return _Rows(*cols)


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


def rate_noise(data: Sequence[MeasuredData]) -> float:
    """White rate-noise standard deviation of the measured runs [rad/s] (`noise_floor_of`)."""
    return noise_floor_of([d.omega for d in data])


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


# ------------------------------------------------------------ search


#: Half-widths of the global-search box around the best point, per regime, in
#: the log-parameters of `_to_z`: 1-a x/÷ 5, b·Ke x/÷ 3, b·Tc x/÷ 5,
#: b·(Ts-Tc) x/÷ 20, alpha x/÷ 30.
_Z_SPAN = np.log(np.array([5.0, 3.0, 5.0, 20.0, 30.0]))


#: Least squares stops when a step lowers the sum of squares by less than this
#: fraction (scipy's ``ftol``; its default 1e-8). The sum of squares of M
#: residuals has a sampling spread of sqrt(2/M) (1.3 % at 2 x 6000 samples):
#: a step of 1e-5 moves the RMS error by 5e-6 noise floors. On reference dev
#: axis 1021 the steps below it took 3500 of 5100 simulated sets (RMS error
#: 0.9910 -> 0.9905 of the noise sigma).
_REFINE_FTOL = 1e-5


def _to_z(x: np.ndarray) -> np.ndarray:
    """Rate-form vectors (..., 5k) -> search variables (..., 5k).

    Per regime ``(log(1-a), log b·Ke, log b·Tc, log b·(Ts-Tc), log alpha)``:
    positive by construction, Ts >= Tc always, and one relative scale for
    quantities spanning many decades (the pole's time constant from 1 ms to
    10 s, levels from 1e-6 to 1 rad/s per sample).
    """
    x = np.asarray(x, dtype=float)
    r = x.reshape(*x.shape[:-1], -1, RATE_LAYOUT.n_fields)
    a, g, st, c, al = (r[..., i] for i in range(5))
    tiny = 1e-300
    gap = np.maximum(st - c, 1e-6 * np.maximum(c, tiny))
    z = np.stack(
        [
            np.log(np.maximum(1.0 - a, 1e-12)),
            np.log(np.maximum(g, tiny)),
            np.log(np.maximum(c, tiny)),
            np.log(np.maximum(gap, tiny)),
            np.log(np.maximum(al, tiny)),
        ],
        axis=-1,
    )
    return z.reshape(x.shape)


def _from_z(z: np.ndarray) -> np.ndarray:
    """Inverse of `_to_z`."""
    z = np.asarray(z, dtype=float)
    r = z.reshape(*z.shape[:-1], -1, RATE_LAYOUT.n_fields)
    e = np.exp(r)
    x = np.stack([1.0 - e[..., 0], e[..., 1], e[..., 2] + e[..., 3], e[..., 2], e[..., 4]], axis=-1)
    return x.reshape(z.shape)


def _z_limits(x0: np.ndarray, u_peak: float, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Limits of the search variables from the data and physics, shapes (n_free,).

    Per regime: the time constant between 0.1 and 1e5 samples; the gain within
    a factor 1e3 of the start; the levels between 1e-4 and 3 times the peak
    drive (b·Ke times the largest command: a level below 1e-4 of it changes
    no response, and a floor keeps the log-variables from sliding to -inf,
    where their gradient vanishes); alpha*|omega|_rms between 1e-3 and 1e4.
    """
    r = np.asarray(x0, float).reshape(-1, RATE_LAYOUT.n_fields)
    drive = r[:, 1] * u_peak
    lo = np.column_stack(
        [
            np.full(len(r), np.log(1e-5)),
            np.log(r[:, 1] / 1e3),
            np.log(1e-4 * drive),
            np.log(1e-4 * drive),
            np.full(len(r), np.log(1e-3 / speed)),
        ]
    )
    hi = np.column_stack(
        [
            np.full(len(r), np.log(1.0 - np.exp(-10.0))),
            np.log(r[:, 1] * 1e3),
            np.log(3.0 * drive),
            np.log(3.0 * drive),
            np.full(len(r), np.log(1e4 / speed)),
        ]
    )
    return lo.ravel(), hi.ravel()


def _robust_to_storage(x: np.ndarray, cost, free: np.ndarray, b: np.ndarray, step: float = 1e-4):
    """A point whose stored (rounded) form keeps the fit; (x, moved?).

    Stick/slip makes the cost jump where a static level equals a drive the
    data hold for long (a torque step that only just breaks away): the
    optimum can sit on that cliff, and rounding the file's values then
    throws it off. If the stored form is more than 1 % worse, each free
    quantity is moved by ±`step` (relative) and the best stored candidate
    is taken (one batched simulation).
    """
    b = np.asarray(b, dtype=float)

    def cost_of(points_free: np.ndarray) -> np.ndarray:
        return np.atleast_1d(cost(points_free))

    stored = stored_form(_embed(x, free), b)
    exact = float(cost_of(x[None])[0])
    rounded = float(cost_of(stored[None][:, free])[0])
    if rounded <= 1.01 * exact + 1e-15:
        return stored[free], False
    deltas = np.vstack([np.diag(step * np.abs(x)), -np.diag(step * np.abs(x))])
    cands = stored_form(np.array([_embed(x + dlt, free) for dlt in deltas]), b)[:, free]
    costs = cost_of(cands)
    best = int(np.argmin(costs))
    if costs[best] < rounded:
        return cands[best], True
    return stored[free], False


def _embed(x_free: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Free quantities into a (`RATE_LAYOUT.size`,) vector (fixed ones: 1, never used after)."""
    out = np.ones(RATE_LAYOUT.size)
    out[free] = x_free
    return out


def identify(
    data: Sequence[MeasuredData],
    prior: AxisParams,
    settings: Settings = Settings(),
    progress: Callable[[str, int, float], None] | None = None,
) -> IdentificationResult:
    """Identify one axis from open-loop runs (all sets in one cost, Eq. 9).

    The stages (module doc): free parameters and start (`_FreeParameters`),
    read-out timing and local refinement (`_refine_from_start`), global
    search (`_global_search`), storage rounding (`_robust_to_storage`),
    intervals (`_intervals`).

    Args:
        data: the identification runs (same sample period; command in the
            unit the prior's Ke refers to).
        prior: prior parameters: b of every regime, the values kept for
            regimes the data do not visit, and the extra effects (held fixed:
            the fit is of Eq. 6 with them, as the twin runs it).
        settings: search budget, seed, regime rules.
        progress: called as ``progress(stage, step, best_cost_rad_s)`` with
            stage "search" (per generation) or "refine" (per evaluation,
            step = simulated parameter sets so far).

    Raises:
        DataError: no data, mixed sample periods, or no regime visited.
    """
    start = time.perf_counter()
    _check_sample_periods(data)
    free = _free_parameters(data, prior, settings)
    search = _Search(data, free, settings, tuple(prior.effects), progress)
    _refine_from_start(search, prior.rate_params().to_vector()[free.mask])
    _global_search(search)
    status = "; ".join(search.status_parts) or "equation-error estimate"
    x_best = _from_z(np.clip(search.z_best, search.z_lo, search.z_hi)[None])[0]
    b = np.array([r.b for r in prior.regimes])
    x_best, moved = _robust_to_storage(x_best, search.rmse_of, free.mask, b)
    if moved:
        status += (
            "; moved off a stick/slip threshold so that the stored 6-digit values reproduce the fit"
        )
    return _result(search, free, x_best, status, time.perf_counter() - start)


def _check_sample_periods(data: Sequence[MeasuredData]) -> None:
    """Raise `DataError` for no runs or runs of different sample periods."""
    if not data:
        raise DataError("no identification data given")
    dts = {round(d.dt, 12) for d in data}
    if len(dts) > 1:
        raise DataError(f"identification sets differ in sample period: {sorted(dts)} s")


@dataclass(frozen=True)
class _FreeParameters:
    """Which rate-form quantities a fit moves, and the fixed vector around them.

    Attributes:
        visits: moving samples per regime, shape (n_regimes,).
        visited: per regime, True where identified, shape (n_regimes,).
        mask: the free entries of the rate vector, shape (`RATE_LAYOUT.size`,).
        base: the full rate vector, prior where fixed and the equation-error
            estimate where free, shape (`RATE_LAYOUT.size`,).
    """

    visits: np.ndarray
    visited: np.ndarray
    mask: np.ndarray
    base: np.ndarray

    @property
    def x0(self) -> np.ndarray:
        """The start: the free quantities of `base`, shape (n_free,)."""
        return self.base[self.mask]

    def full(self, xf: np.ndarray) -> RateParams:
        """Free quantities (n_free,) or (P, n_free) -> batched `RateParams` (P,)."""
        xf = np.atleast_2d(xf)
        out = np.tile(self.base, (xf.shape[0], 1))
        out[:, self.mask] = xf
        return RateParams.from_vector(out)


def _free_parameters(
    data: Sequence[MeasuredData], prior: AxisParams, s: Settings
) -> _FreeParameters:
    """The visited regimes' quantities, started at the equation-error estimate."""
    visits = regime_visits(data, s.side_source, s.rest_rate_deg_s)
    visited = visits >= s.min_regime_samples
    if not visited.any():
        raise DataError(
            f"no regime has {s.min_regime_samples} moving samples (visits "
            f"{','.join(RATE_LAYOUT.regimes)}: {', '.join(map(str, visits))}); nothing to identify"
        )
    mask = RATE_LAYOUT.regime_mask(visited)
    prior_rate = prior.rate_params()
    x_init = equation_error_estimate(
        data, prior_rate, s.side_source, s.rest_rate_deg_s, s.min_regime_samples, prior.effects
    )
    base = prior_rate.to_vector()
    base[mask] = _interior_start(x_init.to_vector())[mask]
    return _FreeParameters(visits, visited, mask, base)


#: A level of the start below this fraction of its regime's static level is
#: "at its bound of 0" (`_interior_start`).
_AT_ZERO = 0.01


def _interior_start(x: np.ndarray) -> np.ndarray:
    """The equation-error start (`RATE_LAYOUT.size`,) moved off the zero bound of a level.

    The bounded equation-error fit often puts b·Tc (or b·(Ts-Tc)) at 0 when
    the Stribeck column is nearly collinear with sign(w) and w. The search
    moves log b·Tc, whose gradient is b·Tc times that in b·Tc: from ~0 the
    least squares crawls (reference dev axis 1002: 5100 simulated sets, the
    Stribeck curve of R+ still off and the held-out error 3.6 noise floors;
    1017: b·Tc left at 1e-3 of the truth, held-out 97 floors). Such a level
    starts at half the regime's static level instead (Ts/Tc = 2, inside the
    range 1-3 of bearings and gears), where its gradient is that of a level.
    Seeds 1002, 1008, 1015, 1017 (dev) shaped this choice.
    """
    r = RATE_LAYOUT.as_table(np.asarray(x, float)).copy()
    i_static, i_coulomb = RATE_LAYOUT.field_index("static"), RATE_LAYOUT.field_index("coulomb")
    static = r[:, i_static]
    low = r[:, i_coulomb] < _AT_ZERO * static
    r[low, i_coulomb] = 0.5 * static[low]
    return RATE_LAYOUT.from_table(r)


class _Search:
    """The working state of one `identify` call (created and dropped inside it).

    Holds the problem (runs, free parameters, limits of the log-variables)
    and what the stages share: the read-out timing in use, the count of
    simulated parameter sets, the best point and cost, the cost history and
    per-iteration log, the status text, and the last residual/Jacobian (so
    least squares' separate residual and Jacobian calls simulate once).
    """

    def __init__(
        self,
        data: Sequence[MeasuredData],
        free: _FreeParameters,
        s: Settings,
        effects: tuple[EffectSpec, ...],
        progress: Callable[[str, int, float], None] | None,
    ) -> None:
        self.data, self.free, self.s, self.effects, self.progress = data, free, s, effects, progress
        self.timing = Timing()
        self._stacked: tuple[Timing, RunStack] | None = None
        self.evaluations = 0
        self.initial_cost = float(self.batch_cost(free.x0[:, None])[0])
        self.history: list[float] = [self.initial_cost]
        self.log: list[SearchStep] = [SearchStep("start", self.evaluations, self.initial_cost)]
        self.status_parts: list[str] = []
        self.last_refinement: int | None = None  # scipy least_squares status
        self.noise = rate_noise(data)
        self.target = s.converged_ratio * self.noise
        u_peak = max(float(np.max(np.abs(d.u))) for d in data)
        speed = float(np.sqrt(np.mean(np.concatenate([d.omega for d in data]) ** 2)))
        self.z_lo, self.z_hi = _z_limits(free.x0, u_peak, max(speed, 1e-9))
        self.cache: dict[str, np.ndarray] = {}
        self.starts: list[np.ndarray] = [_to_z(free.x0)]
        self.z_best = self.starts[0]
        self.best_cost = np.inf

    def _model(self) -> tuple:
        """What `residuals` and `rmse` take after the parameters: the data
        (stacked once per read-out timing) and this search's side source, rest
        level, effects, timing and integration."""
        s = self.s
        if self._stacked is None or self._stacked[0] != self.timing:
            stack = run_stack(
                self.data, s.side_source, s.rest_rate_deg_s, self.timing, s.integration
            )
            self._stacked = (self.timing, stack)
        return (
            self._stacked[1],
            s.side_source,
            s.rest_rate_deg_s,
            self.effects,
            self.timing,
            s.integration,
        )

    def residuals_of(self, xs: np.ndarray) -> np.ndarray:
        """`residuals` at free quantities (P, n_free) with this search's timing."""
        return residuals(self.free.full(xs), *self._model())

    def rmse_of(self, xs: np.ndarray) -> np.ndarray:
        """Eq. 9 at free quantities (P, n_free), not counted as evaluations."""
        return rmse(self.free.full(xs), *self._model())

    def batch_cost(self, xt: np.ndarray) -> np.ndarray:
        """Eq. 9 at free quantities (n_free, S) (the evolutionary search's shape)."""
        self.evaluations += xt.shape[1]
        return np.atleast_1d(self.rmse_of(xt.T))

    def z_cost(self, zs: np.ndarray) -> np.ndarray:
        """Eq. 9 at search variables (S, n_free), clipped to their limits."""
        return self.batch_cost(_from_z(np.clip(zs, self.z_lo, self.z_hi)).T)

    def evaluate(self, z: np.ndarray, jacobian: bool) -> None:
        """The residual at z, and with `jacobian` its forward differences.

        The columns are simulated only when asked for: least squares needs
        none at a trial point it then rejects (each column costs one set).
        """
        h = np.full(z.size, 1e-6)
        cache = self.cache
        if "z" not in cache or not np.array_equal(cache["z"], z):
            pts = np.vstack([z, z + np.diag(h)]) if jacobian else z[None]
            self.evaluations += pts.shape[0]
            e = self.residuals_of(_from_z(pts))
            cache.clear()
            cache.update(z=z.copy(), e=e[0])
            if jacobian:
                cache["j"] = ((e[1:] - e[0]) / h[:, None]).T
            if self.progress is not None:
                self.progress("refine", self.evaluations, float(np.sqrt(np.mean(e[0] ** 2))))
        elif jacobian and "j" not in cache:
            pts = z + np.diag(h)
            self.evaluations += pts.shape[0]
            e = self.residuals_of(_from_z(pts))
            cache["j"] = ((e - cache["e"]) / h[:, None]).T

    def resid(self, z: np.ndarray) -> np.ndarray:
        self.evaluate(z, jacobian=False)
        return self.cache["e"]

    def jac(self, z: np.ndarray) -> np.ndarray:
        self.evaluate(z, jacobian=True)
        return self.cache["j"]

    def refine(self, z: np.ndarray, budget: int) -> tuple[np.ndarray, float, str]:
        """Least squares on Eq. 9's residuals from z; (z, cost, scipy's message)."""
        from scipy.optimize import least_squares

        ls = least_squares(
            self.resid,
            np.clip(z, self.z_lo, self.z_hi),
            jac=self.jac,
            bounds=(self.z_lo, self.z_hi),
            x_scale="jac",
            max_nfev=budget,
            method="trf",
            ftol=_REFINE_FTOL,
        )
        self.last_refinement = int(ls.status)
        return ls.x, float(np.sqrt(2 * ls.cost / ls.fun.size)), ls.message.rstrip(".")

    def record(self, stage: str, cost: float | None = None) -> None:
        """Append the best cost (or `cost`) to the history and the log."""
        value = self.best_cost if cost is None else cost
        self.history.append(value)
        self.log.append(SearchStep(stage, self.evaluations, value))

    def keep_better(
        self, z: np.ndarray, cost: float, label: str, stage: str = "", budget: int = 0
    ) -> None:
        """Refine from z (when refinement is on); keep the result if it beats the best.

        The best cost goes to the history after a refinement, or when a
        `stage` names the step (recorded without refinement too).
        """
        refined = self.s.refine and self.s.refine_evaluations > 0
        if refined:
            z, cost, msg = self.refine(z, budget or self.s.refine_evaluations)
            self.status_parts.append(f"least squares from {label} ({msg})")
        if cost < self.best_cost:
            self.z_best, self.best_cost = z, cost
        if refined or stage:
            self.record("refine" if refined else stage)

    def best_timing(self, z: np.ndarray, options=TIMINGS) -> tuple[Timing, float]:
        """The read-out timing of `options` with the lowest cost at z, and that cost.

        Leaves the search at that timing.
        """
        costs = {}
        for candidate in options:
            self.timing = candidate
            costs[candidate] = float(self.z_cost(z[None])[0])
        self.timing = min(costs, key=costs.get)
        return self.timing, costs[self.timing]


def _refine_from_start(search: _Search, prior_free: np.ndarray) -> None:
    """Read-out timing and least-squares refinement from the data's start.

    `prior_free`: the prior's free quantities, a second start with
    `Settings.prior_in_search`.
    """
    s = search.s
    starts = search.starts
    if s.prior_in_search:
        starts.append(_to_z(prior_free))
    if s.timing is not None or s.side_source != "measured":
        if s.timing is not None:
            search.timing = s.timing
        start_costs = search.z_cost(np.array(starts))
        search.z_best = starts[int(np.argmin(start_costs))]
        search.best_cost = float(np.min(start_costs))
        search.keep_better(search.z_best, search.best_cost, "the data's start")
        return
    # What a sample means in time (`Timing`). The equation-error start
    # reads the gyro as a point value, so at the start that reading looks
    # best even where the gyro averages, and fitted at the wrong read-out
    # a fast axis settles in another basin: both gyro readings are refined
    # from the start (half-plane read at the step's start, a third of the
    # budget each), the better fit is kept; the half-plane shift is
    # chosen at the fitted point (at the start it only follows the noise
    # of a poor fit).
    search.z_best, search.best_cost = starts[0], np.inf
    for average in (False, True):
        options = (Timing(0.0, average),)
        picks = [search.best_timing(z, options) for z in starts]
        i = int(np.argmin([c for _, c in picks]))
        search.timing = picks[i][0]
        search.cache.clear()
        search.keep_better(
            starts[i],
            picks[i][1],
            f"the data's start, {search.timing.describe()}",
            budget=max(1, s.refine_evaluations // 3),
        )
    # Chosen again at the fitted point and refined with the full budget.
    search.cache.clear()
    timing, cost_at = search.best_timing(search.z_best)
    search.status_parts.append(timing.describe())
    search.best_cost = cost_at
    search.keep_better(search.z_best, search.best_cost, "the best point at that timing", "timing")


def _global_search(search: _Search) -> None:
    """Differential evolution around the best point, then least squares again.

    Runs only when the fit is not at the noise (`Settings.converged_ratio`)
    and `Settings.generations` > 0; the box spans `_Z_SPAN` of the
    log-parameters around the best point.
    """
    from scipy.optimize import differential_evolution

    s = search.s
    if not (s.generations > 0 and search.best_cost > search.target):
        return
    n_free = search.z_best.size
    span = np.tile(_Z_SPAN, int(search.free.visited.sum()))
    lo = np.maximum(search.z_best - span, search.z_lo)
    hi = np.minimum(search.z_best + span, search.z_hi)
    rng = np.random.default_rng(s.seed)
    init = lo + (hi - lo) * rng.random((s.population, n_free))
    init[0] = np.clip(search.z_best, lo, hi)
    for i, z in enumerate(search.starts[: s.population - 1]):
        init[i + 1] = np.clip(z, lo, hi)

    def on_generation(intermediate_result):
        search.record("search", float(intermediate_result.fun))
        if search.progress is not None:
            search.progress("search", len(search.history), search.history[-1])

    de = differential_evolution(
        lambda zt: search.z_cost(zt.T),
        list(zip(lo, hi)),
        maxiter=s.generations,
        init=init,
        seed=s.seed,
        vectorized=True,
        updating="deferred",
        polish=False,
        tol=0.0,
        callback=on_generation,
    )
    search.status_parts.append(f"differential evolution ({s.generations} generations)")
    search.keep_better(de.x, float(de.fun), "its best", "search")


def _intervals(
    search: _Search, x_best: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Confidence half-widths and identifiability at the stored point (module doc, step 6).

    Returns the residuals there (M,), ci95 and identifiable over the full
    rate vector (`RATE_LAYOUT.size`,), and the residuals' lag-1 correlation.
    """
    data, mask = search.data, search.free.mask
    h = 1e-6 * np.maximum(np.abs(x_best), 1e-9)
    e_all = search.residuals_of(np.vstack([x_best, x_best + np.diag(h)]))
    e, j = e_all[0], ((e_all[1:] - e_all[0]) / h[:, None]).T
    breaks = list(np.cumsum([0] + [len(d) - 1 for d in data]))
    scale = float(np.sqrt(np.mean(np.concatenate([d.omega for d in data]) ** 2)))
    iv = confidence_intervals(j, e, breaks, search.s.confidence, _REFERENCE_NOISE * scale)
    ci = np.full(RATE_LAYOUT.size, np.nan)
    ident = np.zeros(RATE_LAYOUT.size, dtype=bool)
    sensitive = np.linalg.norm(j, axis=0) > 0
    ident[mask] = sensitive & (iv.at_floor < _MAX_RELATIVE_CI * np.abs(x_best))
    ci[mask] = np.where(ident[mask], iv.half_width, np.nan)
    return e, ci, ident, iv.rho


def _outcome(search: _Search, cost: float) -> IdentificationStatus:
    """The status enum of a finished search with final cost `cost` [rad/s]."""
    if cost <= search.target:
        return IdentificationStatus.AT_NOISE
    if search.last_refinement is None:
        return IdentificationStatus.NOT_AT_NOISE
    if search.last_refinement == 0:  # scipy: the evaluation budget ran out
        return IdentificationStatus.MAX_EVALUATIONS
    return IdentificationStatus.CONVERGED


def _result(
    search: _Search, free: _FreeParameters, x_best: np.ndarray, status: str, wall_time_s: float
) -> IdentificationResult:
    """The `IdentificationResult` at the stored point `x_best` (n_free,)."""
    s = search.s
    e, ci, ident, rho = _intervals(search, x_best)
    rate = RateParams.from_vector(free.full(x_best).to_vector()[0])
    rmse_train = {
        d.name: float(
            rmse(
                rate,
                [d],
                s.side_source,
                s.rest_rate_deg_s,
                search.effects,
                search.timing,
                s.integration,
            )
        )
        for d in search.data
    }
    cost = float(np.sqrt(np.mean(e**2)))
    return IdentificationResult(
        rate=rate,
        ci95=ci,
        identifiable=ident,
        visits=free.visits,
        regime_identified=tuple(bool(v) for v in free.visited),
        rmse_train=rmse_train,
        cost=cost,
        history=tuple(search.history),
        initial_cost=search.initial_cost,
        rho=rho,
        evaluations=search.evaluations,
        wall_time_s=wall_time_s,
        status=status,
        settings=s,
        effects=search.effects,
        timing=search.timing,
        noise=search.noise,
        integration=s.integration,
        outcome=_outcome(search, cost),
        log=tuple(search.log),
    )


def to_axis_params(result: IdentificationResult, prior: AxisParams, note: str = "") -> AxisParams:
    """The parameter file's axis of a result (`isp_twin.estimation.parameter_file.fitted_axis`).

    Regimes not identified keep the prior values; the prior's effects are
    kept (they were part of the fitted model); the model and read-out timing
    of the fit are recorded (`fitted_with`).
    """
    return fitted_axis(
        prior,
        result.vector,
        result.ci95,
        prior.effects,
        fitted_with(result.integration, result.timing),
        note or prior.note,
        identified=result.regime_identified,
    )


def rate_labels() -> list[str]:
    """Labels of the (20,) vector entries, e.g. ``R+.gain``."""
    return RATE_LAYOUT.labels()
