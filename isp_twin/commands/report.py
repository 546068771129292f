"""`isp-twin report`: every paper cell of Tables 4-6 on the twin, labelled (docs/paper_vs_twin.md)."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from isp_twin.commands.progress import working
from isp_twin.errors import ScenarioError
from isp_twin.output.files import check_outputs, transaction, write_text_atomic

__all__ = ["add_parser", "execute", "add_common_options", "run_evaluation"]


def add_common_options(p: argparse.ArgumentParser) -> None:
    """The options `report` and `calibrate` share."""
    p.add_argument("-n", "--runs", type=int, default=10, help="seeds per cell (paper: 10)")
    p.add_argument("--seed", type=int, default=1, help="first seed")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes")
    p.add_argument(
        "--rig",
        default="paper_rig",
        metavar="RIG",
        help="rig file, or a shipped rig's name (default: paper_rig)",
    )
    p.add_argument(
        "--output",
        type=Path,
        default=None,
        metavar="PATH",
        help="also write the Markdown to PATH (e.g. docs/paper_vs_twin.md)",
    )
    p.add_argument(
        "--json", type=Path, default=None, metavar="PATH", help="also write the numbers as JSON"
    )


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="run Tables 4-6 on the twin and print the paper-vs-twin table, each cell labelled",
        description=(
            "Run every paper cell (Table 4 grid with PI, Tables 5 / 6 with PI and PI+NFC, the "
            "NFC on the identified and on the exact model) on the twin with N seeds and print "
            "a Markdown table beside the paper's numbers. Each cell is labelled from the rig "
            "file: fitted, the repeat of another cell's run, shaped by a hand-chosen setting, "
            "or validation; the targets say met or not. `isp-twin calibrate` fits first."
        ),
    )
    add_common_options(p)
    p.set_defaults(execute=execute)


def run_evaluation(args: argparse.Namespace, fit: bool, what: str) -> int:
    """Shared body of `report` and `calibrate`."""
    from isp_twin.experiments.calibration import (
        calibration_markdown,
        evaluate_cells,
        evaluation_json,
    )
    from isp_twin.experiments.rig import load_rig, resolve_rig

    if args.runs < 1:
        raise ScenarioError(f"--runs must be >= 1, got {args.runs}")
    if args.seed < 0:
        raise ScenarioError(f"--seed must be >= 0, got {args.seed}")
    rig_path = resolve_rig(args.rig)
    load_rig(rig_path)  # a bad rig stops here, before any output is checked or run
    check_outputs({"--output": args.output, "--json": args.json}, inputs=[rig_path])
    with working(f"{what}: Tables 4-6, {args.runs} seed(s) per cell"):
        evaluation = evaluate_cells(rig_path, args.runs, args.seed, max(1, args.jobs), fit=fit)
    title = "Calibration and paper vs twin" if fit else "Paper vs twin: Tables 4-6"
    text = calibration_markdown(evaluation, title)
    print(text)
    with transaction():
        if args.output is not None:
            write_text_atomic(args.output, text)
        if args.json is not None:
            payload = evaluation_json(evaluation)
            write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n")
    if args.output is not None:
        print(f"{what} written to {args.output}")
    return 0


def execute(args: argparse.Namespace) -> int:
    return run_evaluation(args, fit=False, what="report")
