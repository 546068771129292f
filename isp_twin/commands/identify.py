"""``isp-twin identify``: Eq. 6 parameters of one axis from open-loop runs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

from isp_twin.commands.data_options import (
    add_data_options,
    check_initial_angle,
    check_sample_budget,
    integration_from_args,
    mapping_from_args,
)
from isp_twin.errors import ParameterError
from isp_twin.identification.fit import Settings, identify, to_axis_params
from isp_twin.identification.gyro_error import fusion_json, fusion_note, one_gyro_error
from isp_twin.identification.measured import check_sample_period, load_measured, unique_names
from isp_twin.identification.report import identification_verdict, result_json, write_report
from isp_twin.identification.side_angle import SIDE_SOURCES
from isp_twin.model.parameters import load_parameters, save_parameters
from isp_twin.output.files import check_outputs, transaction, write_text_atomic
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG
from isp_twin.vocabulary import GIMBAL_AXES


def add_parser(sub) -> None:
    p = sub.add_parser(
        "identify",
        help="identify the per-regime Eq. 6 parameters of one axis from open-loop data",
        description=(
            "Identify a, b·Ke, b·Ts, b·Tc, alpha of each friction regime (Eq. 6, 8) by "
            "minimizing the RMS rate error over all DATA files at once (Eq. 9): "
            "seeded differential evolution, then least squares. b is fixed to the prior. "
            "DATA: canonical CSV (t [s], u, omega [deg/s], theta [deg]) or, with --map / "
            "--describe, other CSV or .mat files."
        ),
    )
    p.add_argument("data", nargs="+", metavar="DATA", help="identification runs")
    p.add_argument(
        "--validate", nargs="+", default=[], metavar="DATA", help="validation runs (Table 3)"
    )
    p.add_argument("--out", required=True, type=Path, help="output parameter file (YAML)")
    p.add_argument(
        "--prior",
        type=Path,
        default=None,
        help="prior parameter file (default: the paper's Table 2)",
    )
    p.add_argument(
        "--axis", default="inner_az", choices=GIMBAL_AXES, help="the axis the data belong to"
    )
    add_data_options(p)
    _add_search_options(p)
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        help="Markdown report (default: OUT with suffix _report.md; PNGs beside it)",
    )
    p.add_argument("--no-report", action="store_true")
    p.add_argument("--json", type=Path, default=None, help="JSON summary")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(execute=execute)


def _add_search_options(p) -> None:
    """The half-plane source and the search budget."""
    p.add_argument(
        "--side",
        dest="side_source",
        default="measured",
        choices=SIDE_SOURCES,
        help="half-plane source: measured (angle fused with rate), raw, wrap, right, left",
    )
    p.add_argument(
        "--prior-in-search",
        action="store_true",
        help="also start the search from the prior's values (by default the prior only "
        "supplies b, the regimes the data do not visit and the effects held fixed)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--generations", type=int, default=Settings.generations)
    p.add_argument("--population", type=int, default=Settings.population)
    p.add_argument("--refine-evaluations", type=int, default=Settings.refine_evaluations)
    p.add_argument("--no-refine", action="store_true", help="skip the least-squares refinement")
    p.add_argument("--min-regime-samples", type=int, default=Settings.min_regime_samples)
    p.add_argument(
        "--rest-rate",
        type=float,
        default=Settings.rest_rate_deg_s,
        metavar="DEG_S",
        help="|rate| counted as at rest [deg/s]",
    )
    p.add_argument(
        "--regime-spread",
        type=_spread,
        default=Settings.regime_spread,
        metavar="FACTOR",
        help="factor within which the regimes' Tc, Ts-Tc and alpha are expected to "
        "agree (a weak prior for what the runs leave open, and a restart from the "
        "other regimes' values for a regime whose alpha is fitted outside it; "
        "'none': neither; "
        f"default {Settings.regime_spread:g})",
    )
    p.add_argument(
        "--jacobian-substeps",
        type=_column_substeps,
        default=Settings.jacobian_substeps,
        metavar="M",
        help="sub-steps per sample of the least squares' finite-difference columns, the slopes "
        "its steps are proposed from, where the model integrates more (every cost stays the "
        f"model's; 0: the model's own; default {Settings.jacobian_substeps})",
    )


def execute(args) -> int:
    _check_options(args)
    prior_path = args.prior or default_parameters_path()
    inputs = [*args.data, *args.validate, prior_path, *([args.describe] if args.describe else [])]
    check_outputs({"--out": args.out}, inputs)  # the report's default name derives from it
    report = None
    if not args.no_report:
        report = args.report or args.out.with_name(f"{args.out.stem}_report.md")
    check_outputs({"--out": args.out, "--report": report, "--json": args.json}, inputs)
    train, validation, prior_set, prior = _load_runs(args, prior_path)
    show = not args.quiet and sys.stderr.isatty()
    result = identify(train, prior, _settings(args), _progress_printer(show))
    if show:
        print(file=sys.stderr)
    names = ", ".join(d.name for d in train)
    axis_params = to_axis_params(
        result, prior, note=f"identified by isp-twin identify from {names}"
    )
    out_set = replace(
        prior_set.with_axis(args.axis, axis_params),
        name=args.out.stem,
        description=f"{args.axis} identified from {names} (b fixed to {prior_set.name}); "
        f"other axes from {prior_set.name}",
        path=None,
    )
    verdict = identification_verdict(result, train, validation)
    summary = result_json(result, args.axis, axis_params, validation, train, verdict)
    summary["sample_period_s"] = {d.name: d.dt for d in train + validation}
    summary.update(fusion_json(train + validation))
    summary.setdefault("units", {})["sample_period_s"] = "s"
    with transaction():
        save_parameters(out_set, args.out)
        if report is not None:
            write_report(
                report, result, args.axis, axis_params, train, validation, args.out, verdict
            )
        if args.json is not None:
            write_text_atomic(args.json, json.dumps(summary, indent=2) + "\n")
    if not args.quiet:
        visited = [r for r, ok in zip(summary["regime_identified"], result.regime_identified) if ok]
        print(f"identified {args.axis} regimes {', '.join(visited) or 'none'} -> {args.out}")
        print(f"RMS rate error (Eq. 9): {result.cost / DEG:.4g} deg/s over {len(train)} set(s)")
        for line in verdict.lines():
            print(line)
    return 0


def _check_options(args) -> None:
    """The search options' ranges and the initial angle (before any file is read).

    Raises:
        ParameterError: an option out of its range, naming it.
    """
    if args.generations < 0:
        raise ParameterError(f"--generations must be >= 0, got {args.generations}")
    for option, value in (
        ("--population", args.population),
        ("--refine-evaluations", args.refine_evaluations),
        ("--min-regime-samples", args.min_regime_samples),
    ):
        if value < 1:
            raise ParameterError(f"{option} must be >= 1, got {value}")
    if args.seed < 0:
        raise ParameterError(f"--seed must be >= 0, got {args.seed}")
    if not math.isfinite(args.rest_rate) or args.rest_rate < 0:
        raise ParameterError(f"--rest-rate must be a finite number >= 0, got {args.rest_rate}")
    check_initial_angle(args)


def _load_runs(args, prior_path: Path):
    """(training runs, validation runs, prior set, its axis), sample periods checked."""
    mapping = mapping_from_args(args)
    runs = one_gyro_error(
        unique_names([load_measured(p, mapping) for p in [*args.data, *args.validate]])
    )
    check_sample_budget(runs, args)
    train, validation = runs[: len(args.data)], runs[len(args.data) :]
    prior_set = load_parameters(prior_path)
    prior = prior_set.axis(args.axis)
    periods = check_sample_period(
        train + validation, prior_set.sample_time_s, str(prior_set.path or prior_set.name)
    ) + fusion_note(runs)
    if not args.quiet:
        for line in periods:
            print(line)
    return train, validation, prior_set, prior


def _settings(args) -> Settings:
    return Settings(
        seed=args.seed,
        generations=args.generations,
        population=args.population,
        refine=not args.no_refine,
        refine_evaluations=args.refine_evaluations,
        min_regime_samples=args.min_regime_samples,
        rest_rate_deg_s=args.rest_rate,
        side_source=args.side_source,
        prior_in_search=args.prior_in_search,
        integration=integration_from_args(args),
        regime_spread=args.regime_spread,
        jacobian_substeps=args.jacobian_substeps,
    )


def _column_substeps(text: str) -> int | None:
    """--jacobian-substeps: an integer >= 0; 0 (the model's own) as None."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got '{text}'")
    return value or None


def _spread(text: str) -> float | None:
    """--regime-spread: 'none' or a factor > 1."""
    if text.strip().lower() == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 1.0:
        raise argparse.ArgumentTypeError(f"expected a factor > 1 or 'none', got '{text}'")
    return value


def _progress_printer(show: bool):
    """The search's progress callback: one overwritten line on a terminal."""

    def progress(stage: str, step: int, cost: float) -> None:
        if show:
            label = (
                "generation {}: best RMS"
                if stage == "search"
                else "refinement, {} simulated sets: RMS"
            )
            print(
                f"\r{label.format(step)} {cost / DEG:.5g} deg/s   ",
                end="",
                file=sys.stderr,
                flush=True,
            )

    return progress
