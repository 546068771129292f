"""Campaigns: a scenario repeated with different noise seeds, PI vs PI+NFC (Tables 5, 6),
and the paper-vs-twin comparison of Tables 4-6.

The paper repeats each experiment ten times; here run i uses seed
``first_seed + i`` (the gyro noise differs, nothing else), once with NFC off
(PI gains `pi`) and once with NFC on (gains `pi_nfc`), and the statistics of
`isp_twin.metrics.campaign_stats` are taken over the runs' J. A campaign is a
small sweep (seeds x {PI, PI+NFC}) run by `isp_twin.sweep.execute`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from isp_twin.errors import ScenarioError, SimulationDiverged
from isp_twin.metrics import CampaignStats, campaign_stats
from isp_twin.paper import (
    TABLE4_ACTUAL,
    TABLE4_AMPLITUDES_DEG_S,
    TABLE4_FREQS_HZ,
    TABLE4_MODEL,
    TABLE5,
    TABLE6,
    relative_reduction,
)
from isp_twin.parameters import ParameterSet
from isp_twin.scenario import Scenario, load_scenario, scenario_to_raw
from isp_twin.sweep.design import RunSpec, make_run
from isp_twin.sweep.execute import execute
from isp_twin.sweep.store import ResultStore, RunOutcome

__all__ = [
    "VARIANTS",
    "VariantResult",
    "CampaignResult",
    "campaign_runs",
    "run_all",
    "run_campaign",
    "TABLE4_SCENARIOS",
    "Comparison",
    "compare_with_paper",
    "comparison_markdown",
]

#: The two controllers compared: label -> NFC on?
VARIANTS: dict[str, bool] = {"PI": False, "PI+NFC": True}


@dataclass(frozen=True)
class VariantResult:
    """One controller over all seeds.

    Attributes:
        stats: statistics of J [%].
        max_abs_error_deg_s: per run, max |omega_1| [deg/s].
        rms_error_deg_s: per run, RMS of omega_1 [deg/s].
    """

    stats: CampaignStats
    max_abs_error_deg_s: tuple[float, ...]
    rms_error_deg_s: tuple[float, ...]

    def as_dict(self) -> dict:
        out = self.stats.as_dict()
        out["max_abs_error_deg_s"] = list(self.max_abs_error_deg_s)
        out["rms_error_deg_s"] = list(self.rms_error_deg_s)
        out["mean_max_abs_error_deg_s"] = _mean(self.max_abs_error_deg_s)
        out["mean_rms_error_deg_s"] = _mean(self.rms_error_deg_s)
        return out


@dataclass(frozen=True)
class CampaignResult:
    """A campaign: PI and PI+NFC over the same seeds.

    Attributes:
        scenario: scenario name.
        parameters_file: the parameter file used.
        axis: the inner axis the statistics are about.
        seeds: the seeds, one per run.
        variants: "PI" / "PI+NFC" -> `VariantResult`.
    """

    scenario: str
    parameters_file: str
    axis: str
    seeds: tuple[int, ...]
    variants: dict[str, VariantResult]

    @property
    def relative_reduction_percent(self) -> float:
        """Improvement of the average J by NFC, in percent of the PI average."""
        return relative_reduction(
            self.variants["PI"].stats.average, self.variants["PI+NFC"].stats.average
        )

    def as_json(self) -> dict:
        """The JSON document of `isp-twin campaign --json`."""
        return {
            "scenario": self.scenario,
            "parameters_file": self.parameters_file,
            "seed": self.seeds[0],
            "seeds": list(self.seeds),
            "metrics": {
                self.axis: {
                    **{label: v.as_dict() for label, v in self.variants.items()},
                    "relative_reduction_percent": self.relative_reduction_percent,
                }
            },
        }


def _mean(x: Sequence[float]) -> float:
    return float(sum(x) / len(x))


def campaign_runs(
    scenario: Scenario,
    seeds: Sequence[int],
    params: ParameterSet | None = None,
    axis: str = "inner_az",
) -> list[RunSpec]:
    """The campaign as a sweep design: seeds x {PI, PI+NFC}, in `VARIANTS` order."""
    if params is not None and params.path is None:
        raise ValueError("a campaign runs on workers: its parameter set must come from a file")
    params_path = Path(params.path if params is not None else scenario.parameters_path).resolve()
    runs = []
    for label, nfc in VARIANTS.items():
        raw = scenario_to_raw(scenario.with_nfc(nfc))
        for seed in seeds:
            runs.append(
                make_run(len(runs), raw, scenario.source, params_path, seed, {"label": label}, axis)
            )
    return runs


def run_all(runs: Sequence[RunSpec], jobs: int = 1, client=None) -> dict[str, RunOutcome]:
    """Run a design without a store file (an in-memory one), by key.

    Args:
        runs: the design.
        jobs: 1 runs here; more starts a local Dask cluster of at most that
            many workers, bounded by the runs and the cores.
        client: a Dask client to use instead (overrides `jobs`).

    Raises:
        SimulationDiverged: a run failed (its one-line reason).
    """
    with ResultStore(":memory:") as store:
        execute(runs, store, workers=jobs, in_process=jobs <= 1 and client is None, client=client)
        outcomes = store.outcomes([r.key for r in runs])
    for r in runs:
        if outcomes[r.key].status != "ok":
            raise SimulationDiverged(outcomes[r.key].error or "a campaign run failed")
    return outcomes


def _j(scenario: Scenario, outcome: RunOutcome, axis: str) -> tuple[float, float, float]:
    m = outcome.metrics.get(axis)
    if m is None:
        raise ScenarioError(
            f"{scenario.source or scenario.name}: turntable: {axis} sees no carrier motion, "
            "so its isolation J (Eq. 10) is undefined; choose the other axis"
        )
    return m["isolation_percent"], m["max_abs_error_deg_s"], m["rms_error_deg_s"]


def run_campaign(
    scenario: Scenario,
    n_runs: int = 10,
    first_seed: int | None = None,
    params: ParameterSet | None = None,
    axis: str = "inner_az",
    jobs: int = 1,
    on_run: Callable[[str, int, float], None] | None = None,
    client=None,
) -> CampaignResult:
    """Run `scenario` n_runs times with PI and with PI+NFC (a sweep of seeds x controllers).

    Args:
        scenario: a closed-loop scenario (its own NFC switch is overridden).
        n_runs: runs per controller (paper: 10).
        first_seed: seed of the first run (default: the scenario's).
        params: parameter set, loaded from a file (default: the scenario's file).
        axis: inner axis the statistics are taken on.
        jobs: worker processes (1: in this process; bounded by runs and cores).
        on_run: called with (variant, seed, J) after the runs, in design order.
        client: a Dask client to run on (overrides `jobs`).
    """
    if n_runs < 1:
        raise ValueError(f"a campaign needs n_runs >= 1, got {n_runs}")
    first = scenario.seed if first_seed is None else first_seed
    seeds = tuple(range(first, first + n_runs))
    runs = campaign_runs(scenario, seeds, params, axis)
    outcomes = run_all(runs, jobs, client)
    results = [_j(scenario, outcomes[r.key], axis) for r in runs]
    labels = [r.knobs["label"] for r in runs]
    if on_run is not None:
        for label, r, res in zip(labels, runs, results):
            on_run(label, r.seed, res[0])
    variants = {}
    for label in VARIANTS:
        rows = [res for lab, res in zip(labels, results) if lab == label]
        variants[label] = VariantResult(
            stats=campaign_stats([r[0] for r in rows]),
            max_abs_error_deg_s=tuple(r[1] for r in rows),
            rms_error_deg_s=tuple(r[2] for r in rows),
        )
    params_file = (
        str(params.path) if params is not None and params.path else str(scenario.parameters_path)
    )
    return CampaignResult(
        scenario=scenario.name,
        parameters_file=params_file,
        axis=axis,
        seeds=seeds,
        variants=variants,
    )


# ---------------------------------------------------------------- paper vs twin

#: The shipped scenario of each Table 4 cell, keyed (freq_hz, amplitude_deg_s).
TABLE4_SCENARIOS: dict[tuple[float, float], str] = {
    (f, a): f"table4_{'1_6Hz' if f < 0.3 else '0_5Hz'}_{tag}"
    for f in TABLE4_FREQS_HZ
    for a, tag in zip(TABLE4_AMPLITUDES_DEG_S, ("half_pi", "pi", "2pi"))
}


@dataclass(frozen=True)
class Comparison:
    """The twin's Table 4-6 numbers.

    Attributes:
        table4: (freq_hz, amplitude_deg_s) -> statistics of J [%] over the seeds (PI).
        table5: the tracking campaign (tracking_0_5Hz).
        table6: the isolation campaign (turbulence_1_6Hz).
        n_runs: runs per cell / controller.
    """

    table4: dict[tuple[float, float], CampaignStats]
    table5: CampaignResult
    table6: CampaignResult
    n_runs: int


def compare_with_paper(n_runs: int = 10, jobs: int = 1, first_seed: int = 1) -> Comparison:
    """Run the Table 4 grid (PI) and the Table 5 / 6 campaigns on the twin."""
    seeds = list(range(first_seed, first_seed + n_runs))
    table4_runs = {}
    for cell, name in TABLE4_SCENARIOS.items():
        scenario = load_scenario(name)
        table4_runs[cell] = (scenario, campaign_runs(scenario, seeds)[:n_runs])  # PI only
    t5_scenario, t6_scenario = load_scenario("tracking_0_5Hz"), load_scenario("turbulence_1_6Hz")
    client = cluster = None
    if jobs > 1:
        from isp_twin.sweep.execute import local_client, worker_count

        client, cluster = local_client(worker_count(jobs, (len(TABLE4_SCENARIOS) + 4) * n_runs))
    try:
        everything = [r for _, runs in table4_runs.values() for r in runs]
        outcomes = run_all(everything, jobs, client)
        table4 = {
            cell: campaign_stats([_j(s, outcomes[r.key], "inner_az")[0] for r in runs])
            for cell, (s, runs) in table4_runs.items()
        }
        t5 = run_campaign(t5_scenario, n_runs, first_seed, jobs=jobs, client=client)
        t6 = run_campaign(t6_scenario, n_runs, first_seed, jobs=jobs, client=client)
    finally:
        if client is not None:
            client.close()
            cluster.close()
    return Comparison(table4=table4, table5=t5, table6=t6, n_runs=n_runs)


def _verdict(ok: bool) -> str:
    return "met" if ok else "**NOT met**"


def comparison_markdown(c: Comparison) -> str:
    """The paper-vs-twin report (docs/paper_vs_twin.md)."""
    out = [
        "# Paper vs twin: Tables 4-6",
        "",
        "Produced by `isp-twin report` (or `python benchmarks/paper_tables.py`); "
        f"{c.n_runs} seeds per cell and controller. J is Eq. 10 over the steady-state "
        "window (the first period discarded), inner azimuth axis. Calibration: "
        "docs/calibration.md (fitted on the 1/6 Hz, pi deg/s cell of Table 4 only).",
        "",
        "## Table 4: J [%] of the PI-controlled system",
        "",
        "| f [Hz] | amplitude [deg/s] | paper actual | paper model | twin mean | twin min-max "
        "| twin - actual | role | target |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for (f, a), stats in c.table4.items():
        actual, model = TABLE4_ACTUAL[(f, a)], TABLE4_MODEL[(f, a)]
        diff = stats.average - actual
        fname = "1/6" if f < 0.3 else "0.5"
        aname = {math.pi / 2: "pi/2", math.pi: "pi", 2 * math.pi: "2 pi"}[a]
        if f < 0.3:
            role = "calibration" if a == math.pi else "calibration data (not fitted)"
            target = "fit" if a == math.pi else "none (reported)"
        else:
            role = "validation"
            target = f"within +-3 points: {_verdict(abs(diff) <= 3.0)}"
        out.append(
            f"| {fname} | {aname} | {actual:.2f} | {model:.2f} | {stats.average:.2f} | "
            f"{stats.best:.2f}-{stats.worst:.2f} | {diff:+.2f} | {role} | {target} |"
        )
    trends = []
    for f in TABLE4_FREQS_HZ:
        row = [c.table4[(f, a)].average for a in TABLE4_AMPLITUDES_DEG_S]
        trends.append(row[0] > row[1] > row[2])
    out += [
        "",
        'Trend "smaller amplitude -> worse isolation" (J decreasing with amplitude at each '
        f"frequency): 1/6 Hz {_verdict(trends[0])}, 0.5 Hz {_verdict(trends[1])}.",
        "",
        "## Tables 5 and 6: PI vs PI+NFC",
        "",
        "| experiment | controller | paper average | twin average | twin best | twin worst "
        "| twin range | twin variance | paper variance |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, table, res in (
        ("Table 5 tracking 0.5 Hz", TABLE5, c.table5),
        ("Table 6 isolation 1/6 Hz", TABLE6, c.table6),
    ):
        for variant, avg, var in (
            ("PI", table.pi_average, table.pi_variance),
            ("PI+NFC", table.pi_nfc_average, table.pi_nfc_variance),
        ):
            s = res.variants[variant].stats
            out.append(
                f"| {label} | {variant} | {avg:.2f} | {s.average:.2f} | {s.best:.2f} | "
                f"{s.worst:.2f} | {s.range:.2f} | {s.variance:.2e} | {var:.2e} |"
            )
    out += [
        "",
        "| experiment | paper reduction of average J | twin reduction | difference | "
        "target (+-10 points) |",
        "|---|---|---|---|---|",
    ]
    for label, table, res in (
        ("Table 5 tracking", TABLE5, c.table5),
        ("Table 6 isolation", TABLE6, c.table6),
    ):
        paper = relative_reduction(table.pi_average, table.pi_nfc_average)
        twin = res.relative_reduction_percent
        out.append(
            f"| {label} | {paper:.1f} % | {twin:.1f} % | {twin - paper:+.1f} | "
            f"{_verdict(abs(twin - paper) <= 10.0)} |"
        )
    out += [
        "",
        "Tracking errors (mean over runs) [deg/s]:",
        "",
        "| experiment | controller | paper max abs | twin max abs | paper rms | twin rms |",
        "|---|---|---|---|---|---|",
    ]
    for label, table, res in (("Table 5", TABLE5, c.table5), ("Table 6", TABLE6, c.table6)):
        for variant, pmax, prms in (
            ("PI", table.pi_max_abs_error_deg_s, table.pi_rms_error_deg_s),
            ("PI+NFC", table.pi_nfc_max_abs_error_deg_s, table.pi_nfc_rms_error_deg_s),
        ):
            v = res.variants[variant]
            out.append(
                f"| {label} | {variant} | {pmax:.4f} | {_mean(v.max_abs_error_deg_s):.4f} | "
                f"{prms:.4f} | {_mean(v.rms_error_deg_s):.4f} |"
            )
    out += ["", "## Notes", ""] + _notes(c) + [""]
    return "\n".join(out)


def _notes(c: Comparison) -> list[str]:
    """Closing notes: each deviation from the paper that the numbers show, with its reason."""
    notes = []
    for (f, a), stats in c.table4.items():
        diff = stats.average - TABLE4_ACTUAL[(f, a)]
        if f < 0.3 and a != math.pi and abs(diff) > 3.0:
            notes.append(
                f"- Table 4, 1/6 Hz, {a:.3f} deg/s: the twin is {diff:+.1f} points off. With the "
                "outer followers on, the inner gimbal moves slowly relative to its outer gimbal "
                "and its peak |omega_1| comes from stick-slip at the reversals, which depends "
                "little on the amplitude, so the twin's J goes roughly as 1/amplitude where the "
                "paper's goes as 1/sqrt(amplitude). One gyro scale cannot fit all three 1/6 Hz "
                "cells; the calibration fits the pi deg/s working point (docs/calibration.md)."
            )
        if f > 0.3 and abs(diff) > 3.0:
            notes.append(
                f"- Table 4, 0.5 Hz, {a:.3f} deg/s: validation target missed by {diff:+.1f} points."
            )
    for label, table, res in (("Table 5", TABLE5, c.table5), ("Table 6", TABLE6, c.table6)):
        paper = relative_reduction(table.pi_average, table.pi_nfc_average)
        diff = res.relative_reduction_percent - paper
        if abs(diff) > 10.0:
            notes.append(
                f"- {label}: NFC changes the average J by {res.relative_reduction_percent:.1f} % "
                f"against the paper's {paper:.1f} % ({diff:+.1f} points, target +-10 missed). "
                "The twin's NFC uses the plant's own parameters (a perfect identification); the "
                "real system compensates with an identified model that is ~90 % accurate [25]."
            )
        pi_var = res.variants["PI"].stats.variance
        if pi_var < 0.1 * table.pi_variance:
            notes.append(
                f"- {label}: the runs scatter far less than the paper's (variance {pi_var:.1e} "
                f"vs {table.pi_variance:.1e}): the only random input of the twin is the gyro "
                "noise; the real runs also differ in start attitude, temperature and turntable "
                "errors, which the twin does not model."
            )
    if not notes:
        notes.append("- Every target is met.")
    return notes
