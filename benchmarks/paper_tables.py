"""Paper vs twin, full size: Table 4 grid and the Table 5 / 6 campaigns with ten seeds.

Writes docs/paper_vs_twin.md (the same text as `isp-twin report --output ...`)
and prints it, with the wall time. With ``--scan-scale`` it instead prints the
calibration scan of docs/calibration.md: the Table 4 grid (PI) for each gyro
scale [counts per deg/s]. With ``--scan`` it prints, for every combination of
the given scenario knobs (dotted field paths of `isp_twin.experiments.scenario.Scenario`),
the three 1/6 Hz cells of Table 4 (PI, the only cells the calibration may be
fitted on) and their sum of squared errors against the paper's measured J;
``--validate`` adds, for the same combinations, the 0.5 Hz cells and the
PI -> PI+NFC reductions of Tables 5 and 6 (validation, not fitted). Usage::

    python benchmarks/paper_tables.py [--runs 10] [--jobs 2]
    python benchmarks/paper_tables.py --scan-scale 50 60 70 80 90 --runs 2
    python benchmarks/paper_tables.py --scan gyro.scale_count_per_deg_s=60,65,70 \
        follower.kp_digit_per_deg=500,1000,2000 --runs 2 [--validate]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.experiments.calibration import calibration_markdown, evaluate_cells
from isp_twin.experiments.campaign import TABLE4_SCENARIOS
from isp_twin.experiments.closed_loop import run_scenario
from isp_twin.experiments.paper import TABLE4_ACTUAL, TABLE5, TABLE6, relative_reduction
from isp_twin.experiments.rig import resolve_rig
from isp_twin.experiments.scenario import Scenario, load_scenario
from isp_twin.output.files import write_text_atomic

Knobs = tuple[tuple[str, float], ...]


def _scan_job(job: tuple[str, float, int]) -> float:
    name, scale, seed = job
    scenario = load_scenario(name).with_nfc(False)
    gyro = dataclasses.replace(scenario.gyro, scale_count_per_deg_s=scale)
    scenario = dataclasses.replace(scenario, gyro=gyro)
    return run_scenario(scenario, seed=seed).metrics["inner_az"]["isolation_percent"]


def scan_scale(scales: list[float], runs: int, jobs: int) -> None:
    """Print the Table 4 grid for each gyro scale (mean over `runs` seeds)."""
    cells = list(TABLE4_SCENARIOS.items())
    work = [(name, sc, seed) for sc in scales for _, name in cells for seed in range(1, runs + 1)]
    with ProcessPoolExecutor(jobs) as pool:
        js = np.array(list(pool.map(_scan_job, work))).reshape(len(scales), len(cells), runs)
    head = " ".join(f"{TABLE4_SCENARIOS[c][7:]:>16}" for c, _ in cells)
    print(f"{'scale':>6} {head}")
    for sc, row in zip(scales, js.mean(axis=2)):
        print(f"{sc:6g} " + " ".join(f"{x:16.2f}" for x in row))
    print(f"{'paper':>6} " + " ".join(f"{TABLE4_ACTUAL[c]:16.2f}" for c, _ in cells))


def _with_knob(obj, path: str, value: float):
    """`obj` with the dotted field `path` replaced by `value` (frozen dataclasses)."""
    head, _, rest = path.partition(".")
    if not any(f.name == head for f in dataclasses.fields(obj)):
        names = ", ".join(f.name for f in dataclasses.fields(obj))
        raise SystemExit(f"--scan: {type(obj).__name__} has no field {head!r} (fields: {names})")
    current = getattr(obj, head)
    if rest:
        return dataclasses.replace(obj, **{head: _with_knob(current, rest, value)})
    return dataclasses.replace(obj, **{head: type(current)(value)})


def _apply(scenario: Scenario, knobs: Knobs) -> Scenario:
    for path, value in knobs:
        scenario = _with_knob(scenario, path, value)
    return scenario


def _knob_job(job: tuple[str, Knobs, int, bool]) -> float:
    name, knobs, seed, nfc = job
    scenario = _apply(load_scenario(name).with_nfc(nfc), knobs)
    return run_scenario(scenario, seed=seed).metrics["inner_az"]["isolation_percent"]


def _parse_knobs(specs: list[str]) -> list[tuple[str, list[float]]]:
    out = []
    for spec in specs:
        path, sep, values = spec.partition("=")
        if not sep or not values:
            raise SystemExit(f"--scan: expected PATH=V1,V2,..., got {spec!r}")
        out.append((path, [float(v) for v in values.split(",")]))
    return out


def scan_knobs(specs: list[str], runs: int, jobs: int, validate: bool) -> None:
    """Print the 1/6 Hz Table 4 cells (and, with `validate`, the validation) per knob setting.

    The 1/6 Hz cells are the fit data (sum of squared errors `sse` against the
    paper's measured J, [points^2]); the 0.5 Hz cells and the NFC reductions
    are validation only.
    """
    axes = _parse_knobs(specs)
    grid: list[Knobs] = [
        tuple(zip([p for p, _ in axes], combo))
        for combo in itertools.product(*[v for _, v in axes])
    ]
    _apply(load_scenario(TABLE4_SCENARIOS[(1 / 6, math.pi)]), grid[0])  # bad paths: fail here
    fit = [(c, n) for c, n in TABLE4_SCENARIOS.items() if math.isclose(c[0], 1 / 6)]
    val = [(c, n) for c, n in TABLE4_SCENARIOS.items() if math.isclose(c[0], 0.5)]
    campaigns = [("tracking_0_5Hz", TABLE5), ("turbulence_1_6Hz", TABLE6)]
    seeds = range(1, runs + 1)
    work = [(n, k, s, False) for k in grid for _, n in fit for s in seeds]
    if validate:
        work += [(n, k, s, False) for k in grid for _, n in val for s in seeds]
        work += [
            (n, k, s, nfc)
            for k in grid
            for n, _ in campaigns
            for nfc in (False, True)
            for s in seeds
        ]
    with ProcessPoolExecutor(jobs) as pool:
        results = dict(zip(work, pool.map(_knob_job, work)))

    def mean(name: str, knobs: Knobs, nfc: bool = False) -> float:
        return float(np.mean([results[(name, knobs, s, nfc)] for s in seeds]))

    names = [p.rsplit(".", 1)[-1] for p, _ in axes]
    head = (
        " ".join(f"{n:>14}" for n in names) + " " + " ".join(f"{str(c[1])[:6]:>8}" for c, _ in fit)
    )
    head += f" {'sse':>8}"
    if validate:
        head += " " + " ".join(f"{'0.5Hz':>8}" for _ in val) + f" {'red5':>6} {'red6':>6} {'ok':>3}"
    print(head)
    rows = []
    for knobs in grid:
        j = [mean(n, knobs) for _, n in fit]
        sse = sum((x - TABLE4_ACTUAL[c]) ** 2 for x, (c, _) in zip(j, fit))
        line = " ".join(f"{v:14g}" for _, v in knobs) + " " + " ".join(f"{x:8.2f}" for x in j)
        line += f" {sse:8.1f}"
        if validate:
            jv = [mean(n, knobs) for _, n in val]
            red = [
                relative_reduction(mean(n, knobs, False), mean(n, knobs, True))
                for n, _ in campaigns
            ]
            paper = [relative_reduction(t.pi_average, t.pi_nfc_average) for _, t in campaigns]
            ok = all(abs(x - TABLE4_ACTUAL[c]) <= 3 for x, (c, _) in zip(jv, val))
            ok &= all(abs(r - p) <= 10 for r, p in zip(red, paper))
            ok &= j[0] > j[1] > j[2] and jv[0] > jv[1] > jv[2]
            line += " " + " ".join(f"{x:8.2f}" for x in jv)
            line += f" {red[0]:6.1f} {red[1]:6.1f} {'yes' if ok else 'no':>3}"
        rows.append((sse, line))
    for _, line in rows:
        print(line)
    tail = " ".join(f"{'':>14}" for _ in names) + " "
    tail += " ".join(f"{TABLE4_ACTUAL[c]:8.2f}" for c, _ in fit) + f" {'paper':>8}"
    if validate:
        tail += " " + " ".join(f"{TABLE4_ACTUAL[c]:8.2f}" for c, _ in val)
        tail += " ".join(
            f" {relative_reduction(t.pi_average, t.pi_nfc_average):6.1f}" for _, t in campaigns
        )
    print(tail)
    best = min(rows)
    print(f"best (lowest sse): {best[1].strip()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--scan-scale", type=float, nargs="+", default=None, metavar="SCALE")
    parser.add_argument("--scan", nargs="+", default=None, metavar="PATH=V1,V2")
    parser.add_argument("--validate", action="store_true", help="with --scan: validation too")
    parser.add_argument(
        "--output",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "docs" / "paper_vs_twin.md",
    )
    args = parser.parse_args()
    if args.scan:
        scan_knobs(args.scan, args.runs, args.jobs, args.validate)
        return
    if args.scan_scale:
        scan_scale(args.scan_scale, args.runs, args.jobs)
        return
    start = time.perf_counter()
    text = calibration_markdown(evaluate_cells(resolve_rig("paper_rig"), args.runs, 1, args.jobs))
    elapsed = time.perf_counter() - start
    write_text_atomic(args.output, text)
    print(text)
    print(f"wall time {elapsed:.1f} s with {args.jobs} workers; written to {args.output}")


if __name__ == "__main__":
    main()
