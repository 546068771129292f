"""The identification report: Table 2 and Table 3 of the paper, Fig. 4 plots.

`write_report` writes a Markdown file and, beside it, one PNG per data set
(measured vs model rate and the error, as the paper's Fig. 4). `result_json`
gives the machine-readable summary written by ``identify --json``.
Rates are shown in deg/s (the paper's unit), converted here at the edge.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from isp_twin.estimation.coverage import beyond_training, thin_training, untrained_breakaways
from isp_twin.estimation.simulation_error import stack_runs
from isp_twin.estimation.verdict import FitVerdict, fit_verdict, noise_floor_of
from isp_twin.identification.cost import (
    held_out_determined,
    model_breakaways,
    rmse,
    simulate_data,
)
from isp_twin.identification.fit import IdentificationResult
from isp_twin.identification.held_out_spread import held_out_spread
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.side_angle import sides_as_read
from isp_twin.model.effects.resonance import Resonance
from isp_twin.model.parameters import PAPER_FIELDS, RATE_LAYOUT, AxisParams
from isp_twin.output.files import staged_path, write_text_atomic
from isp_twin.units import DEG
from isp_twin.vocabulary import REGIMES

__all__ = [
    "rmse_table",
    "result_json",
    "write_report",
    "PAPER_TO_RATE",
    "identification_verdict",
    "payload_hint",
]

#: Which rate-form quantity determines each paper parameter (b: none, fixed).
PAPER_TO_RATE: dict[str, str | None] = {
    "a": "pole",
    "b": None,
    "Ke": "gain",
    "Ts": "static",
    "Tc": "coulomb",
    "alpha": "alpha",
}


def rmse_table(result: IdentificationResult, data: Sequence[MeasuredData]) -> dict[str, float]:
    """RMS rate error per set [deg/s] (Table 3)."""
    s = result.settings
    return {
        d.name: float(
            rmse(
                result.rate,
                [d],
                s.side_source,
                s.rest_rate_deg_s,
                result.effects,
                result.timing,
                result.integration,
            )
        )
        / DEG
        for d in data
    }


def _identifiable(result: IdentificationResult, regime: int, field: str) -> bool:
    rate_field = PAPER_TO_RATE[field]
    if rate_field is None:
        return False
    return bool(result.identifiable[RATE_LAYOUT.index(regime, rate_field)])


#: What to try when an identification is not at the noise.
ADVICE = (
    "The Eq. 6 model has not converged on these data, or the axis has an effect Eq. 6 "
    "lacks. Try: 'isp-twin diagnose' with the written parameter file to look for a missing "
    "effect; more --generations or another --seed; runs that stay off the hard stops and "
    "visit each regime; --side for a freely spinning axis."
)


def identification_verdict(
    result: IdentificationResult, train: Sequence[MeasuredData], validation: Sequence[MeasuredData]
) -> FitVerdict:
    """Training and validation RMS errors against each set's noise floor;
    the advice names the regimes where the validation runs leave the
    training runs' speeds (`beyond_training`) or move far more often
    (`thin_training`), and a payload mode the sensors show (`payload_hint`)."""
    rmse_all = dict(result.rmse_train)
    rmse_all.update({k: v * DEG for k, v in rmse_table(result, validation).items()})
    floors = {d.name: noise_floor_of([d.omega]) for d in list(train) + list(validation)}
    side = result.settings.side_source
    coverage = (
        sides_as_read(train, side),
        sides_as_read(validation, side),
        noise_floor_of([d.omega for d in train]),
    )
    beyond, thin = beyond_training(*coverage), thin_training(*coverage)
    names = [d.name for d in validation]
    spread = held_out_spread(result, train, validation)
    broke, determined = _breakaways(result, train, validation)
    found = (beyond, spread, thin, broke, determined)
    verdict = fit_verdict(rmse_all, floors, names, ADVICE, *found)
    if verdict.converged or any(e.name == "resonance" for e in result.effects):
        return verdict
    # Only a fit that has not converged gets advice: the runs are stacked
    # for the hint only then (a long log costs a stack of its length).
    hinted = payload_hint(train) + ADVICE
    return fit_verdict(rmse_all, floors, names, hinted, *found)


def _breakaways(
    result: IdentificationResult,
    train: Sequence[MeasuredData],
    validation: Sequence[MeasuredData],
) -> tuple:
    """The fitted model's breakaways per regime on `train` and rests on
    `validation` (`model_breakaways`), and each validation run's error
    before the model first rests where it never breaks away on `train`
    (`held_out_determined`)."""
    s = result.settings
    model = (s.side_source, s.rest_rate_deg_s, result.effects, result.timing, result.integration)
    counts = model_breakaways(result.rate, train, validation, *model)
    untrained = untrained_breakaways(*counts)
    return counts, held_out_determined(result.rate, validation, untrained, *model)


def payload_hint(runs: Sequence[MeasuredData]) -> str:
    """A sentence for the advice where the gyro and the angle sensor show a
    payload's mode between them (`Resonance.deflection_peak` of the runs'
    `RunStack.deflection`), else "".

    A strong payload leaves Eq. 6 hundreds of noise floors off whatever the
    search does (reference resonance seed 30: 1860), and says so in the
    data: its mode is the largest, sharp peak of that difference.
    """
    if not runs or any(len(d) < 8 for d in runs):
        return ""
    stack = stack_runs(runs)
    peak = Resonance.deflection_peak(*stack.deflection(), stack.dt)
    if peak is None:
        return ""
    return (
        f"The gyro and the angle sensor differ by a mode near {peak:.1f} Hz, as a flexible "
        "payload between them makes: 'isp-twin diagnose' fits it (the effect 'resonance'). "
    )


def _training_floor(result: IdentificationResult, train: Sequence[MeasuredData]) -> float:
    """The training runs' pooled noise floor [rad/s], by the verdict's estimator
    (`noise_floor_of`); without the runs, the fit's own noise scale."""
    return noise_floor_of([d.omega for d in train]) if train else result.noise


def result_json(
    result: IdentificationResult,
    axis: str,
    params: AxisParams,
    validation: Sequence[MeasuredData] = (),
    train: Sequence[MeasuredData] = (),
    verdict: FitVerdict | None = None,
) -> dict:
    """The ``--json`` content: verdict, parameters, ci95, identifiable, RMS errors.

    Error figures are in deg/s, with the unit in the key or in ``units``;
    undefined numbers are null (JSON has no NaN).
    """

    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    parameters, ci95, identifiable = {}, {}, {}
    for r, name in enumerate(REGIMES):
        reg, ci = params.regimes[r], params.ci95[r]
        parameters[name] = {f: getattr(reg, f) for f in PAPER_FIELDS}
        ci95[name] = {f: (num(getattr(ci, f)) if ci is not None else None) for f in PAPER_FIELDS}
        identifiable[name] = {f: _identifiable(result, r, f) for f in PAPER_FIELDS}
    labels = RATE_LAYOUT.labels()
    if verdict is None and train:
        verdict = identification_verdict(result, train, validation)
    if verdict is not None:
        rmse_validation = {n: verdict.rmse[n] / DEG for n in verdict.held_out}
    else:
        rmse_validation = rmse_table(result, validation)
    return {
        "axis": axis,
        "converged": verdict.converged if verdict else None,
        "rmse_over_noise_floor": num(verdict.worst_ratio) if verdict else None,
        "verdict": verdict.to_json() if verdict else None,
        "units": {
            "rmse": "deg/s",
            "noise_floor": "deg/s (white rate-noise standard deviation of the data)",
            "parameters": "paper form (see parameter file units)",
            "rate_form": "SI: pole 1, gain rad/s per command unit per sample, "
            "static/coulomb rad/s per sample, alpha s/rad",
        },
        "parameters": parameters,
        "ci95": ci95,
        "identifiable": identifiable,
        "regime_identified": dict(zip(REGIMES, result.regime_identified)),
        "regime_visits": dict(zip(REGIMES, (int(v) for v in result.visits))),
        "rate_form": {
            "value": dict(zip(labels, map(float, result.vector))),
            "ci95": dict(zip(labels, (num(c) for c in result.ci95))),
            "identifiable": dict(zip(labels, map(bool, result.identifiable))),
        },
        "rmse_train": {k: v / DEG for k, v in result.rmse_train.items()},
        "rmse_validation": rmse_validation,
        "cost_deg_s": result.cost / DEG,
        "noise_floor_deg_s": num(_training_floor(result, train) / DEG),
        "status": result.status,
        "outcome": result.outcome.value,
        "search_log": [step.to_json() for step in result.log],
        "evaluations": result.evaluations,
        "wall_time_s": result.wall_time_s,
        "residual_lag1_correlation": num(result.rho),
        "effects_held": [{"name": e.name, "parameters": dict(e.params)} for e in result.effects],
        "timing": {
            "gyro_average": result.timing.gyro_average,
            "side_shift_steps": result.timing.side_shift,
        },
        "integration": result.integration.to_json(),
    }


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _table2(result: IdentificationResult, params: AxisParams) -> list[str]:
    lines = [
        "| parameter | " + " | ".join(REGIMES) + " |",
        "|---|" + "---|" * len(REGIMES),
    ]
    for f in PAPER_FIELDS:
        cells = []
        for r in range(len(REGIMES)):
            v = getattr(params.regimes[r], f)
            ci = params.ci95[r]
            c = getattr(ci, f) if ci is not None else math.nan
            if not result.regime_identified[r]:
                cells.append(f"{_fmt(v)} (prior, not visited)")
            elif f == "b":
                cells.append(f"{_fmt(v)} (fixed)")
            elif math.isfinite(c):
                cells.append(f"{_fmt(v)} ± {_fmt(c)}")
            else:
                cells.append(f"{_fmt(v)} (not identifiable)")
        lines.append(f"| {f} | " + " | ".join(cells) + " |")
    return lines


def _rate_table(result: IdentificationResult) -> list[str]:
    units = {
        "pole": "1",
        "gain": "rad/s per unit per sample",
        "static": "rad/s per sample",
        "coulomb": "rad/s per sample",
        "alpha": "s/rad",
    }
    lines = [
        "| quantity | unit | " + " | ".join(REGIMES) + " |",
        "|---|---|" + "---|" * len(REGIMES),
    ]
    for f in RATE_LAYOUT.fields:
        cells = []
        for r in range(len(REGIMES)):
            k = RATE_LAYOUT.index(r, f)
            v = result.vector[k]
            c = result.ci95[k]
            cells.append(f"{_fmt(v)} ± {_fmt(c)}" if math.isfinite(c) else f"{_fmt(v)} (—)")
        lines.append(f"| {f} | {units[f]} | " + " | ".join(cells) + " |")
    return lines


def _plot(result: IdentificationResult, d: MeasuredData, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result.settings
    model = simulate_data(
        result.rate,
        d,
        s.side_source,
        s.rest_rate_deg_s,
        result.effects,
        result.timing,
        result.integration,
    ).omega
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    ax1.plot(d.t, d.omega / DEG, lw=0.8, label="measured")
    ax1.plot(d.t, model / DEG, lw=0.8, ls="--", label=f"model ({result.integration.describe()})")
    ax1.set_ylabel("rate [deg/s]")
    ax1.legend(loc="best")
    ax1.set_title(title)
    ax2.plot(d.t, (d.omega - model) / DEG, lw=0.6, color="C3")
    ax2.set_ylabel("measured - model [deg/s]")
    ax2.set_xlabel("t [s]")
    fig.tight_layout()
    with staged_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def write_report(
    path: str | Path,
    result: IdentificationResult,
    axis: str,
    params: AxisParams,
    train: Sequence[MeasuredData],
    validation: Sequence[MeasuredData] = (),
    parameters_path: str | Path | None = None,
    verdict: FitVerdict | None = None,
) -> Path:
    """Write the Markdown report and its PNG figures (beside it); return its path."""
    path = Path(path)
    stem = path.with_suffix("")
    if verdict is None:
        verdict = identification_verdict(result, train, validation)
    lines = [
        f"# Identification report: {axis}",
        "",
        "## Verdict",
        "",
        *verdict.lines(),
        "",
        f"Identified from {len(train)} set(s): {', '.join(d.name for d in train)}.",
        f"Parameter file: `{parameters_path}`." if parameters_path else "",
        f"Search: {result.status}; {result.evaluations} simulated parameter sets, "
        f"{result.wall_time_s:.1f} s. Eq. 9 cost {result.cost / DEG:.4g} deg/s "
        f"(equation-error start {result.initial_cost / DEG:.4g} deg/s).",
        f"Read-out timing: {result.timing.describe()}. Model: Eq. 6 parameters "
        f"(per sample), integrated as {result.integration.describe()}.",
        f"Half-plane from: `{result.settings.side_source}` angle. Residual lag-1 correlation "
        f"{result.rho:.3f} (intervals inflated by (1+rho)/(1-rho) when positive).",
        "Extra effects of the prior, held fixed in the fit and in every simulation here: "
        + (", ".join(e.name for e in result.effects) or "none")
        + ".",
        "",
        "## Regime visits",
        "",
        "| regime | moving samples | identified |",
        "|---|---|---|",
    ]
    for r, name in enumerate(REGIMES):
        lines.append(
            f"| {name} | {result.visits[r]} | {'yes' if result.regime_identified[r] else 'no (prior kept)'} |"
        )
    lines += [
        "",
        "## Table 2: parameters (value ± 95 % half-width)",
        "",
        "b is not identifiable from rate data (only b·Ke, b·Ts, b·Tc are); it is fixed "
        "to the prior and Ke, Ts, Tc follow from the identified products.",
        "",
        *_table2(result, params),
        "",
        "### The identified rate form (SI)",
        "",
        *_rate_table(result),
        "",
        "## Table 3: RMS rate error [deg/s]",
        "",
        "| set | role | RMS error [deg/s] | [rad/s] |",
        "|---|---|---|---|",
    ]
    for d in train:
        v = result.rmse_train[d.name]
        lines.append(f"| {d.name} | identification | {v / DEG:.4g} | {v:.4g} |")
    for name in verdict.held_out:
        v = verdict.rmse[name] / DEG
        lines.append(f"| {name} | validation | {v:.4g} | {v * DEG:.4g} |")
    lines += ["", "## Measured vs model rate (Fig. 4)", ""]
    for role, sets in (("identification", train), ("validation", validation)):
        for d in sets:
            png = Path(f"{stem}_{d.name}.png")
            _plot(result, d, png, f"{d.name} ({role})")
            lines.append(f"![{d.name}]({png.name})")
            lines.append("")
    return write_text_atomic(path, "\n".join(lines) + "\n")
