"""1000 closed-loop runs through ``isp-twin sweep`` on a local Dask cluster: time and memory.

Writes a sweep of turbulence_1_6Hz (12 s, 12 001 samples each) over `--runs`
noise seeds into a temporary folder, runs ``isp-twin sweep`` on it as a
user would (local cluster, default workers = cores), and prints the wall
time, the time per run, and the resident memory of the sweep's parent
process (which holds the design and writes the store) sampled as the runs
finish: flat memory means the results go to the store, not into memory.
Then re-runs the same command and prints how long it takes to find every
run in the store (nothing is redone).

Issue 9 target: 1000 runs in <= 90 s on 2 cores, memory flat in the runs.
Since the machine may be shared, it also times one run in a single process
just before, and prints the sweep's wall time over the ideal
(one run x runs / workers): the sweep machinery's own overhead.

    python benchmarks/sweep_1000.py [--runs 1000] [--workers N] [--batch B]
    python benchmarks/sweep_1000.py --runs 6000 --duration 0.05   # memory over many runs
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--batch", type=int, default=1, help="runs per Dask task (sweep --batch)")
    ap.add_argument("--scenario", default="turbulence_1_6Hz")
    ap.add_argument(
        "--duration",
        type=float,
        default=None,
        help="shorten each run to this many seconds (metrics over the whole run): many "
        "cheap runs show whether the parent's memory stays flat",
    )
    args = ap.parse_args()
    load_before = os.getloadavg()  # the machine may be shared: say how busy it was
    # The reference: one run in this process, now (the machine may be shared).
    from isp_twin.experiments.closed_loop import run_scenario
    from isp_twin.experiments.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if args.duration is not None:
        from dataclasses import replace

        from isp_twin.experiments.scenario import Metrics

        scenario = replace(scenario, duration_s=args.duration, metrics=Metrics(skip_s=0.0))
    run_scenario(scenario)  # the first run also loads (or compiles) the closed-loop kernel
    start = time.perf_counter()
    run_scenario(scenario)
    one = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sweep = tmp / "many_seeds.yaml"
        text = f"scenario: {args.scenario}\nseeds: {{first: 1, count: {args.runs}}}\n"
        if args.duration is not None:  # the sweep's runs as short as the reference run
            text += f"cases: [{{duration_s: {args.duration}, metrics.skip_s: 0.0}}]\n"
        sweep.write_text(text)
        cmd = [sys.executable, "-m", "isp_twin.cli", "sweep", str(sweep), "--no-plots"]
        cmd += ["--store", str(tmp / "store.sqlite")]
        if args.workers is not None:
            cmd += ["--workers", str(args.workers)]
        cmd += ["--batch", str(args.batch)]
        rss: list[tuple[int, float]] = []  # (runs done, parent RSS [MB])
        start = time.perf_counter()
        proc = subprocess.Popen(
            cmd, cwd=tmp, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        parent = psutil.Process(proc.pid)

        def follow_progress() -> None:
            for line in proc.stderr:
                m = re.match(r"sweep: (\d+)/(\d+) runs done", line)
                if m:
                    try:
                        rss.append((int(m.group(1)), parent.memory_info().rss / 2**20))
                    except psutil.Error:
                        pass

        reader = threading.Thread(target=follow_progress)
        reader.start()
        out = proc.stdout.read()
        proc.wait()
        reader.join()
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            sys.exit(f"sweep failed (exit {proc.returncode}):\n{out}")
        head = out.splitlines()[0]
        start = time.perf_counter()
        again = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, check=True)
        rerun = time.perf_counter() - start
    workers = int(re.search(r"cluster of (\d+) workers", head).group(1))
    print(head)
    print(f"cores: {len(os.sched_getaffinity(0))}, workers: {workers}, runs per task: {args.batch}")
    print(f"load average before / after: {load_before} / {os.getloadavg()}")
    ideal = one * args.runs / workers
    print(
        f"one run in a single process (measured just before): {one:.3f} s -> ideal "
        f"{ideal:.1f} s for {args.runs} runs on {workers} workers"
    )
    print(
        f"{args.runs} runs: {wall:.1f} s wall including cluster start ({wall / args.runs:.3f} s per run)"
    )
    print(
        f"target: <= 90 s for 1000 runs on 2 cores; this run: {wall / args.runs * 1000:.0f} s per 1000"
    )
    if rss:
        print(
            "parent process RSS [MB] as runs finish: "
            + ", ".join(f"{n}: {mb:.0f}" for n, mb in rss[:: max(1, len(rss) // 8)] + [rss[-1]])
        )
    print(f"sweep wall / ideal: {wall / ideal:.2f} (1.0: no overhead beyond the runs)")
    print(f"re-run of the same command (all {args.runs} in the store): {rerun:.1f} s")
    print(again.stdout.splitlines()[0])


if __name__ == "__main__":
    main()
