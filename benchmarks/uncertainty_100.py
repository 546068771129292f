"""100 uncertainty draws of turbulence_1_6Hz through ``isp-twin campaign --uncertainty``: time.

Runs the command as a user would (local Dask cluster, `--jobs` workers;
each draw is one PI and one PI+NFC run of 12 s, so 200 runs), with the PNG
and the JSON written to a temporary folder, and prints its wall time, the
issue's target (100 draws in <= 120 s on 2 cores) as a ratio, and, since the
machine may be shared, one run timed in this process just before with the
command's wall time over the ideal (one run x runs / workers).

    nice python benchmarks/uncertainty_100.py [--draws 100] [--jobs 2] [--oat]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

TARGET_S = 120.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenario", default="turbulence_1_6Hz")
    ap.add_argument("--oat", action="store_true", help="also the one-at-a-time sweep")
    args = ap.parse_args()
    from isp_twin.cli import main as cli
    from isp_twin.experiments.closed_loop import run_scenario
    from isp_twin.experiments.scenario import load_scenario

    start = time.perf_counter()
    run_scenario(load_scenario(args.scenario))
    one = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as tmp:
        png, js = Path(tmp) / "u.png", Path(tmp) / "u.json"
        argv = ["campaign", args.scenario, "--uncertainty", str(args.draws)]
        argv += ["--jobs", str(args.jobs), "--plot", str(png), "--json", str(js)]
        argv += ["--oat"] if args.oat else []
        start = time.perf_counter()
        code = cli(argv)
        wall = time.perf_counter() - start
        doc = json.loads(js.read_text()) if code == 0 else {}
    runs = 2 * args.draws
    if args.oat and doc:
        runs += 2 * 2 * (1 + 2 * len(doc["one_at_a_time"]["knobs"]))
    ideal = one * runs / args.jobs
    print(
        f"\n{args.draws} draws ({runs} runs) in {wall:.1f} s with {args.jobs} workers "
        f"(exit {code}); target {TARGET_S:.0f} s: wall / target = {wall / TARGET_S:.2f}"
    )
    print(
        f"one run in this process just before: {one:.2f} s; wall / ideal "
        f"(one run x {runs} / {args.jobs}) = {wall / ideal:.2f}"
    )


if __name__ == "__main__":
    main()
