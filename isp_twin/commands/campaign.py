"""`isp-twin campaign SCENARIO`: repeat a scenario over seeds, PI vs PI+NFC (Tables 5, 6)."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from isp_twin.commands.progress import working
from isp_twin.errors import ScenarioError
from isp_twin.output.files import check_outputs, is_stdout, transaction, write_text_atomic
from isp_twin.vocabulary import INNER_AXES

__all__ = ["add_parser", "execute", "STATS_UNITS"]

#: Units of a campaign's statistics in JSON (Tables 5, 6).
STATS_UNITS = {
    "runs": "% (J of Eq. 10, one per seed)",
    "average": "%",
    "best": "%",
    "worst": "%",
    "range": "percentage points",
    "variance": "1 (sample variance of J as a fraction, J/100; the paper's square error)",
    "max_abs_error_deg_s": "deg/s",
    "rms_error_deg_s": "deg/s",
    "mean_max_abs_error_deg_s": "deg/s",
    "mean_rms_error_deg_s": "deg/s",
    "relative_reduction_percent": "% of the PI average",
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "campaign",
        help="run a scenario N times with different noise seeds, PI and PI+NFC side by side",
        description=(
            "Repeat a closed-loop scenario with seeds seed, seed+1, ... once with PI only "
            "(Kp 3.568, Ki 0.0714) and once with PI+NFC (Kp 3.0, Ki 0.15, Eq. 11-14), and "
            "print the statistics of Tables 5 and 6: each run's J, average, best, worst, "
            "range and variance."
        ),
    )
    p.add_argument("scenario", help="scenario file or shipped scenario name")
    p.add_argument("-n", "--runs", type=int, default=10, help="runs per controller (paper: 10)")
    p.add_argument("--seed", type=int, default=None, help="first seed (default: the scenario's)")
    p.add_argument(
        "--axis",
        choices=INNER_AXES,
        default="inner_az",
        help="inner axis the statistics are taken on",
    )
    p.add_argument("--params", type=Path, default=None, help="parameter file")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes")
    p.add_argument(
        "--json", type=Path, default=None, metavar="PATH", help="also write the statistics as JSON"
    )
    u = p.add_argument_group(
        "uncertainty and sensitivity (docs/uncertainty.md)",
        "With --uncertainty N, draw N plants from the parameter file's ci95 and the rig's "
        "unstated settings from their plausible ranges, run each with PI and PI+NFC, and "
        "report J as a mean with a 90 %% band, a sensitivity table and a PNG (-n is not used).",
    )
    u.add_argument("--uncertainty", type=int, default=None, metavar="N", help="number of draws")
    u.add_argument(
        "--uncertainty-seed", type=int, default=0, metavar="S", help="seed of the draws (default 0)"
    )
    u.add_argument(
        "--oat",
        action="store_true",
        help="also each setting alone at the ends of its range (does the NFC gain survive?)",
    )
    u.add_argument(
        "--oat-seeds", type=int, default=2, metavar="K", help="noise seeds per one-at-a-time point"
    )
    u.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="PNG",
        help="the plot (default: sweeps/<scenario>_uncertainty.png)",
    )
    u.add_argument("--no-plot", action="store_true", help="write no PNG")
    p.set_defaults(execute=execute)


def execute(args: argparse.Namespace) -> int:
    from isp_twin.experiments.campaign import run_campaign
    from isp_twin.experiments.scenario import load_scenario
    from isp_twin.model.parameters import load_parameters

    if args.runs < 1:
        raise ScenarioError(f"--runs must be >= 1, got {args.runs}")
    if args.seed is not None and args.seed < 0:
        raise ScenarioError(f"--seed must be >= 0, got {args.seed}")
    scenario = load_scenario(args.scenario)
    if scenario.kind != "closed_loop":
        raise ScenarioError(f"{scenario.source}: kind: a campaign needs a closed_loop scenario")
    if args.uncertainty is not None:
        return _uncertainty(args, scenario)
    inputs = [scenario.source, *([args.params] if args.params is not None else [])]
    check_outputs({"--json": args.json}, inputs)
    params = load_parameters(args.params) if args.params is not None else None
    print(f"campaign {scenario.name}: {args.runs} runs x (PI, PI+NFC), axis {args.axis}")
    with working(f"campaign {scenario.name}, {2 * args.runs} runs"):
        result = run_campaign(scenario, args.runs, args.seed, params, args.axis, max(1, args.jobs))
    print(f"seeds {result.seeds[0]}..{result.seeds[-1]}  parameters {result.parameters_file}\n")
    print(
        f"{'controller':<8} {'average':>8} {'best':>7} {'worst':>7} {'range':>6} "
        f"{'variance':>10} {'max|w1|':>8} {'rms w1':>7}   runs J [%]"
    )
    for label, v in result.variants.items():
        s = v.stats
        d = v.as_dict()
        runs = " ".join(f"{x:.2f}" for x in s.runs)
        print(
            f"{label:<8} {s.average:8.2f} {s.best:7.2f} {s.worst:7.2f} {s.range:6.2f} "
            f"{s.variance:10.3e} {d['mean_max_abs_error_deg_s']:8.4f} "
            f"{d['mean_rms_error_deg_s']:7.4f}   {runs}"
        )
    print(
        f"\nNFC reduces the average J by {result.relative_reduction_percent:.1f} % "
        "(paper: 36.9 % tracking, 41.8 % isolation)"
    )
    if args.json is not None:
        payload = {**result.as_json(), "units": STATS_UNITS}
        with transaction():
            write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n")
        if not is_stdout(args.json):
            print(f"statistics written to {args.json}")
    return 0


def _uncertainty(args: argparse.Namespace, scenario) -> int:
    from isp_twin.experiments.uncertainty import (
        format_uncertainty,
        plot_uncertainty,
        run_uncertainty,
    )

    if args.uncertainty < 2:
        raise ScenarioError(f"--uncertainty must be >= 2 draws, got {args.uncertainty}")
    if args.uncertainty_seed < 0:
        raise ScenarioError(f"--uncertainty-seed must be >= 0, got {args.uncertainty_seed}")
    if args.oat_seeds < 1:
        raise ScenarioError(f"--oat-seeds must be >= 1, got {args.oat_seeds}")
    plot = (
        None if args.no_plot else args.plot or Path("sweeps") / f"{scenario.name}_uncertainty.png"
    )
    inputs = [scenario.source, *([args.params] if args.params is not None else [])]
    check_outputs({"--json": args.json, "--plot": plot}, inputs)
    if args.params is not None:
        from isp_twin.model.parameters import load_parameters

        load_parameters(args.params)  # a bad file stops before any output
    n_runs = 2 * args.uncertainty
    print(
        f"campaign {scenario.name}: uncertainty, {args.uncertainty} draws x (PI, PI+NFC)"
        f"{', plus one-at-a-time' if args.oat else ''}, axis {args.axis}"
    )
    with working(f"uncertainty {scenario.name}, {n_runs}{'+' if args.oat else ''} runs"):
        result = run_uncertainty(
            scenario,
            args.uncertainty,
            seed=args.uncertainty_seed,
            params_path=args.params,
            axis=args.axis,
            jobs=max(1, args.jobs),
            oat=args.oat,
            oat_seeds=args.oat_seeds,
            first_seed=args.seed,
        )
    print(format_uncertainty(result))
    with transaction():
        if plot is not None:
            plot_uncertainty(result, plot)
        if args.json is not None:
            payload = {
                **result.as_json(),
                "units": {"J": "% (Eq. 10)", "reduction": "% of J PI, per draw", "rho": "1"},
            }
            write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n")
    if plot is not None:
        print(f"\nplot written to {plot}")
    if args.json is not None and not is_stdout(args.json):
        print(f"statistics written to {args.json}")
    return 0
