"""Speed of the sub-stepped model (`isp_twin.model.substep_model`), the cost of every
identify and diagnose trial, measured in one run as ratios (the machine is shared).

Kernel: a batch of P parameter sets (the truth's rate form of a reference axis,
jittered by 1 %) on its two training runs (2 x 6000 samples), m = 10 sub-steps,
half-plane from the fused angle, as `identification.residuals` calls it. Prints
the time per sample per parameter set of

* the row-by-row kernel before this change (`tests/substep_kernel_reference.py`),
* the kernel with interleaved rows on one thread (`_advance_rows`),
* the same on all of numba's threads (`_advance_blocks`),

the ratios new/old, and whether all three give the same numbers bit for bit.

Commands (``--commands SEED...``): `isp-twin identify` (2 x 6000 samples) and
`isp-twin diagnose` with the whole library (3 x 6000) on reference axes
(`isp-twin generate --reference --seed SEED`), wall and CPU time of each (CPU:
user + system of the child, all its threads); with ``--baseline DIR`` the same
commands of another checkout (e.g. ``git worktree add /tmp/base 9cc08c3``) are
run alternately with these, and the ratios printed.

    python benchmarks/substep_speed.py [--sets 21 80] [--repeat 5]
    python benchmarks/substep_speed.py --commands 1000 1001 1002 --baseline /tmp/base
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

import isp_twin  # noqa: F401, E402  # isort: skip  (first: its OpenBLAS settings precede numpy's)
import numba  # noqa: E402
import numpy as np  # noqa: E402
from substep_kernel_reference import advance_row_by_row  # noqa: E402

from isp_twin.identification.measured import MeasuredData  # noqa: E402
from isp_twin.identification.read_out import Timing  # noqa: E402
from isp_twin.identification.side_angle import side_angle  # noqa: E402
from isp_twin.model.parameters import RATE_LAYOUT, RateParams  # noqa: E402
from isp_twin.model.substep_model import (  # noqa: E402
    DEFAULT_INTEGRATION,
    _advance_blocks,
    _advance_rows,
    _substep_table,
)
from isp_twin.reference import design_experiment  # noqa: E402


def kernel_inputs(seed: int, n_sets: int):
    """Kernel arguments for `n_sets` jittered truths on the axis' two training runs."""
    exp = design_experiment(seed)
    rf = exp.truth()["rate_form"]["regimes"]
    x = np.array([rf[r][f] for r in RATE_LAYOUT.regimes for f in RATE_LAYOUT.fields])
    rng = np.random.default_rng(seed)
    xs = x * (1 + 0.01 * rng.standard_normal((n_sets, RATE_LAYOUT.size)))
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, float(r.t[1] - r.t[0]))
        for n, r in exp.runs.items()
        if n.startswith("train")
    ]
    m = DEFAULT_INTEGRATION.substeps
    timing = Timing(0.5, True)
    n = max(len(d) for d in runs)
    u = np.zeros((len(runs), n))
    y = np.zeros((len(runs), n))
    for i, d in enumerate(runs):
        u[i, : len(d)] = d.u
        y[i, : len(d)] = side_angle(d, "measured", timing.side_shift / m)
        y[i, len(d) :] = y[i, len(d) - 1]
    rows = n_sets * len(runs)
    table = _substep_table(RateParams.from_vector(np.repeat(xs, len(runs), axis=0)), rows, m, True)
    u = np.ascontiguousarray(np.tile(u, (n_sets, 1)))
    y = np.ascontiguousarray(np.tile(y, (n_sets, 1)))
    w0 = np.zeros(rows)
    return table, u, np.zeros_like(u), y, m, runs[0].dt, w0, y[:, 0].copy()


def time_kernel(kernel, inputs, tail, repeat: int, clock=time.thread_time):
    """Best time of `repeat` calls: `clock` is this thread's CPU time for a
    one-thread kernel (what other processes on the machine take is not
    counted), the wall time for a parallel one."""
    table, u, extra, y, m, dt, w0, a0 = inputs
    times = []
    for _ in range(repeat + 1):  # the first call loads or compiles
        w, a = w0.copy(), a0.copy()
        out = [np.zeros(u.shape) for _ in range(3)] + [np.zeros(u.shape, dtype=np.int64)]
        start = clock()
        kernel(table, u, extra, y, True, -1, 1, u.shape[1], m, dt, True, True, True, w, a, *out,
               *tail)  # fmt: skip
        times.append(clock() - start)
    return min(times[1:]), [*out, w, a]


def kernels(args) -> None:
    for n_sets in args.sets:
        inputs = kernel_inputs(args.seed, n_sets)
        rows = inputs[1].shape[0]
        old, ref = time_kernel(advance_row_by_row, inputs, (), args.repeat)
        ser, a = time_kernel(_advance_rows, inputs, (0, rows), args.repeat)
        ser_wall, _ = time_kernel(_advance_rows, inputs, (0, rows), args.repeat, time.perf_counter)
        blocks = min(numba.get_num_threads(), rows)
        par, b = time_kernel(_advance_blocks, inputs, (blocks,), args.repeat, time.perf_counter)
        same = all(np.array_equal(p, q) and np.array_equal(p, r) for p, q, r in zip(ref, a, b))
        ns = 1e9 / (rows * inputs[1].shape[1])  # per sample of the runs, per set
        print(
            f"\nP = {n_sets} sets x {rows // n_sets} runs x {inputs[1].shape[1]} samples, "
            f"m = {inputs[4]} (best of {args.repeat}), per sample per set:\n"
            f"  row by row (before)     {old * ns:7.1f} ns CPU\n"
            f"  interleaved, 1 thread   {ser * ns:7.1f} ns CPU    new/old {ser / old:.2f}\n"
            f"  interleaved, 1 thread   {ser_wall * ns:7.1f} ns wall\n"
            f"  interleaved, {blocks} threads  {par * ns:7.1f} ns wall   {blocks} threads/1 thread "
            f"{par / ser_wall:.2f} (wall; {1 / blocks:.2f} needs {blocks} idle cores)\n"
            f"  same numbers bit for bit: {same}"
        )
    print(f"numba threading layer: {numba.threading_layer()}, threads {numba.get_num_threads()}")


def run_command(
    argv: list[str], pythonpath: Path, timeout_s: float
) -> tuple[int, float, float, str]:
    """(exit code, wall [s], CPU [s] of the child and its threads, last stderr line)
    of ``isp-twin ARGV`` run from the checkout `pythonpath`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "isp_twin.cli", *argv],
        cwd=pythonpath,  # `-m` puts the working directory first on sys.path
        env=dict(os.environ, PYTHONPATH=str(pythonpath)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        timeout=timeout_s,
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    lines = proc.stderr.strip().splitlines()
    return proc.returncode, wall, cpu, lines[-1] if lines else ""


def commands(args) -> None:
    checkouts = {"this": ROOT}
    if args.baseline is not None:
        checkouts["baseline"] = args.baseline.resolve()
    rows: dict[str, dict[str, list[tuple[float, float]]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.commands:
            d = Path(tmp) / str(seed)
            code, *_ = run_command(
                ["generate", "--reference", "--seed", str(seed), "--out", str(d)], ROOT, 300
            )
            if code != 0:
                raise SystemExit(f"generate --reference --seed {seed} failed")
            train = [str(d / "train1.csv"), str(d / "train2.csv")]
            held = str(d / "heldout.csv")
            for label, root in checkouts.items():
                p = str(d / f"{label}.yaml")
                jobs = {
                    "identify": ["identify", *train, "--validate", held, "--out", p, "--no-report"],
                    "diagnose": ["diagnose", *train, "--holdout", held, "--params", p,
                                 "--no-recording", "--report", str(d / f"{label}_rep")],
                }  # fmt: skip
                for name, argv in jobs.items():
                    code, wall, cpu, last = run_command(argv, root, 600)
                    if code != 0:
                        raise SystemExit(f"{label} {name} seed {seed}: exit {code}: {last}")
                    rows.setdefault(name, {}).setdefault(label, []).append((wall, cpu))
                    print(f"seed {seed} {label:8s} {name:8s} wall {wall:6.1f} s  CPU {cpu:6.1f} s")
    for name, by in rows.items():
        for label, vals in by.items():
            walls, cpus = zip(*vals)
            print(
                f"{name} {label}: wall median {statistics.median(walls):.1f} s max "
                f"{max(walls):.1f} s; CPU median {statistics.median(cpus):.1f} s max {max(cpus):.1f} s"
            )
        if "baseline" in by:
            r_wall = [a[0] / b[0] for a, b in zip(by["this"], by["baseline"])]
            r_cpu = [a[1] / b[1] for a, b in zip(by["this"], by["baseline"])]
            print(
                f"{name} this/baseline per seed: wall {', '.join(f'{r:.2f}' for r in r_wall)}; "
                f"CPU {', '.join(f'{r:.2f}' for r in r_cpu)}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1000, help="reference axis of the kernel timing")
    ap.add_argument("--sets", type=int, nargs="+", default=[21, 80], help="parameter sets P")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--commands", type=int, nargs="*", default=[], metavar="SEED")
    ap.add_argument("--baseline", type=Path, default=None, metavar="DIR")
    args = ap.parse_args()
    if args.commands:
        commands(args)
    else:
        kernels(args)


if __name__ == "__main__":
    main()
