"""The runs as the diagnosis sees them: checked against the parameter
file, read at the data's read-out timing, with the half-plane angle chosen
(`side_choice`), split for held-out judgement and stacked for the engine's
simulation error (`stacked`, `Data`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from isp_twin.diagnosis.candidates import (
    BASELINE,
    CandidateFit,
    fit_candidates,
    holdout_residual,
    holdout_residuals,
)
from isp_twin.errors import DataError, ParameterError, nearest
from isp_twin.estimation.simulation_error import RunStack
from isp_twin.estimation.simulation_error import residuals as _simulation_residuals
from isp_twin.estimation.simulation_error import stack_runs as _stack_runs
from isp_twin.identification.cost import rmse
from isp_twin.identification.fit import IdentificationResult, identify
from isp_twin.identification.fit import Settings as IdSettings
from isp_twin.identification.measured import SAMPLE_PERIOD_TOLERANCE, MeasuredData
from isp_twin.identification.read_out import TIMINGS, Timing
from isp_twin.identification.side_angle import with_side_angle
from isp_twin.model.effects import EFFECTS, effect_class
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    AxisParams,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.vocabulary import SIDE_L, SIDE_R

__all__ = [
    "LIBRARY",
    "FIXED_SIDE",
    "DIAGNOSE_FIT",
    "DiagnosisRuns",
    "DiagnosisData",
    "split_in_time",
    "checked_inputs",
    "read_out_timing",
    "side_choice",
    "RAW_SIDE_MARGIN",
    "fused_runs",
    "stacked",
    "given_held",
]

#: How every diagnose fit calls `identify` (`rounds.identify_held` and the
#: opt-in base search): Eq. 9 alone, no regime prior (it moved a leading
#: input delay's refit into another basin, docs/diagnosis.md "Stop 19"), and
#: no restart at the noise (it turned input delay seed 0 tentative,
#: docs/diagnosis.md "Stop 26"). The Jacobian's columns are identify's
#: (`JACOBIAN_SUBSTEPS` sub-steps where no held effect needs the model's
#: own, `relative_stack`), as are the candidates' (docs/diagnosis.md "Stop 84").
DIAGNOSE_FIT = {"regime_spread": None, "restart_at_noise": False}

#: `side_choice` keeps the raw angle only where it fits the starting model
#: better than the fused one by this fraction of the training cost. Without
#: a margin the choice followed differences of 0.01-0.15 %: the starting
#: model misses the effect, so such a difference says nothing about the
#: side, and the raw reading's rests at angle 0 cost the true model up to
#: 3 noise floors held out (reference input delay seed 331: raw chosen at
#: 0.077 % below, its true model 3.07 held out on the raw angle, 1.01 on
#: the fused one; docs/diagnosis.md "Stop 50").
RAW_SIDE_MARGIN = 0.01

#: The candidate effects, in report order: the registry's.
LIBRARY: tuple[str, ...] = tuple(EFFECTS)
#: The side sources `diagnose` accepts (identification's but ``wrap``) -> the
#: side each fixes (None: read from the angle).
FIXED_SIDE: dict[str, int | None] = {"measured": None, "raw": None, "right": SIDE_R, "left": SIDE_L}


def split_in_time(run) -> tuple[MeasuredData, MeasuredData]:
    """Two halves of one run (for cross-validation with a single data set)."""
    n = len(run.u) // 2
    parts = []
    for name, sl in (
        (f"{run.name}[first half]", slice(0, n)),
        (f"{run.name}[second half]", slice(n, None)),
    ):
        parts.append(
            MeasuredData(
                name,
                run.t[sl],
                run.u[sl],
                run.omega[sl],
                run.angle[sl],
                getattr(run, "source", None),
                run.dt,
            )
        )
    return parts[0], parts[1]


def _cv_residuals(
    runs,
    fits: Sequence[CandidateFit],
    max_iter: int,
    side=None,
    gyro_average: bool = False,
    integration: Integration = DEFAULT_INTEGRATION,
) -> list[list[np.ndarray]]:
    """Leave-one-run-out residuals of each fit; every fold refits all of them
    in lockstep, warm-started from their all-run fits."""
    out: list[list[np.ndarray]] = [[] for _ in fits]
    for k in range(len(runs)):
        train = _stack_runs(
            [r for i, r in enumerate(runs) if i != k],
            side=side,
            gyro_average=gyro_average,
            integration=integration,
        )
        folds = fit_candidates(
            train,
            fits[0].rate_vector,
            [f.name for f in fits],
            fits[0].fixed,
            starts={f.name: dict(f.params) for f in fits if f.name != BASELINE},
            max_iter=max_iter,
            rate_starts={f.name: f.rate_vector for f in fits},
            # The all-run fits were polished already; a fold only adjusts.
            polish=False,
        )
        held = holdout_residuals(
            _stack_runs([runs[k]], side=side, gyro_average=gyro_average, integration=integration),
            [folds[f.name] for f in fits],
        )
        for i, parts in enumerate(held):
            out[i].extend(parts)
    return out


@dataclass(frozen=True)
class DiagnosisRuns:
    """The runs of one diagnosis before stacking.

    Attributes:
        raw: the training runs with the angle as read (split in two halves
            when a single run has no hold-out): what the equation-error
            starts and `identify` see.
        train: the training runs the model is fitted to (the angle fused
            where that fits better, `side_choice`).
        holdout: the held-out runs, read the same way (empty: cross-validation).
    """

    raw: list
    train: list
    holdout: list


@dataclass(frozen=True, eq=False)
class DiagnosisData:
    """The data of one diagnosis, read out and stacked once, and how it is read.

    Attributes:
        runs: the runs (`DiagnosisRuns`).
        ax: the axis's given parameters.
        train: the training runs stacked.
        held: the held-out runs stacked, or None (cross-validation over the
            training runs).
        holdout_names: the held-out runs' names (or "cross-validation: ...").
        side_source: the side source (`FIXED_SIDE`).
        timing: the data's read-out timing.
        integration: how the model integrates a sample.
        seed: seed of `identify`'s global search.
        max_iter: Levenberg-Marquardt iterations per fit.
        cv_iter: iterations per cross-validation fold.
        identified: `identify`'s results on these runs, by what they held
            (`rounds.identify_held`); each `replace` of the data starts empty.
    """

    runs: DiagnosisRuns
    ax: AxisParams
    train: RunStack
    held: RunStack | None
    holdout_names: tuple[str, ...]
    side_source: str
    timing: Timing
    integration: Integration
    seed: int
    max_iter: int
    cv_iter: int
    identified: dict = field(default_factory=dict, init=False, compare=False, repr=False)

    @property
    def fixed_side(self) -> int | None:
        """The side the side source fixes (None: read from the angle)."""
        return FIXED_SIDE[self.side_source]

    def held_residuals(self, fits: Sequence[CandidateFit]) -> list[list[np.ndarray]]:
        """Held-out residuals per run of each fit (cross-validated without hold-out)."""
        if self.held is not None:
            return holdout_residuals(self.held, fits)
        return _cv_residuals(
            self.runs.train,
            fits,
            self.cv_iter,
            self.fixed_side,
            self.timing.gyro_average,
            self.integration,
        )


def checked_inputs(runs, holdout, params, axis, candidates, side_source):
    """The inputs checked: (training runs, held-out runs, the axis, the candidates).

    A single training run without hold-out is split in two halves (`split_in_time`).
    """
    runs = list(runs)
    holdout = list(holdout)
    sides = FIXED_SIDE
    if side_source not in sides:
        raise ParameterError(
            f"diagnose: side '{side_source}'{nearest(side_source, sides)}; "
            f"allowed: {', '.join(sides)}"
        )
    if not runs:
        raise DataError("diagnose: no data sets given")
    ax: AxisParams = params.axis(axis)
    for r in runs + holdout:
        if abs(r.dt - params.sample_time_s) > SAMPLE_PERIOD_TOLERANCE * params.sample_time_s:
            raise DataError(
                f"{r.source or r.name}: sample period {r.dt:g} s, but the parameter file "
                f"{params.path or params.name} is for {params.sample_time_s:g} s"
            )
    if candidates is None:
        present = {e.name for e in ax.effects}
        candidates = [c for c in LIBRARY if c not in present]
    for c in candidates:
        effect_class(c, "candidate effect")
    if not holdout and len(runs) == 1:
        runs = list(split_in_time(runs[0]))
    return runs, holdout, ax, list(candidates)


def read_out_timing(
    runs, ax, side_source, seed, integration, timing, base_search
) -> tuple[IdentificationResult | None, Timing]:
    """The base model's global identification (`base_search`, else None) and
    the data's read-out timing: the given one, the identification's, or the
    best fit at the file's parameters (side source ``measured``)."""
    if base_search:
        base_id = identify(
            runs,
            ax,
            IdSettings(
                side_source=side_source,
                seed=seed,
                integration=integration,
                timing=timing,
                **DIAGNOSE_FIT,
            ),
        )
        return base_id, base_id.timing
    if side_source == "measured" and timing is None:
        # The data's read-out timing (what a gyro sample means) at the file's
        # parameters, as `identify` chooses it: a gyro averaging over the
        # sample read as a point value leaves a fast axis far from the noise.
        x_file_rate = ax.rate_params()
        costs = {
            t: float(rmse(x_file_rate, runs, side_source, 0.1, tuple(ax.effects), t, integration))
            for t in TIMINGS
        }
        return None, min(costs, key=costs.get)
    return None, Timing() if timing is None else timing


def side_choice(runs, holdout, ax, timing, integration, x_start) -> tuple[list, list]:
    """The runs with the fused angle, or as given (the raw angle) where
    that fits the starting model better by `RAW_SIDE_MARGIN` (side source
    ``measured``)."""
    # The half-plane and the angle-dependent effects see the fused angle
    # (resolver quantization steps would flip the regime back and forth
    # at angle 0), read at the data's timing, unless the raw angle fits
    # the starting model better: a gyro scale or bias error (the
    # sensor_bias effect) enters the integrated rate the fusion trusts
    # at short times and moves its zero crossings.
    fused = fused_runs(runs, timing, integration)
    costs = [
        float(
            np.sum(
                _simulation_residuals(
                    _stack_runs(
                        rs,
                        side=None,
                        gyro_average=timing.gyro_average,
                        integration=integration,
                    ),
                    x_start,
                    fixed=tuple(ax.effects),
                )
                ** 2
            )
        )
        for rs in (fused, runs)
    ]
    if costs[1] < (1.0 - RAW_SIDE_MARGIN) * costs[0]:
        return runs, holdout
    return fused, fused_runs(holdout, timing, integration)


def fused_runs(runs, timing: Timing, integration: Integration) -> list:
    """The runs with the fused angle as their side angle, its half-plane
    read at `timing`'s shift (a fraction of a step, over the sub-steps)."""
    shift = timing.side_shift / integration.substeps
    return [with_side_angle(r, "measured", shift, integration.opens_on_boundary) for r in runs]


def stacked(
    runs: DiagnosisRuns,
    ax: AxisParams,
    side_source: str,
    timing: Timing,
    integration: Integration,
    seed: int,
    max_iter: int,
    cv_iter: int,
) -> DiagnosisData:
    """The training and held-out runs stacked at the side and read-out chosen."""

    def stack(rs):
        return _stack_runs(
            rs,
            side=FIXED_SIDE[side_source],
            gyro_average=timing.gyro_average,
            integration=integration,
        )

    train = stack(runs.train)
    held = stack(runs.holdout) if runs.holdout else None
    holdout_names = (
        tuple(r.name for r in runs.holdout)
        if runs.holdout
        else ("cross-validation: " + ", ".join(train.names),)
    )
    return DiagnosisData(
        runs,
        ax,
        train,
        held,
        holdout_names,
        side_source,
        timing,
        integration,
        seed,
        max_iter,
        cv_iter,
    )


def given_held(data: DiagnosisData, x_file: np.ndarray) -> list[np.ndarray]:
    """Held-out residuals per run of the given model, unchanged (no fit)."""
    given = CandidateFit(
        name=BASELINE,
        params={},
        ci95={},
        rate_vector=x_file,
        rate_ci95=np.full(RATE_LAYOUT.size, np.nan),
        sse=np.nan,
        n_samples=1,
        n_params=RATE_LAYOUT.size,
        bic=np.nan,
        status=None,
        fixed=tuple(data.ax.effects),
    )
    return holdout_residual(data.held if data.held is not None else data.train, given)
