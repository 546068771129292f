"""`isp-twin diagnose DATA... --params P`: find what the model of an axis misses."""

from __future__ import annotations

import argparse
import builtins
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from isp_twin.commands.data_options import (
    add_data_options,
    check_initial_angle,
    check_sample_budget,
    mapping_from_args,
    model_from_file,
)
from isp_twin.commands.progress import working
from isp_twin.diagnosis.prepared_runs import FIXED_SIDE
from isp_twin.diagnosis.search import DEFAULT_ITERATIONS
from isp_twin.errors import ParameterError
from isp_twin.estimation.coverage import (
    beyond_training,
    breakaway_sentence,
    breakaway_table,
    reach_sentence,
    thin_sentence,
    thin_training,
    untrained_breakaways,
)
from isp_twin.estimation.verdict import CONVERGED_RATIO, json_safe
from isp_twin.identification.cost import held_out_determined, model_breakaways
from isp_twin.identification.gyro_error import fusion_json, fusion_note, one_gyro_error
from isp_twin.identification.measured import check_sample_period, load_measured, unique_names
from isp_twin.identification.side_angle import sides_as_read
from isp_twin.model.parameters import AxisParams, load_parameters, save_parameters
from isp_twin.output.files import check_outputs, is_stdout, transaction, write_text_atomic
from isp_twin.units import DEG
from isp_twin.vocabulary import GIMBAL_AXES

__all__ = ["add_parser", "execute"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "diagnose",
        help="find an effect the model misses in measured open-loop data (residual analysis)",
        description=(
            "Simulate the model of one axis on measured open-loop runs, analyse the residual "
            "(whiteness, input correlation, spectrum, noise floor), refit the model with each "
            "candidate effect of the library, compare on held-out data (--holdout, or "
            "leave-one-run-out cross-validation), accept the best only if significant, and "
            "look again. DATA: canonical CSV (t [s], u, omega [deg/s], theta [deg]) or, with "
            "--map / --describe, other CSV or .mat files."
        ),
    )
    p.add_argument("data", nargs="+", metavar="DATA", help="training runs")
    p.add_argument("--params", required=True, type=Path, help="current parameter file (YAML)")
    p.add_argument("--holdout", nargs="+", default=[], metavar="DATA", help="held-out runs")
    p.add_argument("--out", type=Path, default=None, help="updated parameter file (YAML)")
    p.add_argument(
        "--axis", default="inner_az", choices=GIMBAL_AXES, help="the axis the data belong to"
    )
    add_data_options(p)
    _add_search_options(p)
    _add_output_options(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the base model's global search")
    p.add_argument(
        "--base-search",
        action="store_true",
        help="fit the base model with identify's global method first (and the winner again "
        "with its effect held) instead of starting from the file's rate parameters",
    )
    p.add_argument("--quiet", action="store_true", help="print only the verdict line")
    p.set_defaults(execute=execute)


def _add_search_options(p: argparse.ArgumentParser) -> None:
    """Which effects are tried, on which half-plane, how many, how hard."""
    p.add_argument(
        "--candidates",
        default=None,
        metavar="A,B,...",
        help="comma-separated effects to test (default: the whole library)",
    )
    p.add_argument(
        "--side",
        default=None,
        choices=tuple(FIXED_SIDE),
        help="half-plane of the regimes: measured (the angle fused with the integrated rate, "
        "as identify; the raw angle if that fits the starting model better), raw (the angle "
        "as measured), or right/left (fixed: a freely spinning motor); default: the parameter "
        "file's fitted_with.side_source, else measured",
    )
    p.add_argument("--max-rounds", type=int, default=2, help="at most this many effects are added")
    p.add_argument(
        "--iterations",
        type=int,
        default=DEFAULT_ITERATIONS,
        help="Levenberg-Marquardt iterations per refit",
    )


def _add_output_options(p: argparse.ArgumentParser) -> None:
    """The JSON result, the report folder and the residual recording."""
    p.add_argument(
        "--json", type=Path, default=None, metavar="PATH", help="write the result as JSON"
    )
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        metavar="DIR",
        help="report folder (default: beside --out, else diagnosis_report/)",
    )
    p.add_argument(
        "--recording",
        type=Path,
        default=None,
        metavar="PATH",
        help="Rerun recording of the residuals (default: REPORT_DIR/residuals.rrd)",
    )
    p.add_argument("--no-recording", action="store_true", help="do not write a Rerun recording")


def execute(args: argparse.Namespace) -> int:
    from isp_twin.diagnosis.search import diagnose

    if args.max_rounds < 1:
        raise ParameterError(f"--max-rounds must be >= 1, got {args.max_rounds}")
    if args.iterations < 1:
        raise ParameterError(f"--iterations must be >= 1, got {args.iterations}")
    check_initial_angle(args)
    report_path, recording = _checked_outputs(args)
    params = load_parameters(args.params)
    runs = _load_runs(args, params)
    train, holdout = runs[: len(args.data)], runs[len(args.data) :]
    axis_in = params.axis(args.axis)
    where = f"{params.path or params.name}: axes.{args.axis}"
    integration, timing, override = model_from_file(args, axis_in, where)
    side, side_override = _side_from_file(args, axis_in, where)
    for line in (override, side_override):
        if line is not None and not args.quiet:
            print(line)
    candidates = None
    if args.candidates:
        candidates = [c.strip() for c in args.candidates.split(",") if c.strip()]
    with working(f"diagnose {args.axis} on {len(train)} run(s)"):
        diag = diagnose(
            train,
            params,
            args.axis,
            holdout=holdout,
            candidates=candidates,
            max_rounds=args.max_rounds,
            max_iter=args.iterations,
            side_source=side,
            seed=args.seed,
            base_search=args.base_search,
            integration=integration,
            timing=timing,
        )
    result = diag.to_json()
    result.update(_model_source(args, axis_in, override))
    if side_override is not None:
        result["side_override"] = side_override
    result["sample_period_s"] = {d.name: d.dt for d in runs}
    result.update(fusion_json(runs))
    result.setdefault("units", {})["sample_period_s"] = "s"
    _with_coverage(
        result, sides_as_read(train, side), sides_as_read(holdout, side), diag.noise_floor
    )
    _with_breakaways(result, diag, args.axis, side, train, holdout)
    say = _teller(args.quiet)
    _print_diagnosis(diag, result, args.axis, len(train), say)
    _write_outputs(args, diag, axis_in, result, report_path, recording, say)
    return 0


def _with_coverage(result: dict, train, holdout, noise_floor: float) -> None:
    """The regimes where the held-out runs go faster than the training runs
    (`beyond_training`) or move far more often (`thin_training`) into
    `result`, and into its verdict where the model is not at the noise."""
    beyond = beyond_training(train, holdout, noise_floor)
    thin = thin_training(train, holdout, noise_floor)
    result["held_out_beyond_training"] = [b.to_json() for b in beyond]
    result["held_out_thin_in_training"] = [t.to_json() for t in thin]
    said = (reach_sentence(beyond) + thin_sentence(thin)).strip()
    if said and not result["converged"]:
        result["verdict"] += ". " + said


def _with_breakaways(result: dict, diag, axis: str, side: str, train, holdout) -> None:
    """The final model's breakaways from rest per regime on the training runs
    and its rests on the held-out runs (`model_breakaways`) into `result`,
    and the regimes held-out rests push against where the training runs
    never break away (`untrained_breakaways`), with each held-out run's
    error before the model first rests there (`held_out_determined`), into
    its verdict where the model fits the training runs within the limit and
    the held-out runs not."""
    ax = diag.params_out.axis(axis)
    model = {"effects": tuple(ax.effects), "timing": diag.timing, "integration": diag.integration}
    counts = model_breakaways(ax.rate_params(), train, holdout, side, **model)
    untrained = untrained_breakaways(*counts)
    determined = held_out_determined(ax.rate_params(), holdout, untrained, side, **model)
    result["breakaways"] = breakaway_table(*counts)
    result["held_out_breakaways_untrained"] = [b.to_json() for b in untrained]
    parts = [json_safe(p.to_json(diag.noise_floor)) for p in determined]
    result["held_out_before_untrained_rest"] = parts
    said = breakaway_sentence(untrained) + "".join(p.sentence(diag.noise_floor) for p in determined)
    residual = diag.stack.flat(np.asarray(diag.residual_after))
    trained = np.sqrt(np.mean(residual**2)) <= CONVERGED_RATIO * diag.noise_floor
    if said.strip() and trained and not result["converged"]:
        result["verdict"] += ". " + said.strip()


def _side_from_file(
    args: argparse.Namespace, axis_in: AxisParams, where: str
) -> tuple[str, str | None]:
    """The side source to diagnose with: ``--side``, else the one the file's
    rate parameters were fitted with (``fitted_with.side_source``), else
    ``measured``; and a line stating an override of the file (None if none).

    Raises:
        ParameterError: the file's side source is one diagnose does not read
            (``wrap``) and ``--side`` does not choose another.
    """
    record = axis_in.fitted_with
    if args.side is not None:
        if record is None or record.side_source == args.side:
            return args.side, None
        return args.side, (
            f"--side {args.side} overrides {where}.fitted_with.side_source "
            f"{record.side_source}: the parameters were fitted on another half-plane"
        )
    if record is None:
        return "measured", None
    if record.side_source not in FIXED_SIDE:
        raise ParameterError(
            f"{where}.fitted_with.side_source: {record.side_source!r} is not a half-plane "
            f"diagnose reads ({', '.join(FIXED_SIDE)}); choose one with --side"
        )
    return record.side_source, None


def _model_source(args: argparse.Namespace, axis_in: AxisParams, override: str | None) -> dict:
    """Where the fitted model (sub-steps, read-out) came from, for the JSON."""
    if override is not None:
        source = "--substeps / --split-sides (overrides the parameter file's fitted_with)"
    elif axis_in.fitted_with is not None:
        source = "parameter file (fitted_with)"
    elif args.substeps is not None or args.split_sides is not None:
        source = "--substeps / --split-sides (the parameter file has no fitted_with block)"
    else:
        source = "defaults (the parameter file has no fitted_with block)"
    out = {"model_source": source}
    if override is not None:
        out["model_override"] = override
    return out


def _teller(quiet: bool):
    """`print` unless --quiet: it silences the chatter, not the verdict."""

    def say(*a, **k):
        if not quiet:
            builtins.print(*a, **k)

    return say


def _checked_outputs(args: argparse.Namespace) -> tuple[Path, Path | None]:
    """The report's and the recording's paths, every destination checked up front."""
    report_dir = Path(
        args.report or (args.out.parent if args.out is not None else Path("diagnosis_report"))
    )
    prefix = f"{args.out.stem}_" if args.out is not None else ""
    report_path = report_dir / f"{prefix}diagnosis.md"
    recording = None
    if not args.no_recording:
        recording = args.recording or report_dir / f"{prefix}residuals.rrd"
    inputs = [*args.data, *args.holdout, args.params, *([args.describe] if args.describe else [])]
    check_outputs(
        {
            "--out": args.out,
            "--report": report_path,
            "--recording": recording,
            "--json": args.json,
        },
        inputs,
    )
    return report_path, recording


def _load_runs(args: argparse.Namespace, params):
    """The training then held-out runs, names unique, sample periods checked."""
    mapping = mapping_from_args(args)
    runs = one_gyro_error(
        unique_names([load_measured(p, mapping) for p in [*args.data, *args.holdout]])
    )
    check_sample_budget(runs, args)
    periods = check_sample_period(runs, params.sample_time_s, str(params.path or params.name))
    for line in [*periods, *fusion_note(runs)]:
        print(line)
    return runs


def _print_diagnosis(diag, result: dict, axis: str, n_train: int, say) -> None:
    """Each round's candidates and verdicts, the accepted fits, the errors, the verdict."""
    side = diag.side_angle
    half_plane = f"from the {side} angle" if side in ("fused", "resolver") else f"fixed: {side}"
    say(
        f"diagnosis of {axis} on {n_train} run(s); held out: {', '.join(diag.holdout_names)}; "
        f"half-plane {half_plane}"
    )
    for i, r in enumerate(diag.rounds, 1):
        say(
            f"round {i}: {'no missing effect found' if r.selected == 'none' else 'selected ' + r.selected}"
        )
        say(f"  {'candidate':<14} {'held-out RMS':>13} {'z':>7} {'dBIC':>10}  verdict")
        for v in r.verdicts:
            say(
                f"  {v.name:<14} {v.holdout_rmse / DEG:>9.4g} deg/s {v.improvement_z:>7.2f} "
                f"{v.delta_bic:>10.1f}  {'ACCEPT ' if v.significant else ''}{v.reason}"
            )
    for fit in diag.accepted:
        say(f"{fit.name}:")
        for k, v in fit.params.items():
            say(f"  {k} = {v:.6g} {_interval(fit, k)}")
    say(
        f"held-out RMS error: before {diag.rmse_before / DEG:.4g} deg/s, after {diag.rmse_after / DEG:.4g} deg/s, "
        f"noise floor {diag.noise_floor / DEG:.4g} deg/s"
    )
    _set_aside_lines(diag, say)
    builtins.print(result["verdict"])
    if diag.selected_effect == "none":
        say(_none_found(diag))
        off = diag.implied_torque_offset
        if off is not None and off.consistent and abs(off.value_rad_s2) > off.ci95:
            say(
                f"equivalent: a constant torque of {off.value_rad_s2:.4g} ± {off.ci95:.2g} rad/s^2 "
                "(torque / J) is what the per-direction friction levels imply, the same on "
                "both sides (the data cannot tell it from asymmetric friction)"
            )
        if result["refit_adopted"]:
            say(
                "(the parameters re-identified without a new effect fit significantly better: "
                "they are the ones written)"
            )


def _set_aside_lines(diag, say) -> None:
    """What the answer leaves out: tentative effects, a sub-sample delay read
    as the gyro's averaging, effects the data cannot tell apart."""
    t = diag.tentative_fit
    if t is not None:
        say(
            f"tentative (not adopted): {', '.join(t.effects)} passed the acceptance rule "
            f"but left the held-out error at {t.held_out_over_noise:.2f} x the noise floor "
            f"(training runs {t.training_over_noise:.2f}; without an effect "
            f"{t.without_over_noise:.2f} held out)"
        )
    if diag.delay_as_read_out is not None:
        say(
            f"set aside: an input delay of {diag.delay_as_read_out * 1e3:.3g} ms (under one "
            "sample) found with the gyro read at the sample instant; read as its average over "
            "the sample, the model without an effect fits the held-out runs at the noise and "
            "as well (the gyro's averaging, not a delay)"
        )
    if diag.equivalent:
        say(
            f"ambiguous: the data cannot tell {diag.selected_effect} apart from "
            f"{', '.join(diag.equivalent)} (alike over the travelled angles, equally good held out)"
        )


def _none_found(diag) -> str:
    """The answer `none` in words (`Diagnosis.none_words`), for the text."""
    what, why = diag.none_words()
    return what if why is None else f"{what} ({why})"


def _write_outputs(
    args, diag, axis_in: AxisParams, result: dict, report_path: Path, recording, say
) -> None:
    """Parameters, report, recording and JSON as one transaction; then where they went."""
    from isp_twin.diagnosis.report import write_recording, write_report

    with transaction():
        if args.out is not None:
            out_set = replace(diag.params_out, name=args.out.stem, path=None)
            save_parameters(out_set, args.out)
        write_report(diag, report_path, args.out)
        if recording is not None:
            write_recording(diag, recording)
        if args.json is not None:
            text = json.dumps(result, indent=2, default=_json_default, allow_nan=False) + "\n"
            write_text_atomic(args.json, text)
    if args.out is not None:
        say(f"parameters written to {args.out}")
    say(f"report written to {report_path}")
    if recording is not None:
        say(f"recording written to {recording}  (open it with: rerun {recording})")
    if args.json is not None and not is_stdout(args.json):
        say(f"result written to {args.json}")


def _json_default(x):
    try:
        return float(x)
    except (TypeError, ValueError):
        return str(x)


def _interval(fit, name: str) -> str:
    """A parameter's ± 95 % half-width, or that the held-out run placed it."""
    if name in fit.placed:
        return "(placed by the held-out run: the training runs do not tell it)"
    return f"± {fit.ci95[name]:.3g}"
