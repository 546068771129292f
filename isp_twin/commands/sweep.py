"""`isp-twin sweep SWEEP.yaml`: many closed-loop runs on Dask, results in an SQLite store."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from isp_twin.errors import ScenarioError
from isp_twin.output.files import write_text_atomic

__all__ = ["add_parser", "execute"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a design sweep (grid, cases, random draws, seeds, parameter draws)",
        description=(
            "Check a sweep file whole, expand it into closed-loop runs and run them on Dask "
            "(a local cluster on all cores, or --scheduler). Each finished run goes to an "
            "SQLite store keyed by the hash of its inputs, so a re-run skips finished runs. "
            "Prints the best settings and J per knob, and writes a PNG of J per knob. "
            "The sweep file format is in docs/sweep.md."
        ),
    )
    p.add_argument("sweep", type=Path, help="sweep file (YAML)")
    p.add_argument(
        "--store",
        type=Path,
        default=None,
        help="results store (default: sweeps/<name>.sqlite)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="local worker processes (default: all cores; never more than the runs or cores)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="use a running Dask scheduler, e.g. tcp://10.0.0.5:8786, instead of a local cluster",
    )
    p.add_argument(
        "--batch",
        type=int,
        default=1,
        metavar="B",
        help="runs per Dask task (default 1); larger batches cut the per-task overhead of "
        "many short runs, a worker that dies loses its whole batch",
    )
    p.add_argument(
        "--in-process",
        action="store_true",
        help="run here, one run after the other (no Dask)",
    )
    p.add_argument(
        "--plots",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder for the J-per-knob PNGs (default: sweeps/<name>/)",
    )
    p.add_argument("--no-plots", action="store_true", help="write no PNGs")
    p.add_argument(
        "--json", type=Path, default=None, metavar="PATH", help="also write the summary as JSON"
    )
    p.add_argument("--top", type=int, default=10, help="best design points listed (default 10)")
    p.set_defaults(execute=execute)


class _ProgressPrinter:
    """A bar with ETA on a terminal, plain lines (about every 5 %) otherwise."""

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty()
        self.next_line = 0.0

    def __call__(self, p) -> None:
        eta = f"{p.eta_s:.0f} s" if p.done < p.total else "0 s"
        failed = f", {p.failed} failed" if p.failed else ""
        if self.tty:
            width = 30
            fill = int(width * p.done / p.total)
            print(
                f"\r[{'#' * fill}{'.' * (width - fill)}] {p.done}/{p.total} runs{failed}, "
                f"{p.elapsed_s:.0f} s, ETA {eta}   ",
                end="" if p.done < p.total else "\n",
                file=self.stream,
                flush=True,
            )
            return
        if p.done / p.total >= self.next_line or p.done == p.total:
            print(
                f"sweep: {p.done}/{p.total} runs done{failed}, {p.elapsed_s:.1f} s, ETA {eta}",
                file=self.stream,
                flush=True,
            )
            self.next_line = p.done / p.total + 0.05


def execute(args: argparse.Namespace) -> int:
    from isp_twin.experiments.sweep.design import load_sweep
    from isp_twin.experiments.sweep.execute import execute as run_sweep
    from isp_twin.experiments.sweep.execute import worker_count
    from isp_twin.experiments.sweep.store import ResultStore
    from isp_twin.experiments.sweep.summary import format_summary, plot_knobs, summarize

    if args.workers is not None and args.workers < 1:
        raise ScenarioError(f"--workers must be >= 1, got {args.workers}")
    if args.batch < 1:
        raise ScenarioError(f"--batch must be >= 1, got {args.batch}")
    if args.top < 1:
        raise ScenarioError(f"--top must be >= 1, got {args.top}")
    if args.in_process and args.scheduler:
        raise ScenarioError("--in-process and --scheduler exclude each other")
    sweep = load_sweep(args.sweep)  # the whole file is checked before any run
    store_path = args.store or Path("sweeps") / f"{sweep.name}.sqlite"
    with ResultStore(store_path) as store:
        pending = len({r.key for r in sweep.runs} - store.finished_keys())
        where = (
            "(nothing to run)"
            if not pending
            else "in this process"
            if args.in_process
            else f"on {args.scheduler}"
            if args.scheduler
            else f"on a local cluster of {worker_count(args.workers, pending)} workers"
        )
        print(
            f"sweep {sweep.name}: {len(sweep.runs)} runs, {len(sweep.runs) - pending} already "
            f"in {store_path}; running {pending} {where}"
        )
        start = time.perf_counter()
        done, _ = run_sweep(
            sweep.runs,
            store,
            workers=args.workers,
            scheduler=args.scheduler,
            in_process=args.in_process,
            on_progress=_ProgressPrinter(),
            name=sweep.name,
            batch=args.batch,
        )
        if done:
            elapsed = time.perf_counter() - start
            print(f"{done} runs in {elapsed:.1f} s ({elapsed / done:.3f} s per run)")
        summary = summarize(sweep, store)
    print()
    print(format_summary(summary, args.top))
    if not args.no_plots:
        out = args.plots or Path("sweeps") / sweep.name
        files = plot_knobs(summary, out)
        if files:
            print(f"\nplots of J per knob written to {out}/ ({len(files)} files)")
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(summary.as_json(), indent=2) + "\n")
        print(f"summary written to {args.json}")
    return 0
