"""Paper vs twin, full size: Table 4 grid and the Table 5 / 6 campaigns with ten seeds.

Writes docs/paper_vs_twin.md (the same text as `isp-twin report --output ...`)
and prints it, with the wall time. With ``--scan-scale`` it instead prints the
calibration scan of docs/calibration.md: the Table 4 grid (PI) for each gyro
scale [counts per deg/s]. Usage::

    python benchmarks/paper_tables.py [--runs 10] [--jobs 2]
    python benchmarks/paper_tables.py --scan-scale 50 60 70 80 90 --runs 2
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from isp_twin.atomic import write_text_atomic
from isp_twin.campaign import TABLE4_SCENARIOS, compare_with_paper, comparison_markdown
from isp_twin.closed_loop import run_scenario
from isp_twin.paper import TABLE4_ACTUAL
from isp_twin.scenario import load_scenario


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--scan-scale", type=float, nargs="+", default=None, metavar="SCALE")
    parser.add_argument(
        "--output",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "docs" / "paper_vs_twin.md",
    )
    args = parser.parse_args()
    if args.scan_scale:
        scan_scale(args.scan_scale, args.runs, args.jobs)
        return
    start = time.perf_counter()
    text = comparison_markdown(compare_with_paper(args.runs, args.jobs))
    elapsed = time.perf_counter() - start
    write_text_atomic(args.output, text)
    print(text)
    print(f"wall time {elapsed:.1f} s with {args.jobs} workers; written to {args.output}")


if __name__ == "__main__":
    main()
