"""Campaigns: a scenario repeated with different noise seeds, PI vs PI+NFC (Tables 5, 6).

The paper-vs-twin comparison of every cell lives in `isp_twin.experiments.calibration`.

The paper repeats each experiment ten times; here run i uses seed
``first_seed + i`` (the gyro noise differs, nothing else), once with NFC off
(PI gains `pi`) and once with NFC on (gains `pi_nfc`), and the statistics of
`isp_twin.experiments.metrics.campaign_stats` are taken over the runs' J. A campaign is a
small sweep (seeds x {PI, PI+NFC}) run by `isp_twin.experiments.sweep.execute`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from isp_twin.errors import ScenarioError, SimulationDiverged
from isp_twin.experiments.metrics import CampaignStats, campaign_stats
from isp_twin.experiments.paper import (
    TABLE4_AMPLITUDES_DEG_S,
    TABLE4_FREQS_HZ,
    relative_reduction,
)
from isp_twin.experiments.scenario import Scenario, scenario_to_raw
from isp_twin.experiments.sweep.design import RunSpec, make_run
from isp_twin.experiments.sweep.execute import execute
from isp_twin.experiments.sweep.store import ResultStore, RunOutcome
from isp_twin.model.parameters import ParameterSet

__all__ = [
    "VARIANTS",
    "VariantResult",
    "CampaignResult",
    "campaign_runs",
    "run_all",
    "run_campaign",
    "TABLE4_SCENARIOS",
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
