"""Test helper: the library with a reference axis' true parameters."""

from __future__ import annotations

import numpy as np

from isp_twin.diagnosis.prepared_runs import checked_inputs, fused_runs
from isp_twin.diagnosis.search import _prepared
from isp_twin.estimation.parameter_file import fitted_axis
from isp_twin.estimation.simulation_error import RunStack, stack_runs
from isp_twin.identification.cost import rmse
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing, fitted_with
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    EffectSpec,
    ParameterSet,
    RateParams,
    load_parameters,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.reference import REGIME_NAMES, Axis, design_experiment
from isp_twin.reference.truth import rate_form
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG


def true_rate_params(axis: Axis) -> RateParams:
    """A reference axis' rate form (`isp_twin.reference.truth.rate_form`, 1 ms
    samples) as the model's parameters."""
    form = rate_form(axis)
    return RateParams.from_vector(
        np.concatenate([[form[n][f] for f in RATE_LAYOUT.fields] for n in REGIME_NAMES])
    )


def truth_rate_vector(truth: dict) -> np.ndarray:
    """The rate vector (`RATE_LAYOUT`) of a reference experiment's truth
    (`Experiment.truth()`), its regimes in the model's order."""
    regimes = truth["rate_form"]["regimes"]
    return np.concatenate(
        [[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]]
    )


def truth_parameter_set(
    truth: dict, axis: str, timing: Timing, note: str = "truth"
) -> ParameterSet:
    """The default parameter set with `axis` holding a reference truth's
    rate form and no effect, recorded as fitted at the read-out `timing`
    with the default integration (a parameter file as `identify` writes it)."""
    x = truth_rate_vector(truth)
    params = load_parameters(default_parameters_path())
    record = fitted_with(DEFAULT_INTEGRATION, timing)
    ax = fitted_axis(params.axis(axis), x, np.full_like(x, np.nan), (), record, note)
    return params.with_axis(axis, ax)


def training_stack(exp) -> RunStack:
    """A reference experiment's training runs (all but "heldout") at the
    averaged gyro reading, fused angle, as one `RunStack`."""
    runs = [d for n, d in measured_runs(exp).items() if n != "heldout"]
    return stack_runs(
        fused_runs(runs, Timing(0.0, True), DEFAULT_INTEGRATION),
        side=None,
        gyro_average=True,
        integration=DEFAULT_INTEGRATION,
    )


def measured_runs(exp) -> dict[str, MeasuredData]:
    """A reference experiment's runs as measured data (the resolver's
    reading as the angle), by run name."""
    return {
        n: MeasuredData(n, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])
        for n, r in exp.runs.items()
    }


def diagnose_options(timing: Timing) -> tuple:
    """`diagnose`'s options (`isp_twin.diagnosis.search._prepared`'s order)
    on the fused angle at the read-out `timing`: seed 0, the default
    integration, no base search, 8 iterations, 2 per fold."""
    return ("measured", 0, DEFAULT_INTEGRATION, timing, False, 8, 2)


def prepared_reference(seed: int, effect: str, axis: str, timing: Timing, candidates) -> tuple:
    """(the checked inputs, the data `diagnose` prepares at the read-out
    `timing` (`diagnose_options`), the parameter set holding the truth's
    rate form, the truth) of reference axis `seed` with `effect`, its
    held-out run of the covered design; `candidates`: the effects to test."""
    exp = design_experiment(seed, effect, held_out="covered")
    truth = exp.truth()
    params = truth_parameter_set(truth, axis, timing)
    runs = measured_runs(exp)
    train, held = [runs["train1"], runs["train2"]], [runs["heldout"]]
    checked = checked_inputs(train, held, params, axis, candidates, "measured")
    return checked, _prepared(checked, *diagnose_options(timing))[0], params, truth


def truth_error(seed: int, effect: str, integration: Integration) -> list[float]:
    """The sub-stepped model in `integration` with the reference's true rate
    parameters and effects (axis `seed`, `effect`), at its gyro read-out:
    RMS error over the gyro sigma per run, in run-name order (heldout,
    train1, train2)."""
    exp = design_experiment(seed, effect)
    truth = exp.truth()
    x = truth_rate_vector(truth)
    effects = [EffectSpec(e["name"], e["params"]) for e in truth["effects"]]
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    sigma = truth["noise_sigma_deg_s"] * DEG
    out = []
    for _, d in sorted(measured_runs(exp).items()):
        e = rmse(RateParams.from_vector(x), [d], effects=effects, timing=timing,
                 integration=integration)  # fmt: skip
        out.append(float(e) / sigma)
    return out
