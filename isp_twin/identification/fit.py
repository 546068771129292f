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
   vector in log variables (`to_z`) with limits from the data
   (`z_limits`), a batched finite-difference Jacobian; then the read-out
   timing (`Timing`) is chosen from the data and the fit refined with it.
   A regime whose Stribeck decay alpha ends outside `Settings.regime_spread`
   of the other regimes' is refined again from their friction shape (b·Tc,
   b·(Ts-Tc), alpha; `shape_outliers`), kept where it fits the runs better;
   then the regimes whose Stribeck curve is a straight line over the runs'
   speeds, with the curve opened (`linear_stribeck`), kept likewise; then,
   where the fit is above `NEAR_NOISE` floors but within
   `JOINT_ALPHA_REACH`, from every regime's alpha stepped up and down at
   once, the rest fitted to those alphas first (`every_alpha_stepped`),
   kept where it fits the runs better by more than `JOINT_ALPHA_GAIN`;
   then, where the fit is judged at the noise but above `NEAR_NOISE`
   floors, from each regime's alpha stepped up and down (`stepped_alpha`),
   kept where it fits the runs better.
5. **Global search**, only when the fit is still above
   `Settings.converged_ratio` noise floors (at the noise: the least squares
   restarted once from its own end, `Settings.restart_at_noise`):
   differential evolution (scipy,
   seeded, vectorized: the population is the batch dimension of
   `isp_twin.model.axis_model.simulate`) in a box around the best point,
   stopped once `DE_STALL_GENERATIONS` generations gain less than
   `DE_STALL_GAIN` (`stalled`), then least squares again. The result is
   taken in the form the parameter file stores (6 digits), moved off a
   stick/slip threshold if the rounding would spoil the fit
   (`robust_to_storage`).
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
from isp_twin.estimation.intervals import Intervals, confidence_intervals
from isp_twin.estimation.least_squares import FitStatus, trust_region
from isp_twin.estimation.parameter_file import fitted_axis
from isp_twin.estimation.simulation_error import JACOBIAN_SUBSTEPS, RunStack, relative_stack
from isp_twin.identification.cost import rate_noise, residuals, rmse, run_stack
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import TIMINGS, Timing, fitted_with
from isp_twin.identification.search_space import (
    ALPHA_JOINT_STEP,
    ALPHA_STEP,
    Z_SPAN,
    FreeParameters,
    alpha_positions,
    consensus_start,
    every_alpha_stepped,
    free_parameters,
    from_z,
    linear_stribeck,
    opened_stribeck,
    regime_prior_residuals,
    robust_to_storage,
    shape_outliers,
    stepped_alpha,
    to_z,
    z_limits,
)
from isp_twin.identification.side_angle import SIDE_SOURCES
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    AxisParams,
    EffectSpec,
    RateParams,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.units import DEG

__all__ = [
    "JACOBIAN_SUBSTEPS",
    "RATE_FIELDS",
    "Settings",
    "IdentificationResult",
    "IdentificationStatus",
    "SearchStep",
    "identify",
    "to_axis_params",
    "rate_labels",
]

#: Names of the rate-form quantities per regime, `RateParams.to_vector` order
#: (`RATE_LAYOUT.fields`, kept under this name for callers of this module).
RATE_FIELDS: tuple[str, ...] = RATE_LAYOUT.fields

#: Noise floor for the identifiability test, relative to the rate RMS.
_REFERENCE_NOISE = 1e-3
#: Largest relative 95 % half-width of an identifiable quantity.
_MAX_RELATIVE_CI = 0.5


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
        restart_at_noise: where that fit is at the noise instead, restart
            the least squares once from its own end (a fresh trust region).
            A refinement stopped by `_REFINE_FTOL` in a long valley (a
            regime's small alpha traded against its pole) can be at the
            noise on the training runs and far from it held out: reference
            clean seed 15, regime R- (alpha 0.49 s/rad, the truth 72), 1.04
            noise floors on training where the truth reaches 1.00, 3.2 held
            out; restarted 0.99 and 1.16 (docs/identification.md "Stop 26").
            Above `NEAR_NOISE` floors each regime's alpha is also stepped
            (`_stepped_alpha_restarts`).
        prior_in_search: also start from the prior's values (by default the
            prior only supplies b, unvisited regimes and held effects).
        timing: the data's read-out timing (`Timing`); None: the one of
            `TIMINGS` that fits best (``side_source="measured"``; else Eq. 6's).
        integration: how the model integrates a sample
            (`isp_twin.model.substep_model.Integration`; `EQ6` is the paper's Eq. 6).
        jacobian_substeps: sub-steps per sample of the refinement's
            finite-difference columns (`_Search.columns`) where the model
            integrates more (`JACOBIAN_SUBSTEPS`); None: the model's own.
            The residuals, so the cost, every step's acceptance and the
            result's figures, stay the model's.
        regime_spread: the factor within which the regimes' friction
            quantities (b·Tc, b·(Ts-Tc), alpha) are expected to agree, one
            standard deviation of a weak prior that pulls each toward the
            visited regimes' geometric mean in the least-squares refinement
            (`regime_prior_residuals`), and beyond which a regime's alpha
            has its shape restarted from the others' (`shape_outliers`);
            None: neither.
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
    restart_at_noise: bool = True
    prior_in_search: bool = False
    timing: Timing | None = None
    integration: Integration = DEFAULT_INTEGRATION
    jacobian_substeps: int | None = JACOBIAN_SUBSTEPS
    regime_spread: float | None = 3.0

    def __post_init__(self):
        if self.side_source not in SIDE_SOURCES:
            raise ParameterError(
                f"side source '{self.side_source}' unknown; allowed: {', '.join(SIDE_SOURCES)}"
            )
        if self.population < 5 or self.generations < 0:
            raise ParameterError("population >= 5 and generations >= 0 required")
        if self.jacobian_substeps is not None and self.jacobian_substeps < 1:
            raise ParameterError(f"jacobian sub-steps must be >= 1, got {self.jacobian_substeps}")
        if self.regime_spread is not None and not self.regime_spread > 1.0:
            raise ParameterError(f"regime spread must be > 1 (a factor), got {self.regime_spread}")


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
        covariance: the covariance of the free quantities (the visited
            regimes' entries of the rate vector, in its order), (n_free,
            n_free), the intervals' (step 6) without their t quantile; NaN
            where not determined. Empty when not computed.
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
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def vector(self) -> np.ndarray:
        return self.rate.to_vector()


#: Least squares stops when a step lowers the sum of squares by less than this
#: fraction (scipy's ``ftol``; its default 1e-8). The sum of squares of M
#: residuals has a sampling spread of sqrt(2/M) (1.3 % at 2 x 6000 samples):
#: a step of 1e-5 moves the RMS error by 5e-6 noise floors. On reference dev
#: axis 1021 the steps below it took 3500 of 5100 simulated sets (RMS error
#: 0.9910 -> 0.9905 of the noise sigma).
_REFINE_FTOL = 1e-5

#: Noise floors above which a fit judged at the noise (`Settings.converged_ratio`)
#: still has each regime's alpha stepped (`_stepped_alpha_restarts`). On
#: reference clean seeds 100-139 the fit ended at 0.57-1.03 floors of
#: `rate_noise` on every axis but 111 (1.14).
NEAR_NOISE = 1.05
#: Jacobian evaluations of the least squares at the other gyro reading where
#: the fit is already within `NEAR_NOISE` (`_other_reading_restart`): a
#: probe, which the restart at the noise continues where it is kept. With
#: the whole budget (200) the stage took up to 2900 more simulated sets on
#: reference clean seeds 600-659 (602, 603, 607, 613: +10 s) for the same
#: two moves (626, and 349) that 5 make: +13 % simulated sets (median),
#: at most +151.
PROBE_EVALUATIONS = 5
#: Jacobian evaluations of the least squares with the alphas held
#: (`_joint_alpha_restarts`), before the restart frees them.
HELD_ALPHA_EVALUATIONS = 60
#: Noise floors above which `_joint_alpha_restarts` does not run: a fit that
#: far off lacks an effect rather than an alpha. Reference seed 353 shaped
#: it (6.6 ms, every case; truth sigmas on training): the stage moved clean
#: (3.95) and dead zone (3.84) to the noise and unbalance from 6.1 to 4.8;
#: cogging, cable spring, input delay, saturation, sensor bias, resonance
#: and LuGre (24 to 685) it left where they were, at up to +32 s each.
JOINT_ALPHA_REACH = 10.0
#: The fraction by which a joint-alpha restart must lower the training RMS
#: error to be kept (`_joint_alpha_restarts`): three times the sampling
#: spread of an RMS error over 2 x 6000 samples (sqrt(1/2M), 0.65 %). On
#: fresh seeds 351-358's effect axes the restarts that were kept at any
#: gain moved the fit by 0.05-1.4 % and changed no answer but one
#: (resonance 355: right -> `none`); on seed 353 and clean 659 they gained
#: 22-75 %.
JOINT_ALPHA_GAIN = 0.02
#: Passes of the stepped alphas over the regimes (`_stepped_alpha_restarts`):
#: the second only after a first that lowered the cost.
ALPHA_PASSES = 2
#: The differential evolution (`_global_search`) stops after this many
#: generations in a row that together lowered its best cost by less than
#: `DE_STALL_GAIN` of it (`stalled`). Over the 516 runs of `identify` in the
#: reference benchmarks of stops 50-57 where the stage ran (20 generations
#: x 40), no generation ever beat the point it started from; the stage
#: took a median 27 % of their simulated parameter sets (docs/identification.md
#: "Stop 58").
DE_STALL_GENERATIONS = 5
#: The relative gain of the best cost over `DE_STALL_GENERATIONS`
#: generations below which the differential evolution stops.
DE_STALL_GAIN = 1e-3


def identify(
    data: Sequence[MeasuredData],
    prior: AxisParams,
    settings: Settings = Settings(),
    progress: Callable[[str, int, float], None] | None = None,
) -> IdentificationResult:
    """Identify one axis from open-loop runs (all sets in one cost, Eq. 9).

    The stages (module doc): free parameters and start (`FreeParameters`),
    read-out timing and local refinement (`_refine_from_start`), restarts
    from the other regimes' friction shape (`_consensus_restarts`), with a
    straight Stribeck curve opened (`_opened_stribeck_restart`), from every
    alpha stepped at once (`_joint_alpha_restarts`) and from each regime's
    alpha stepped (`_stepped_alpha_restarts`), global
    search (`_global_search`), storage rounding (`robust_to_storage`),
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
    free = free_parameters(data, prior, settings)
    search = _Search(data, free, settings, tuple(prior.effects), progress)
    _refine_from_start(search, prior.rate_params().to_vector()[free.mask])
    _other_reading_restart(search)
    _consensus_restarts(search)
    _opened_stribeck_restart(search)
    _joint_alpha_restarts(search)
    _stepped_alpha_restarts(search)
    _global_search(search)
    status = "; ".join(search.status_parts) or "equation-error estimate"
    x_best = from_z(np.clip(search.z_best, search.z_lo, search.z_hi)[None])[0]
    b = np.array([r.b for r in prior.regimes])
    x_best, moved = robust_to_storage(x_best, search.rmse_of, free.mask, b)
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
        free: FreeParameters,
        s: Settings,
        effects: tuple[EffectSpec, ...],
        progress: Callable[[str, int, float], None] | None,
    ) -> None:
        self.data, self.free, self.s, self.effects, self.progress = data, free, s, effects, progress
        self.timing = Timing()
        # The runs stacked per integration, at `_stacks_timing` (`_model`).
        self._stacks: dict[Integration, RunStack] = {}
        self._stacks_timing: Timing | None = None
        self.evaluations = 0
        self.initial_cost = float(self.batch_cost(free.x0[:, None])[0])
        self.history: list[float] = [self.initial_cost]
        self.log: list[SearchStep] = [SearchStep("start", self.evaluations, self.initial_cost)]
        self.status_parts: list[str] = []
        self.last_refinement: FitStatus | None = None  # the last refinement's
        self.noise = rate_noise(data)
        self.target = s.converged_ratio * self.noise
        u_peak = max(float(np.max(np.abs(d.u))) for d in data)
        speed = float(np.sqrt(np.mean(np.concatenate([d.omega for d in data]) ** 2)))
        self.speed = max(speed, 1e-9)  # the runs' RMS rate [rad/s]
        self.z_lo, self.z_hi = z_limits(free.x0, u_peak, self.speed)
        self.cache: dict[str, np.ndarray] = {}
        self.prior = regime_prior_residuals(int(free.visited.sum()), s.regime_spread, self.noise)
        self.starts: list[np.ndarray] = [to_z(free.x0)]
        self.z_best = self.starts[0]
        self.best_cost = np.inf

    def _model(self, integration: Integration | None = None) -> tuple:
        """What `residuals` and `rmse` take after the parameters: the data
        (stacked once per read-out timing and integration) and this search's
        side source, rest level, effects, timing and integration (the
        settings' unless `integration` is given)."""
        s = self.s
        integration = s.integration if integration is None else integration
        if self._stacks_timing != self.timing:
            self._stacks, self._stacks_timing = {}, self.timing
        if integration not in self._stacks:
            self._stacks[integration] = run_stack(
                self.data, s.side_source, s.rest_rate_deg_s, self.timing, integration
            )
        return (
            self._stacks[integration],
            s.side_source,
            s.rest_rate_deg_s,
            self.effects,
            self.timing,
            integration,
        )

    def _column_model(self) -> tuple | None:
        """`_model` with the sub-steps of the finite-difference columns
        (`Settings.jacobian_substeps`; the refinement's columns were 20 of
        the 21 simulated sets of a Jacobian evaluation and took 70 % of a
        clean identify, reference seed 443: 21 of 30 s); None where the
        columns take the model's own (`relative_stack`: as many sub-steps, or
        a held effect whose slopes need them)."""
        m = self.s.jacobian_substeps
        if relative_stack(self._model()[0], [e.name for e in self.effects], m) is None:
            return None
        return self._model(replace(self.s.integration, substeps=m))

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
        return self.batch_cost(from_z(np.clip(zs, self.z_lo, self.z_hi)).T)

    def evaluate(self, z: np.ndarray, jacobian: bool) -> None:
        """The residual at z, and with `jacobian` its forward differences.

        The columns are simulated only when asked for: least squares needs
        none at a trial point it then rejects (each column costs one set).
        """
        h = np.full(z.size, 1e-6)
        cache = self.cache
        # Columns simulated apart (`_column_model`) are asked for below.
        together = jacobian and self._column_model() is None
        if "z" not in cache or not np.array_equal(cache["z"], z):
            pts = np.vstack([z, z + np.diag(h)]) if together else z[None]
            self.evaluations += pts.shape[0]
            e = self.residuals_of(from_z(pts))
            cache.clear()
            cache.update(z=z.copy(), e=e[0])
            if together:
                cache["j"] = ((e[1:] - e[0]) / h[:, None]).T
            if self.progress is not None:
                self.progress("refine", self.evaluations, float(np.sqrt(np.mean(e[0] ** 2))))
        if jacobian and "j" not in cache:
            cache["j"] = self.columns(z, np.ones(z.size, bool))

    def columns(self, z: np.ndarray, moved: np.ndarray) -> np.ndarray:
        """Forward differences at z (cached by `evaluate`) of the `moved`
        search variables (boolean mask), one simulated set each: (M, moved).
        With `Settings.jacobian_substeps` (`_column_model`) they are
        differences from z simulated the same way, one more set."""
        h = 1e-6
        pts = z + h * np.eye(z.size)[moved]
        model = self._column_model()
        if model is None:
            self.evaluations += pts.shape[0]
            return ((self.residuals_of(from_z(pts)) - self.cache["e"]) / h).T
        self.evaluations += pts.shape[0] + 1
        e = residuals(self.free.full(from_z(np.vstack([z, pts]))), *model)
        return ((e[1:] - e[0]) / h).T

    def resid(self, z: np.ndarray) -> np.ndarray:
        self.evaluate(z, jacobian=False)
        return np.concatenate([self.cache["e"], self.prior @ z])

    def jac(self, z: np.ndarray) -> np.ndarray:
        self.evaluate(z, jacobian=True)
        return np.vstack([self.cache["j"], self.prior])

    def held_jac(self, z: np.ndarray, moved: np.ndarray) -> np.ndarray:
        """`jac`'s columns of the `moved` variables only (`columns`)."""
        self.evaluate(z, jacobian=False)
        return np.vstack([self.columns(z, moved), self.prior[:, moved]])

    @property
    def refining(self) -> bool:
        """Whether refinement is on (`Settings.refine`, a budget above 0)."""
        return self.s.refine and self.s.refine_evaluations > 0

    def refine(
        self, z: np.ndarray, budget: int, held: np.ndarray | None = None
    ) -> tuple[np.ndarray, float, str]:
        """Least squares on Eq. 9's residuals (and the regime prior's) from z,
        with the search variables of the boolean mask `held` kept at z's;
        (z, Eq. 9's cost there, the solver's message)."""
        moved = np.ones(z.size, bool) if held is None else ~held

        def full(y: np.ndarray) -> np.ndarray:
            out = z.copy()
            out[moved] = y
            return out

        if held is None:
            resid, jac = self.resid, self.jac
        else:
            resid = lambda y: self.resid(full(y))  # noqa: E731
            jac = lambda y: self.held_jac(full(y), moved)  # noqa: E731
        fit = trust_region(
            resid, jac, z[moved], self.z_lo[moved], self.z_hi[moved], budget, _REFINE_FTOL
        )  # fmt: skip
        self.last_refinement = fit.status
        data = fit.residual[: fit.residual.size - self.prior.shape[0]]
        return full(fit.x), float(np.sqrt(np.mean(data**2))), fit.message

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
        refined = self.refining
        if refined:
            z, cost, msg = self.refine(z, budget or self.s.refine_evaluations)
            self.status_parts.append(f"least squares from {label} ({msg})")
        if cost < self.best_cost:
            self.z_best, self.best_cost = z, cost
        if refined or stage:
            self.record("refine" if refined else stage)

    def restart(self, start: np.ndarray, label: str) -> None:
        """`keep_better` from `start` (search variables), clipped to their limits."""
        start = np.clip(start, self.z_lo, self.z_hi)
        self.keep_better(start, float(self.z_cost(start[None])[0]), label)

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
        starts.append(to_z(prior_free))
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


def _other_reading_restart(search: _Search) -> None:
    """Least squares again at the other gyro reading (point value or sample
    mean, `Timing.gyro_average`) from the refined point, its half-plane
    shift chosen there; kept, with its timing, only where it fits the runs
    better. Above `NEAR_NOISE` noise floors with the whole budget, at or
    below it with `PROBE_EVALUATIONS` (a kept probe is refined further by
    the restart at the noise, `_global_search`).

    `_refine_from_start` picks the reading from a third of the budget from
    the start; where that part ends above the other reading's, the whole
    budget goes to the wrong one. Reference clean seed 237 (its gyro
    averages) with the breakaway's friction at its mean rate: 1.30/1.73
    floors on training at the sample, 1.01/1.00 averaged
    (docs/identification.md "Stop 42"). Seed 349 is the same kind of miss
    at the noise (1.025/1.022 truth sigmas at the sample, 2.17 held out;
    the truth reads 1.014/1.002 averaged): the probe moves it to
    1.013/1.002 and 1.02 held out ("Stop 54"). Not with a timing given
    (`Settings.timing`) or a side source other than the measured angle,
    nor in diagnose's fits (`Settings.restart_at_noise` off).
    """
    s = search.s
    if s.timing is not None or s.side_source != "measured" or not s.restart_at_noise:
        return
    if not search.refining:
        return
    budget = s.refine_evaluations
    if search.best_cost <= NEAR_NOISE * search.noise:
        budget = min(budget, PROBE_EVALUATIONS)
    kept, kept_status = search.timing, search.last_refinement
    other = tuple(t for t in TIMINGS if t.gyro_average != kept.gyro_average)
    search.cache.clear()
    timing, _ = search.best_timing(search.z_best, other)
    z, cost, msg = search.refine(search.z_best, budget)
    search.status_parts.append(f"least squares at {timing.describe()} from the best point ({msg})")
    search.cache.clear()
    if cost < search.best_cost:
        search.z_best, search.best_cost = z, cost
    else:
        search.timing, search.last_refinement = kept, kept_status
    search.record("refine")


def _consensus_restarts(search: _Search) -> None:
    """Least squares again from the other regimes' friction shape, for each
    regime whose alpha lies outside `Settings.regime_spread` of theirs
    (`shape_outliers`, `consensus_start`); a restart is kept only where it
    fits the runs better (the prior's residuals do not count)."""
    for r in shape_outliers(search.z_best, search.s.regime_spread):
        name = search.free.visited_names[r]
        search.restart(
            consensus_start(search.z_best, r), f"the other regimes' friction shape in {name}"
        )


def _opened_stribeck_restart(search: _Search) -> None:
    """Least squares again with the Stribeck curve opened in each regime
    where it is a straight line over the runs' speeds (`linear_stribeck`,
    `opened_stribeck`); kept only where it fits the runs better."""
    linear = linear_stribeck(search.z_best, search.speed)
    if linear:
        names = ", ".join(search.free.visited_names[r] for r in linear)
        start = opened_stribeck(search.z_best, linear, search.speed)
        search.restart(start, f"the Stribeck curve opened in {names}")


def _joint_alpha_restarts(search: _Search) -> None:
    """Least squares again from every regime's alpha stepped up and down by
    `ALPHA_JOINT_STEP` at once (`every_alpha_stepped`), where the fit is
    between `NEAR_NOISE` and `JOINT_ALPHA_REACH` noise floors: first with
    the alphas held (`HELD_ALPHA_EVALUATIONS`), so that the poles, gains
    and levels move to where those alphas fit, then with everything free;
    each kept only where it fits the runs better by more than
    `JOINT_ALPHA_GAIN`.

    On a fast axis the alphas of two regimes trade against small moves of
    every other quantity: reference clean seed 353 (6.6 ms), R- and L+ at
    0.42 and 0.48 of the truth's alpha, 3.1/4.6 truth sigmas on training
    (the truth 1.01/1.06). The straight path to the truth crosses a ridge
    of 4.4 estimated noise floors; from either alpha stepped alone, or from
    every alpha stepped with the rest kept, the least squares walks back,
    the alphas first. With the alphas held for a start it reaches the
    truth's minimum (docs/identification.md "Stop 55"). With
    `Settings.restart_at_noise` off (diagnose's fits) it does not run.
    """
    s = search.s
    if not (s.restart_at_noise and search.refining):
        return
    if not NEAR_NOISE * search.noise < search.best_cost <= JOINT_ALPHA_REACH * search.noise:
        return
    held = alpha_positions(search.z_best.size)
    base = search.z_best
    for factor in (ALPHA_JOINT_STEP, 1.0 / ALPHA_JOINT_STEP):
        before = search.last_refinement
        start = np.clip(every_alpha_stepped(base, factor), search.z_lo, search.z_hi)
        z, _, _ = search.refine(start, HELD_ALPHA_EVALUATIONS, held)
        z, cost, msg = search.refine(z, s.refine_evaluations)
        kept = cost < (1.0 - JOINT_ALPHA_GAIN) * search.best_cost
        said = "kept" if kept else f"not kept: less than {JOINT_ALPHA_GAIN:.0%} better"
        search.status_parts.append(
            f"least squares from every alpha x{factor:.3g}, the rest fitted to it first "
            f"({msg}; {said})"
        )
        if kept:
            search.z_best, search.best_cost = z, cost
        else:
            search.last_refinement = before
        search.record("refine")


def _stepped_alpha_restarts(search: _Search) -> None:
    """Least squares again from each visited regime's alpha stepped up and down
    by `ALPHA_STEP` (`stepped_alpha`), where the fit is above `NEAR_NOISE`
    noise floors but judged at the noise (where the global search does not
    run); each kept only where it fits the runs better. A pass steps every
    regime, even after one step reached the noise: a regime stepped while
    another was still off may find its way out once that one is mended
    (reference clean seed 111 with the breakaway's friction at its mean
    rate: R- left at 0.77 of its alpha). Another pass follows one that
    lowered the cost, `ALPHA_PASSES` in all. With
    `Settings.restart_at_noise` off (diagnose's fits) it does not run."""
    s = search.s
    near = NEAR_NOISE * search.noise < search.best_cost <= search.target
    if not (s.restart_at_noise and near):
        return
    for _ in range(ALPHA_PASSES):
        before = search.best_cost
        for r, name in enumerate(search.free.visited_names):
            for factor in (ALPHA_STEP, 1.0 / ALPHA_STEP):
                search.restart(
                    stepped_alpha(search.z_best, r, factor), f"alpha x{factor:.3g} in {name}"
                )
        if search.best_cost >= before:
            return


def stalled(costs: Sequence[float]) -> bool:
    """Whether a differential evolution has stalled.

    costs: its best cost [rad/s] before the first generation, then after
    each generation. True once the last `DE_STALL_GENERATIONS` generations
    together lowered it by less than `DE_STALL_GAIN` of itself.
    """
    if len(costs) <= DE_STALL_GENERATIONS:
        return False
    return costs[-1] > (1.0 - DE_STALL_GAIN) * costs[-1 - DE_STALL_GENERATIONS]


def _global_search(search: _Search) -> None:
    """Differential evolution around the best point, then least squares again.

    Runs only when the fit is not at the noise (`Settings.converged_ratio`)
    and `Settings.generations` > 0; the box spans `Z_SPAN` of the
    log-parameters around the best point. At the noise, the least squares
    restarted from its own end instead (`Settings.restart_at_noise`).
    """
    from scipy.optimize import differential_evolution

    s = search.s
    if s.generations <= 0:
        return
    if search.best_cost <= search.target:
        if s.restart_at_noise:
            search.keep_better(search.z_best, search.best_cost, "its own end")
        return
    n_free = search.z_best.size
    span = np.tile(Z_SPAN, int(search.free.visited.sum()))
    lo = np.maximum(search.z_best - span, search.z_lo)
    hi = np.minimum(search.z_best + span, search.z_hi)
    rng = np.random.default_rng(s.seed)
    init = lo + (hi - lo) * rng.random((s.population, n_free))
    init[0] = np.clip(search.z_best, lo, hi)
    for i, z in enumerate(search.starts[: s.population - 1]):
        init[i + 1] = np.clip(z, lo, hi)

    costs = [search.best_cost]

    def on_generation(intermediate_result) -> bool:
        costs.append(float(intermediate_result.fun))
        search.record("search", costs[-1])
        if search.progress is not None:
            search.progress("search", len(search.history), search.history[-1])
        return stalled(costs)

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
    ran = len(costs) - 1
    stop = "" if ran >= s.generations else ", stalled"
    search.status_parts.append(
        f"differential evolution ({ran} of {s.generations} generations{stop})"
    )
    search.keep_better(de.x, float(de.fun), "its best", "search")


def _intervals(
    search: _Search, x_best: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Intervals]:
    """Confidence half-widths and identifiability at the stored point (module doc, step 6).

    Returns the residuals there (M,), ci95 and identifiable over the full
    rate vector (`RATE_LAYOUT.size`,), and the free quantities' `Intervals`
    (their lag-1 correlation and covariance).
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
    return e, ci, ident, iv


def _outcome(search: _Search, cost: float) -> IdentificationStatus:
    """The status enum of a finished search with final cost `cost` [rad/s]."""
    if cost <= search.target:
        return IdentificationStatus.AT_NOISE
    if search.last_refinement is None:
        return IdentificationStatus.NOT_AT_NOISE
    if search.last_refinement is FitStatus.MAX_ITERATIONS:  # the budget ran out
        return IdentificationStatus.MAX_EVALUATIONS
    return IdentificationStatus.CONVERGED


def _result(
    search: _Search, free: FreeParameters, x_best: np.ndarray, status: str, wall_time_s: float
) -> IdentificationResult:
    """The `IdentificationResult` at the stored point `x_best` (n_free,)."""
    s = search.s
    e, ci, ident, iv = _intervals(search, x_best)
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
        rho=iv.rho,
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
        covariance=iv.covariance,
    )


def to_axis_params(result: IdentificationResult, prior: AxisParams, note: str = "") -> AxisParams:
    """The parameter file's axis of a result (`isp_twin.estimation.parameter_file.fitted_axis`).

    Regimes not identified keep the prior values; the prior's effects are
    kept (they were part of the fitted model); the model and read-out timing
    of the fit and the side source are recorded (`fitted_with`).
    """
    return fitted_axis(
        prior,
        result.vector,
        result.ci95,
        prior.effects,
        fitted_with(result.integration, result.timing, result.settings.side_source),
        note or prior.note,
        identified=result.regime_identified,
    )


def rate_labels() -> list[str]:
    """Labels of the (20,) vector entries, e.g. ``R+.gain``."""
    return RATE_LAYOUT.labels()
