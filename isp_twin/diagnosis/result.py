"""What `diagnose` returns: each round's outcome (`RoundResult`) and the
diagnosis (`Diagnosis`) with its JSON form."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from isp_twin.diagnosis.candidates import (
    BASELINE,
    CandidateFit,
)
from isp_twin.diagnosis.determined import DeterminedHeldOut
from isp_twin.diagnosis.residual import ResidualAnalysis
from isp_twin.diagnosis.selection import Verdict
from isp_twin.estimation.simulation_error import RunStack
from isp_twin.estimation.verdict import CONVERGED_RATIO, json_safe
from isp_twin.identification.read_out import Timing
from isp_twin.model.effects.torque_offset import ImpliedOffset
from isp_twin.model.parameters import (
    ParameterSet,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.units import DEG

__all__ = [
    "RoundResult",
    "TrainingExplained",
    "TentativeFit",
    "Diagnosis",
    "rms_of",
]


@dataclass(frozen=True)
class RoundResult:
    """One round of the loop.

    Attributes:
        baseline: the current model refitted without a new effect.
        fits: candidate name -> its refit (trained on all training runs).
        verdicts: one per candidate, best held-out RMSE first (the ranking).
        selected: the accepted candidate's name, or `BASELINE`.
        holdout_before / holdout_after: held-out residuals per run of the
            baseline and of the selected model [rad/s].
        noise_floor: noise estimate from the baseline's held-out residual [rad/s].
    """

    baseline: CandidateFit
    fits: dict
    verdicts: tuple[Verdict, ...]
    selected: str
    holdout_before: tuple
    holdout_after: tuple
    noise_floor: float

    @property
    def model(self) -> CandidateFit:
        return self.fits[self.selected] if self.selected != BASELINE else self.baseline


@dataclass(frozen=True)
class TrainingExplained:
    """Why effects were adopted with the held-out error above the noise:
    with them the model fits the training runs at the noise and removes
    most of the held-out excess (`search.EXPLAINED_SHARE`), or reaches the
    noise on the held-out part the training runs determine
    (`determined`).

    Attributes:
        training_over_noise: training RMS error of the model with the
            effects over the noise floor.
        excess_removed: share of the refit without an effect's held-out
            mean-square excess over the noise floor that the effects remove.
        determined: where the share fell short, the model judged on the
            held-out samples before its first rest against a regime it
            never breaks away in on the training runs
            (`isp_twin.diagnosis.determined.DeterminedHeldOut`); else None.
    """

    training_over_noise: float
    excess_removed: float
    determined: DeterminedHeldOut | None = None

    def sentence(self, effects: str) -> str:
        """The verdict's explanation of the adoption."""
        said = (
            f"NOT CONVERGED held out, though the model with {effects} fits the training "
            f"runs at {self.training_over_noise:.2f} x the noise floor and removes "
            f"{100.0 * self.excess_removed:.2f} % of the held-out excess over the noise"
        )
        d = self.determined
        if d is not None:
            said += (
                f", and reads {d.over_noise:.2f} x the noise floor (without it "
                f"{d.base_over_noise:.2f}) over the {d.samples} of {d.of_samples} held-out "
                "samples before its first rest in a regime it never breaks away in "
                "on the training runs"
            )
        return said + (
            ": the held-out run goes where the training runs leave the model undetermined "
            "(add a training run that covers it)"
        )

    def to_json(self) -> dict:
        out = {
            "training_over_noise_floor": self.training_over_noise,
            "held_out_excess_removed": self.excess_removed,
        }
        d = self.determined
        if d is not None:
            out["held_out_determined"] = {
                "samples": d.samples,
                "of_samples": d.of_samples,
                "rmse_over_noise_floor": d.over_noise,
                "without_effects_over_noise_floor": d.base_over_noise,
                "improvement_z": d.improvement_z,
            }
        return out


@dataclass(frozen=True)
class TentativeFit:
    """How far the model with the tentative effects got, where they were set
    aside (`Diagnosis.tentative`): the verdict states it, so that a `none`
    never hides an effect that took most of the error away.

    Attributes:
        effects: the tentative effects, in the order accepted.
        training_over_noise: training RMS error of the model with them over
            the noise floor.
        held_out_over_noise: its held-out RMS error over the noise floor.
        without_over_noise: the held-out error of the refit without an effect
            over the noise floor.
    """

    effects: tuple[str, ...]
    training_over_noise: float
    held_out_over_noise: float
    without_over_noise: float

    def sentence(self) -> str:
        """The verdict's account of the effects set aside, and what to try."""
        names = ", ".join(self.effects)
        it = "they" if len(self.effects) > 1 else "it"
        said = (
            f"NOT CONVERGED, no effect adopted: with the tentative {names} the model fits "
            f"the training runs at {self.training_over_noise:.2f} and the held-out run at "
            f"{self.held_out_over_noise:.2f} x the noise floor (without an effect "
            f"{self.without_over_noise:.2f}); {it} passed the acceptance rule but the model "
            f"is not at the noise, so {it} may stand in for a base model that does not fit"
        )
        if self.training_over_noise > CONVERGED_RATIO:
            return said + (
                ": the fit stops short on the training runs (try more --iterations, or "
                "identify again from other parameters)"
            )
        return said + (
            ": the held-out run goes where the training runs leave the model undetermined "
            "(add a training run that covers it)"
        )

    def to_json(self) -> dict:
        return {
            "effects": list(self.effects),
            "training_over_noise_floor": self.training_over_noise,
            "held_out_over_noise_floor": self.held_out_over_noise,
            "without_effects_over_noise_floor": self.without_over_noise,
        }


@dataclass(frozen=True)
class Diagnosis:
    """The whole diagnosis of one axis.

    Attributes:
        axis: gimbal axis name.
        rounds: the rounds, in order.
        rmse_before: held-out RMS error of the given model, unchanged [rad/s].
        rmse_after: held-out RMS error of the final model [rad/s].
        noise_floor: noise estimate [rad/s] (first round).
        params_out: the updated parameter set (effects added, rate parameters
            re-identified). Without a new effect: the plain re-identification
            if it passes the acceptance rule against the given parameters
            (`refit`), else the input set.
        analysis_before / analysis_after: residual analyses on the training
            runs, given model and final model.
        holdout_names: the held-out runs (or "cross-validation").
        refit: the re-identification without a new effect judged against the
            given parameters.
        tentative: effects that passed the acceptance rule but left the
            held-out error above `CONVERGED_RATIO` noise floors: not adopted
            (an effect that does not bring the model to the noise may be
            standing in for a base model that does not fit).
        tentative_fit: how far the model with them got (`TentativeFit`),
            where there are tentative effects.
        timing: the data's read-out timing (found by the base model's fit,
            or at the file's parameters).
        integration: how the model integrates a sample (`Integration`).
        equivalent: effects the data cannot tell apart from the first
            accepted one (`ALIKE`, significant too, held-out MSE within the
            selection's tie margin): the answer is ambiguous between them.
        side_angle: the angle whose sign chose each sample's half-plane:
            ``fused`` (the measured angle fused with the integrated gyro),
            ``resolver`` (the angle as read), or a fixed ``right``/``left``.
        explained: set where the effects were adopted though the held-out
            error stays above `CONVERGED_RATIO` (`TrainingExplained`).
        delay_as_read_out: an input delay [s] under a sample found at the
            point gyro reading and set aside: the averaged reading without
            it fits the held-out runs at the noise and as well
            (`search._delay_or_averaging`); None otherwise.
    """

    axis: str
    rounds: tuple[RoundResult, ...]
    rmse_before: float
    rmse_after: float
    noise_floor: float
    params_out: ParameterSet
    analysis_before: ResidualAnalysis
    analysis_after: ResidualAnalysis
    residual_before: tuple = ()
    residual_after: tuple = ()
    holdout_names: tuple[str, ...] = ()
    refit: Verdict | None = None
    stack: RunStack | None = field(default=None, repr=False)
    tentative: tuple[str, ...] = ()
    tentative_fit: TentativeFit | None = None
    timing: Timing = Timing()
    integration: Integration = DEFAULT_INTEGRATION
    equivalent: tuple[str, ...] = ()
    implied_torque_offset: ImpliedOffset | None = None
    side_angle: str = "fused"
    explained: TrainingExplained | None = None
    delay_as_read_out: float | None = None

    @property
    def accepted(self) -> tuple[CandidateFit, ...]:
        return tuple(r.model for r in self.rounds if r.selected != BASELINE)

    def none_words(self) -> tuple[str, str | None]:
        """The answer `none` in words, (what, why or None): no effect found,
        no effect adopted where effects were set aside as tentative (not the
        same answer), or none found where a sub-sample delay was read as the
        gyro's averaging. The text and the report word it each their way."""
        if self.tentative:
            return "no effect adopted", f"tentative: {', '.join(self.tentative)}"
        if self.delay_as_read_out is not None:
            return (
                "no missing effect found",
                "a sub-sample input delay read as the gyro's averaging",
            )
        return "no missing effect found", None

    @property
    def selected_effect(self) -> str:
        """The first accepted effect, or ``none``."""
        acc = self.accepted
        return acc[0].name if acc else BASELINE

    def to_json(self) -> dict:
        """The ``--json`` record (see docs/diagnosis.md)."""
        first = self.rounds[0]
        return json_safe(
            {
                "axis": self.axis,
                **self._verdict_json(),
                **self._model_json(),
                **self._effects_json(),
                "ranking": [
                    {
                        "name": v.name,
                        "holdout_rmse": v.holdout_rmse,
                        "improvement_z": v.improvement_z,
                        "delta_bic": v.delta_bic,
                        "significant": v.significant,
                        "reason": v.reason,
                        "parameters": dict(first.fits[v.name].params),
                    }
                    for v in first.verdicts
                ],
                "rounds": [
                    {"selected": r.selected, "ranking": [v.name for v in r.verdicts]}
                    for r in self.rounds
                ],
                "analysis_before": self.analysis_before.summary(),
                "analysis_after": self.analysis_after.summary(),
            }
        )

    def _verdict_json(self) -> dict:
        """Whether the final model is at the noise, and the effects set aside."""
        ratio = self.rmse_after / self.noise_floor if self.noise_floor > 0 else float("inf")
        converged = bool(ratio <= CONVERGED_RATIO)
        if converged:
            why = "the model is at the noise"
        elif self.explained is not None:
            why = self.explained.sentence(", ".join(f.name for f in self.accepted))
        elif self.tentative_fit is not None:
            why = self.tentative_fit.sentence()
        else:
            why = (
                "NOT CONVERGED: the model has not converged or lacks an effect the "
                "library does not have (try more --iterations, other runs, or a new effect)"
            )
        return {
            "converged": converged,
            "rmse_over_noise_floor": ratio,
            "verdict": f"held-out RMS error {ratio:.2f} x the noise floor: {why}",
            "training_explained": None if self.explained is None else self.explained.to_json(),
            "tentative_effects": list(self.tentative),
            "tentative_fit": None if self.tentative_fit is None else self.tentative_fit.to_json(),
            "equivalent_effects": list(self.equivalent),
            "equivalent_torque_offset": _offset_json(self.implied_torque_offset),
            "delay_as_read_out_s": self.delay_as_read_out,
        }

    def _model_json(self) -> dict:
        """How the data were read and the model integrated, and the record's units."""
        return {
            "timing": {
                "gyro_average": self.timing.gyro_average,
                "side_shift_steps": self.timing.side_shift,
            },
            "integration": self.integration.to_json(),
            "side_angle": self.side_angle,
            "units": {
                "rmse_before": "rad/s",
                "rmse_baseline_refit": "rad/s",
                "rmse_after": "rad/s",
                "noise_floor": "rad/s",
                "holdout_rmse": "rad/s",
                "effect_parameters": "SI, unit in the parameter name",
            },
        }

    def _effects_json(self) -> dict:
        """The selected effects with their parameters, and the held-out errors."""
        acc = self.accepted
        return {
            "rmse_before_deg_s": self.rmse_before / DEG,
            "rmse_after_deg_s": self.rmse_after / DEG,
            "noise_floor_deg_s": self.noise_floor / DEG,
            "selected_effect": self.selected_effect,
            "effect_parameters": dict(acc[0].params) if acc else {},
            "effect_ci95": dict(acc[0].ci95) if acc else {},
            "effect_placed_by_held_out": list(acc[0].placed) if acc else [],
            "all_selected": [
                {
                    "name": f.name,
                    "parameters": dict(f.params),
                    "ci95": dict(f.ci95),
                    "placed_by_held_out": list(f.placed),
                }
                for f in acc
            ],
            "rmse_before": self.rmse_before,
            "rmse_baseline_refit": float(rms_of(self.rounds[0].holdout_before)),
            "rmse_after": self.rmse_after,
            "refit_adopted": bool(not acc and self.refit is not None and self.refit.significant),
            "noise_floor": self.noise_floor,
            "holdout": list(self.holdout_names),
        }


def _offset_json(o: ImpliedOffset | None) -> dict | None:
    """The constant torque the levels of the answer `none` imply (`implied_offset`)."""
    if o is None:
        return None
    return {
        "accel_rad_s2": o.value_rad_s2,
        "ci95_rad_s2": o.ci95,
        "right_side_rad_s2": o.right_rad_s2,
        "right_ci95_rad_s2": o.right_ci95,
        "left_side_rad_s2": o.left_rad_s2,
        "left_ci95_rad_s2": o.left_ci95,
        "consistent": o.consistent,
        "meaning": "(Tc- - Tc+)/(2 J) of the model without an effect: a constant torque is "
        "exactly this shift of the per-direction levels, plus the bearings' own asymmetry",
    }


def rms_of(parts) -> float:
    x = np.concatenate([np.asarray(p) for p in parts]) if len(parts) else np.array([np.nan])
    return float(np.sqrt(np.mean(x**2)))
