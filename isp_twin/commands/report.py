"""`isp-twin report`: the paper-vs-twin table of Tables 4-6 (docs/paper_vs_twin.md)."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from isp_twin.atomic import write_text_atomic
from isp_twin.commands.campaign import STATS_UNITS
from isp_twin.commands.progress import working
from isp_twin.errors import ScenarioError
from isp_twin.outputs import check_outputs, transaction

__all__ = ["add_parser", "execute"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="run Tables 4-6 on the twin and print the paper-vs-twin table",
        description=(
            "Run the Table 4 grid (PI) and the Table 5 / 6 campaigns (PI vs PI+NFC) on the "
            "twin with N seeds each and print a Markdown table beside the paper's numbers, "
            "saying which targets are met."
        ),
    )
    p.add_argument("-n", "--runs", type=int, default=10, help="seeds per cell (paper: 10)")
    p.add_argument("--seed", type=int, default=1, help="first seed")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes")
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
    p.set_defaults(execute=execute)


def execute(args: argparse.Namespace) -> int:
    from isp_twin.campaign import compare_with_paper, comparison_markdown

    if args.runs < 1:
        raise ScenarioError(f"--runs must be >= 1, got {args.runs}")
    if args.seed < 0:
        raise ScenarioError(f"--seed must be >= 0, got {args.seed}")
    check_outputs({"--output": args.output, "--json": args.json})
    with working(f"report: Tables 4-6, {args.runs} seed(s) per cell"):
        comparison = compare_with_paper(args.runs, max(1, args.jobs), args.seed)
    text = comparison_markdown(comparison)
    print(text)
    with transaction():
        if args.output is not None:
            write_text_atomic(args.output, text)
        if args.json is not None:
            payload = comparison_json(comparison)
            write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n")
    if args.output is not None:
        print(f"report written to {args.output}")
    return 0


def comparison_json(c) -> dict:
    """The twin's Table 4-6 numbers with their units (`report --json`)."""
    return {
        "n_runs": c.n_runs,
        "table4": [
            {"freq_hz": f, "amplitude_deg_s": a, "PI": stats.as_dict()}
            for (f, a), stats in c.table4.items()
        ],
        "table5": c.table5.as_json(),
        "table6": c.table6.as_json(),
        "units": {"freq_hz": "Hz", "amplitude_deg_s": "deg/s", **STATS_UNITS},
    }
