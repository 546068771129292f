"""Uncertainty and sensitivity of a closed-loop scenario: J with a 90 % band, and what moves it.

`isp-twin campaign SCENARIO --uncertainty N` runs N draws. Draw d gets

* a plant drawn from the parameter file's ci95 (`isp_twin.experiments.sweep.design.draw_parameters`,
  seeded by (seed, d)); the NFC keeps the scenario's model (`nfc_parameters`:
  the identified one by default, else the file's nominal set), as a
  controller holds its identified model while the real plant differs;
* every unstated rig setting (`KnobRange`) drawn uniformly from its plausible
  range (seeded by (seed, d, 1)), the same value on both inner axes;
* noise seed = the scenario's seed + d;

and is run twice, with PI and with PI+NFC, on the sweep machinery (one
`RunSpec` per run, `isp_twin.experiments.sweep.execute`). Reported: mean J and the 5-95 %
percentile band per controller and of the NFC's relative reduction, and
a sensitivity table.

Sensitivity method: Spearman's rank correlation between each drawn input
(rig knob or Table 2 parameter) and each output over the draws. It measures a
monotone influence over the whole range while every other unknown varies too
(so it ranks the unknowns by how much of J's spread they explain, with no
extra runs and no linearity assumed); its significance is judged at 5 %
after a Bonferroni correction for the number of inputs. What rank
correlation cannot say is whether one setting alone, at the end of its range,
flips the NFC's benefit: `--oat` adds a one-at-a-time sweep (each knob at its
low and high end, the others and the plant nominal) that answers exactly
that, per setting.

The plausible ranges are the scenario's rig file's (models/rigs/, `isp_twin.experiments.rig`):
every knob with a `range` is drawn, where its `when` conditions hold.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from isp_twin.errors import ScenarioError
from isp_twin.experiments.paper import TABLE5, TABLE6, relative_reduction
from isp_twin.experiments.rig import Rig, load_rig
from isp_twin.experiments.scenario import Scenario, parse_scenario, scenario_to_raw
from isp_twin.experiments.sweep.design import (
    RunSpec,
    _file_digest,
    _set_key,
    draw_parameters,
    make_run,
)
from isp_twin.experiments.sweep.store import RunOutcome

__all__ = [
    "KnobRange",
    "rig_knob_ranges",
    "Band",
    "SensitivityRow",
    "OatRow",
    "UncertaintyResult",
    "uncertainty_runs",
    "oat_runs",
    "run_uncertainty",
    "format_uncertainty",
    "plot_uncertainty",
]

#: Paper reduction of the average J by NFC [%] for the scenarios that are paper experiments.
PAPER_REDUCTION = {
    "turbulence_1_6Hz": relative_reduction(TABLE6.pi_average, TABLE6.pi_nfc_average),
    "tracking_0_5Hz": relative_reduction(TABLE5.pi_average, TABLE5.pi_nfc_average),
}
#: The NFC reduction may differ from the paper's by this much [percentage points] (issue 10).
REDUCTION_TOLERANCE = 10.0
#: Fewer draws than this mark no correlation significant (rho = +-1 is common by chance).
MIN_DRAWS_FOR_SIGNIFICANCE = 10
#: Percentiles of the band: a central 90 % interval.
BAND_PERCENTILES = (5.0, 95.0)


@dataclass(frozen=True)
class KnobRange:
    """One unstated rig setting and its plausible range.

    Attributes:
        name: the knob's name (rig file).
        keys: scenario key paths it sets (all get the same value).
        low, high: the plausible range, in `unit`.
        integer: drawn as an integer.
        unit: its unit (paper units, as in the scenario file).
        provenance: paper / assumption / calibrated.
        when: scenario key path -> value; the knob applies only where they match.
    """

    name: str
    keys: tuple[str, ...]
    low: float
    high: float
    integer: bool = False
    unit: str = ""
    provenance: str = "assumption"
    when: Mapping[str, Any] | None = None

    def applies(self, raw: Mapping) -> bool:
        """Whether the knob applies to a scenario (as a raw mapping)."""
        return all(_get_key(raw, k) == v for k, v in (self.when or {}).items())


def _get_key(raw: Mapping, path: str) -> Any:
    node: Any = raw
    for part in path.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def rig_knob_ranges(rig: Rig) -> tuple[KnobRange, ...]:
    """The rig's knobs that have a plausible range, as `KnobRange`s (the rig file is the source).

    Named settings (``choices``: the PI form, the NFC's model) are not drawn:
    the scenario's choice stays. A knob is drawn as an integer when its value is one.
    """
    out = []
    for k in rig.knobs.values():
        if k.range is None:
            continue
        integer = isinstance(k.value, int) and not isinstance(k.value, bool)
        lo, hi = (int(x) for x in k.range) if integer else (float(x) for x in k.range)
        when = dict(k.when) or None
        out.append(KnobRange(k.name, tuple(k.keys), lo, hi, integer, k.unit, k.provenance, when))
    return tuple(out)


# ---------------------------------------------------------------- design


def _draw_knobs(knobs: Sequence[KnobRange], seed: int, draw: int) -> dict[str, float | int]:
    rng = np.random.default_rng([seed, draw, 1])
    out: dict[str, float | int] = {}
    for k in knobs:
        if k.integer:
            out[k.name] = int(rng.integers(int(k.low), int(k.high), endpoint=True))
        else:
            out[k.name] = float(rng.uniform(k.low, k.high))
    return out


def _scenario_raw(
    scenario: Scenario, nfc: bool, values: Mapping[str, float], knobs: Sequence[KnobRange]
) -> dict:
    by_name = {k.name: k for k in knobs}
    raw = scenario_to_raw(scenario.with_nfc(nfc))
    for name, value in values.items():
        for key in by_name[name].keys:
            _set_key(raw, key, value)
    where = ", ".join(f"{n}={v:g}" for n, v in values.items())
    try:
        parsed = parse_scenario(raw, scenario.source or "<scenario>")
    except ScenarioError as exc:
        raise ScenarioError(f"the draw with {where}: {exc}") from None
    out = scenario_to_raw(parsed)
    out["name"] = scenario.name
    return out


def _applicable(scenario: Scenario, knobs: Sequence[KnobRange]) -> tuple[KnobRange, ...]:
    raw = scenario_to_raw(scenario)
    return tuple(k for k in knobs if k.applies(raw))


def uncertainty_runs(
    scenario: Scenario,
    n_draws: int,
    seed: int,
    params_path: Path,
    knobs: Sequence[KnobRange],
    axis: str = "inner_az",
    first_seed: int | None = None,
) -> list[RunSpec]:
    """The draws as a sweep design: draw d -> (PI, PI+NFC), runs 2d and 2d + 1.

    Each run's knobs hold ``label``, ``draw`` and every drawn rig value; its
    ``parameter_draw`` the drawn plant.
    """
    from isp_twin.errors import ParameterError
    from isp_twin.input_files import load_yaml
    from isp_twin.model.parameters import load_parameters

    params_path = Path(params_path).resolve()
    load_parameters(params_path)  # a bad file stops here, naming the file and key
    params_raw = load_yaml(params_path, "parameter file", ParameterError)[0] or {}
    if not draw_parameters(params_raw, seed, 0):
        raise ScenarioError(f"{params_path}: gives no ci95 to draw the plant from")
    digest = _file_digest(params_path)
    first = scenario.seed if first_seed is None else first_seed
    runs: list[RunSpec] = []
    for d in range(n_draws):
        values = _draw_knobs(knobs, seed, d)
        pdraw = draw_parameters(params_raw, seed, d)
        for label, nfc in (("PI", False), ("PI+NFC", True)):
            raw = _scenario_raw(scenario, nfc, values, knobs)
            meta = {"label": label, "draw": d, **values}
            runs.append(
                make_run(
                    len(runs), raw, scenario.source, params_path, first + d, meta, axis, pdraw,
                    digest,
                )
            )  # fmt: skip
    return runs


def oat_runs(
    scenario: Scenario,
    params_path: Path,
    knobs: Sequence[KnobRange],
    seeds: Sequence[int],
    axis: str = "inner_az",
) -> list[RunSpec]:
    """One-at-a-time: the nominal scenario, then each knob at its low and high end.

    Nominal plant, the other knobs at the scenario's values; PI and PI+NFC,
    every seed. Knobs carry ``label``, ``knob`` (None for nominal) and ``end``.
    """
    params_path = Path(params_path).resolve()
    digest = _file_digest(params_path)
    runs: list[RunSpec] = []
    points: list[tuple[str | None, str, dict]] = [(None, "nominal", {})]
    for k in knobs:
        points += [(k.name, "low", {k.name: k.low}), (k.name, "high", {k.name: k.high})]
    for name, end, values in points:
        for label, nfc in (("PI", False), ("PI+NFC", True)):
            raw = _scenario_raw(scenario, nfc, values, knobs)
            meta = {"label": label, "knob": name, "end": end}
            for s in seeds:
                runs.append(
                    make_run(
                        len(runs), raw, scenario.source, params_path, s, meta, axis, None, digest
                    )
                )
    return runs


# ---------------------------------------------------------------- results


@dataclass(frozen=True)
class Band:
    """Mean and central 90 % interval (5th and 95th percentiles) of a quantity over the draws."""

    mean: float
    low: float
    high: float

    @classmethod
    def of(cls, x: np.ndarray) -> Band:
        lo, hi = np.percentile(x, BAND_PERCENTILES)
        return cls(float(np.mean(x)), float(lo), float(hi))

    def as_dict(self) -> dict:
        return {"mean": self.mean, "p5": self.low, "p95": self.high}


@dataclass(frozen=True)
class SensitivityRow:
    """Spearman rank correlation of one drawn input with the outputs over the draws.

    Attributes:
        name: the input (rig knob name, or ``axis regime field`` of Table 2).
        rho_pi, rho_nfc, rho_reduction: correlation with J (PI), J (PI+NFC)
            and the NFC's relative reduction (NaN where the input is constant).
        significant: some |rho| is significant at 5 % after Bonferroni.
    """

    name: str
    rho_pi: float
    rho_nfc: float
    rho_reduction: float
    significant: bool

    @property
    def strength(self) -> float:
        """The largest |rho| of the three (NaN counts as 0)."""
        return max(abs(np.nan_to_num(r)) for r in (self.rho_pi, self.rho_nfc, self.rho_reduction))


@dataclass(frozen=True)
class OatRow:
    """One knob at the ends of its range, all else nominal (means over the seeds).

    Attributes:
        knob: its name; unit, low, high: its range.
        j_pi, j_nfc: J [%] at (low, high).
        reduction: the NFC's relative reduction [%] at (low, high).
        failed: runs of this knob that diverged (J then from the rest).
    """

    knob: str
    unit: str
    low: float
    high: float
    j_pi: tuple[float, float]
    j_nfc: tuple[float, float]
    reduction: tuple[float, float]
    failed: int


@dataclass(frozen=True)
class UncertaintyResult:
    """An uncertainty campaign.

    Attributes:
        scenario, axis, seed: what was run (`seed` seeds the draws).
        inputs: input name -> values per successful draw, shape (n_ok,).
        j_pi, j_nfc, reduction: per successful draw [%], shape (n_ok,).
        draws: draws designed; failed: draws with a failed run (left out).
        sensitivity: rows, strongest first.
        paper_reduction: the paper's reduction [%] (None: not a paper experiment).
        oat: one-at-a-time rows (empty without ``--oat``); oat_nominal:
            (J PI, J PI+NFC, reduction) of the nominal scenario.
    """

    scenario: str
    axis: str
    seed: int
    inputs: Mapping[str, np.ndarray]
    j_pi: np.ndarray
    j_nfc: np.ndarray
    reduction: np.ndarray
    draws: int
    failed: int
    sensitivity: tuple[SensitivityRow, ...]
    paper_reduction: float | None
    oat: tuple[OatRow, ...] = ()
    oat_nominal: tuple[float, float, float] | None = None

    @property
    def bands(self) -> dict[str, Band]:
        return {
            "J_PI": Band.of(self.j_pi),
            "J_PI+NFC": Band.of(self.j_nfc),
            "reduction": Band.of(self.reduction),
        }

    def oat_verdict(self, row: OatRow) -> str:
        """``sign lost`` (reduction <= 0 at an end, or a run failed), ``off`` (more than
        `REDUCTION_TOLERANCE` points from the paper's), else ``ok``."""
        red = row.reduction
        if row.failed or not all(math.isfinite(r) and r > 0.0 for r in red):
            return "sign lost"
        if self.paper_reduction is not None and any(
            abs(r - self.paper_reduction) > REDUCTION_TOLERANCE for r in red
        ):
            return "off"
        return "ok"

    def as_json(self) -> dict:
        out = {
            "scenario": self.scenario,
            "axis": self.axis,
            "seed": self.seed,
            "draws": self.draws,
            "failed_draws": self.failed,
            "bands": {k: b.as_dict() for k, b in self.bands.items()},
            "paper_reduction_percent": self.paper_reduction,
            "per_draw": {
                "J_PI": self.j_pi.tolist(),
                "J_PI+NFC": self.j_nfc.tolist(),
                "reduction": self.reduction.tolist(),
                "inputs": {k: v.tolist() for k, v in self.inputs.items()},
            },
            "sensitivity": [
                {
                    "input": r.name,
                    "rho_J_PI": _json_float(r.rho_pi),
                    "rho_J_PI+NFC": _json_float(r.rho_nfc),
                    "rho_reduction": _json_float(r.rho_reduction),
                    "significant": r.significant,
                }
                for r in self.sensitivity
            ],
        }
        if self.oat:
            out["one_at_a_time"] = {
                "nominal": dict(zip(("J_PI", "J_PI+NFC", "reduction"), self.oat_nominal or ())),
                "knobs": [
                    {
                        "knob": r.knob,
                        "unit": r.unit,
                        "range": [r.low, r.high],
                        "J_PI": list(r.j_pi),
                        "J_PI+NFC": list(r.j_nfc),
                        "reduction": list(r.reduction),
                        "failed_runs": r.failed,
                        "verdict": self.oat_verdict(r),
                    }
                    for r in self.oat
                ],
            }
        return out


def _json_float(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def _plant_inputs(runs: Sequence[RunSpec]) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for r in runs:
        for axis, regimes in (r.parameter_draw or {}).items():
            for regime, fields in regimes.items():
                for f, v in fields.items():
                    out.setdefault(f"{axis} {regime} {f}", []).append(v)
    return out


def sensitivity(
    inputs: Mapping[str, np.ndarray], outputs: Sequence[np.ndarray]
) -> tuple[SensitivityRow, ...]:
    """Spearman's rho of every input with each output, strongest first (see the module doc)."""
    from scipy.stats import spearmanr

    n_in = max(1, len(inputs))
    rows = []
    for name, x in inputs.items():
        rhos, sig = [], False
        for y in outputs:
            if np.ptp(x) == 0.0 or np.ptp(y) == 0.0 or len(x) < 3:
                rhos.append(math.nan)
                continue
            res = spearmanr(x, y)
            rhos.append(float(res.statistic))
            # below MIN_DRAWS_FOR_SIGNIFICANCE the p-value's normal approximation is meaningless
            enough = len(x) >= MIN_DRAWS_FOR_SIGNIFICANCE
            sig = sig or (enough and float(res.pvalue) < 0.05 / n_in)
        rows.append(SensitivityRow(name, rhos[0], rhos[1], rhos[2], sig))
    return tuple(sorted(rows, key=lambda r: -r.strength))


def run_uncertainty(
    scenario: Scenario,
    n_draws: int,
    seed: int = 0,
    params_path: Path | None = None,
    axis: str = "inner_az",
    jobs: int = 1,
    oat: bool = False,
    oat_seeds: int = 2,
    knobs: Sequence[KnobRange] | None = None,
    first_seed: int | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> UncertaintyResult:
    """Run the draws (and the one-at-a-time sweep) on the sweep machinery.

    Args:
        scenario: a closed-loop scenario (its NFC switch is overridden).
        n_draws: draws (each run with PI and with PI+NFC).
        seed: seeds the draws of the plant and of the rig knobs.
        params_path: the plant's parameter file (default: the scenario's).
        axis: inner axis of J.
        jobs: worker processes (1: in this process).
        oat: also the one-at-a-time sweep over each knob's range.
        oat_seeds: noise seeds per one-at-a-time point.
        knobs: the ranges (default: the scenario's rig file, `rig_knob_ranges`);
            only those whose conditions hold for the scenario are drawn.
        first_seed: noise seed of draw 0 (default: the scenario's).
        on_progress: called with (runs done, runs total).

    Raises:
        ScenarioError: no draws, or a drawn setting the scenario loader rejects.
    """
    knobs = _checked_knobs(scenario, n_draws, knobs)
    path = Path(params_path or scenario.parameters_path)
    runs = uncertainty_runs(scenario, n_draws, seed, path, knobs, axis, first_seed)
    seeds = range(scenario.seed, scenario.seed + oat_seeds)
    extra = oat_runs(scenario, path, knobs, seeds, axis) if oat else []
    outcomes = _execute_runs(runs + extra, jobs, on_progress)
    j_of = functools.partial(_j_of, axis=axis)
    ok_draws, jp, jn = _paired_j(scenario, runs, outcomes, n_draws, j_of)
    red = 100.0 * (jp - jn) / jp
    inputs = _drawn_inputs([runs[2 * d] for d in ok_draws], knobs)
    nominal, oat_rows = _oat_table(extra, outcomes, knobs, axis, j_of) if oat else (None, [])
    return UncertaintyResult(
        scenario=scenario.name,
        axis=axis,
        seed=seed,
        inputs=inputs,
        j_pi=jp,
        j_nfc=jn,
        reduction=red,
        draws=n_draws,
        failed=n_draws - len(ok_draws),
        sensitivity=sensitivity(inputs, (jp, jn, red)),
        paper_reduction=PAPER_REDUCTION.get(scenario.name),
        oat=tuple(oat_rows),
        oat_nominal=nominal,
    )


def _checked_knobs(
    scenario: Scenario, n_draws: int, knobs: Sequence[KnobRange] | None
) -> tuple[KnobRange, ...]:
    """The knob ranges to draw (default: the scenario's rig file), those that apply.

    Raises:
        ScenarioError: fewer than 2 draws, or not a closed-loop scenario.
    """
    if n_draws < 2:
        raise ScenarioError(f"--uncertainty needs at least 2 draws, got {n_draws}")
    if scenario.kind != "closed_loop":
        raise ScenarioError(f"{scenario.source}: kind: uncertainty needs a closed_loop scenario")
    if knobs is None:
        knobs = rig_knob_ranges(load_rig(scenario.rig_path))
    return _applicable(scenario, knobs)


def _execute_runs(
    runs: Sequence[RunSpec], jobs: int, on_progress: Callable[[int, int], None] | None
) -> dict[str, RunOutcome]:
    """Run everything on the sweep machinery (a store in memory): run key -> outcome."""
    from isp_twin.experiments.sweep.execute import execute
    from isp_twin.experiments.sweep.store import ResultStore

    with ResultStore(":memory:") as store:
        progress = None
        if on_progress is not None:

            def progress(p) -> None:
                on_progress(p.done, p.total)

        execute(runs, store, workers=jobs, in_process=jobs <= 1, on_progress=progress)
        return store.outcomes([r.key for r in runs])


def _drawn_inputs(pi_runs: Sequence[RunSpec], knobs: Sequence[KnobRange]) -> dict[str, np.ndarray]:
    """Each drawn input (rig knob, plant parameter) over the runs, shape (draws,)."""
    inputs = {k.name: np.array([float(r.knobs[k.name]) for r in pi_runs]) for k in knobs}
    inputs.update({k: np.array(v) for k, v in _plant_inputs(pi_runs).items()})
    return inputs


def _j_of(o: RunOutcome, axis: str) -> float | None:
    """J of Eq. 10 [%] on `axis`, None when the run failed."""
    m = o.metrics.get(axis) if o.status == "ok" else None
    return None if m is None else float(m["isolation_percent"])


def _paired_j(
    scenario: Scenario,
    runs: Sequence[RunSpec],
    outcomes: Mapping[str, RunOutcome],
    n_draws: int,
    j_of: Callable[[RunOutcome], float | None],
) -> tuple[list[int], np.ndarray, np.ndarray]:
    """The draws whose PI and PI+NFC runs both ran, with their J [%] (PI, PI+NFC).

    Raises:
        ScenarioError: fewer than 2 draws ran (the message has the failures' reasons).
    """
    ok_draws, j_pi, j_nfc = [], [], []
    for d in range(n_draws):
        a, b = j_of(outcomes[runs[2 * d].key]), j_of(outcomes[runs[2 * d + 1].key])
        if a is not None and b is not None:
            ok_draws.append(d)
            j_pi.append(a)
            j_nfc.append(b)
    if len(ok_draws) < 2:
        reasons = {o.error for o in outcomes.values() if o.status != "ok"}
        raise ScenarioError(
            f"{scenario.name}: fewer than 2 draws ran ({n_draws - len(ok_draws)} failed: "
            f"{'; '.join(sorted(str(r) for r in reasons))[:300]})"
        )
    return ok_draws, np.array(j_pi), np.array(j_nfc)


def _oat_table(runs, outcomes, knobs, axis, j_of):
    groups: dict[tuple, list[float | None]] = {}
    for r in runs:
        groups.setdefault((r.knobs["knob"], r.knobs["end"], r.knobs["label"]), []).append(
            j_of(outcomes[r.key])
        )

    def mean(key) -> tuple[float, int]:
        vals = [v for v in groups[key] if v is not None]
        return (float(np.mean(vals)) if vals else math.nan), len(groups[key]) - len(vals)

    (np_, _), (nn, _) = mean((None, "nominal", "PI")), mean((None, "nominal", "PI+NFC"))
    nominal = (np_, nn, relative_reduction(np_, nn))
    rows = []
    for k in knobs:
        jp, jn, failed = [], [], 0
        for end in ("low", "high"):
            (a, fa), (b, fb) = mean((k.name, end, "PI")), mean((k.name, end, "PI+NFC"))
            jp.append(a)
            jn.append(b)
            failed += fa + fb
        red = tuple(
            relative_reduction(a, b) if math.isfinite(a) and math.isfinite(b) else math.nan
            for a, b in zip(jp, jn)
        )
        rows.append(OatRow(k.name, k.unit, k.low, k.high, tuple(jp), tuple(jn), red, failed))
    return nominal, rows


# ---------------------------------------------------------------- output


def format_uncertainty(res: UncertaintyResult, top: int = 12) -> str:
    """Plain-text report: the bands, the sensitivity table, the one-at-a-time table."""
    ok = res.draws - res.failed
    lines = [
        f"uncertainty {res.scenario}: {ok} of {res.draws} draws ran "
        f"({res.failed} left out: a run diverged); axis {res.axis}, draw seed {res.seed}",
        "",
        f"{'quantity':<24} {'mean':>8} {'90 % band (p5 .. p95)':>24}",
    ]
    names = {
        "J_PI": "J PI [%]",
        "J_PI+NFC": "J PI+NFC [%]",
        "reduction": "NFC reduction [%]",
    }
    for key, b in res.bands.items():
        lines.append(f"{names[key]:<24} {b.mean:8.2f} {b.low:11.2f} .. {b.high:8.2f}")
    if res.paper_reduction is not None:
        inside = np.mean(np.abs(res.reduction - res.paper_reduction) <= REDUCTION_TOLERANCE)
        lines.append(
            f"paper reduction {res.paper_reduction:.1f} %: {100 * np.mean(res.reduction > 0):.0f} "
            f"% of the draws keep the sign, {100 * inside:.0f} % are within "
            f"+-{REDUCTION_TOLERANCE:g} points"
        )
    lines += [
        "",
        f"sensitivity (Spearman rank correlation over the draws; * significant at 5 % after "
        f"Bonferroni over {len(res.sensitivity)} inputs), strongest {min(top, len(res.sensitivity))}"
        + (
            ":"
            if len(res.j_pi) >= MIN_DRAWS_FOR_SIGNIFICANCE
            else f" (fewer than {MIN_DRAWS_FOR_SIGNIFICANCE} draws: significance not judged):"
        ),
        f"{'input':<28} {'rho J PI':>9} {'rho J NFC':>10} {'rho reduction':>14}",
    ]
    for r in res.sensitivity[:top]:
        lines.append(
            f"{r.name:<28} {r.rho_pi:9.2f} {r.rho_nfc:10.2f} {r.rho_reduction:14.2f}"
            f"{' *' if r.significant else ''}"
        )
    if res.oat:
        p = res.oat_nominal or (math.nan,) * 3
        lines += [
            "",
            "one at a time (each knob at the ends of its range, all else nominal):",
            f"nominal: J PI {p[0]:.2f}, J PI+NFC {p[1]:.2f}, reduction {p[2]:.1f} %",
            f"{'knob':<22} {'range':>22} {'J PI':>14} {'J PI+NFC':>14} {'reduction %':>16}  verdict",
        ]
        for r in res.oat:
            fail = f" ({r.failed} runs failed)" if r.failed else ""
            lines.append(
                f"{r.knob:<22} {f'{r.low:.4g} .. {r.high:.4g}':>22} "
                f"{r.j_pi[0]:6.1f} {r.j_pi[1]:7.1f} {r.j_nfc[0]:6.1f} {r.j_nfc[1]:7.1f} "
                f"{r.reduction[0]:7.1f} {r.reduction[1]:8.1f}  {res.oat_verdict(r)}{fail}"
            )
    return "\n".join(lines)


def plot_uncertainty(res: UncertaintyResult, path: str | Path, top: int = 12) -> Path:
    """One PNG: J per controller and the reduction over the draws with their bands, and rho."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from isp_twin.output.files import staged_path

    fig, axes = plt.subplots(1, 3, figsize=(15.0, 4.8))
    ax = axes[0]
    bins = np.linspace(
        min(res.j_pi.min(), res.j_nfc.min()), max(res.j_pi.max(), res.j_nfc.max()), 25
    )
    for x, label, color in ((res.j_pi, "PI", "C0"), (res.j_nfc, "PI+NFC", "C1")):
        b = Band.of(x)
        ax.hist(x, bins=bins, alpha=0.5, color=color, label=f"{label}: mean {b.mean:.1f} %")
        ax.axvspan(b.low, b.high, color=color, alpha=0.08)
        ax.axvline(b.mean, color=color)
    ax.set_xlabel(f"J {res.axis} [%] (Eq. 10)")
    ax.set_ylabel("draws")
    ax.set_title("J over the draws (shaded: 90 % band)")
    ax.legend(fontsize=8)
    ax = axes[1]
    b = Band.of(res.reduction)
    ax.hist(res.reduction, bins=25, color="C2", alpha=0.7)
    ax.axvspan(b.low, b.high, color="C2", alpha=0.1, label=f"90 % band {b.low:.0f}..{b.high:.0f}")
    ax.axvline(0.0, color="k", lw=0.8)
    if res.paper_reduction is not None:
        p = res.paper_reduction
        ax.axvline(p, color="C3", label=f"paper {p:.1f} %")
        ax.axvspan(p - REDUCTION_TOLERANCE, p + REDUCTION_TOLERANCE, color="C3", alpha=0.08)
    ax.set_xlabel("NFC reduction of J [%]")
    ax.set_title("Is the NFC gain robust?")
    ax.legend(fontsize=8)
    ax = axes[2]
    rows = list(res.sensitivity[:top])[::-1]
    y = np.arange(len(rows))
    for shift, key, label in ((-0.27, "rho_pi", "J PI"), (0.0, "rho_nfc", "J PI+NFC")) + (
        (0.27, "rho_reduction", "NFC reduction"),
    ):
        ax.barh(y + shift, [getattr(r, key) for r in rows], height=0.27, label=label)
    ax.set_yticks(y, [r.name + (" *" if r.significant else "") for r in rows], fontsize=7)
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlim(-1, 1)
    ax.set_xlabel("Spearman rank correlation")
    ax.set_title("What moves J (* significant)")
    ax.legend(fontsize=8)
    fig.suptitle(
        f"{res.scenario}: {res.draws - res.failed} draws of plant (Table 2 ci95) and rig settings"
    )
    fig.tight_layout()
    with staged_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    return Path(path)
