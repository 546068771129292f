"""Speed of the reference simulator's experiment design against another
checkout, and whether both make the same data bit for bit.

For each seed and case, a child process of each checkout (PYTHONPATH set to
it) runs `isp_twin.reference.design_experiment` (the axis, its probes and
its three runs) after one untimed design that loads or compiles the
integrator. It reports the CPU time of each design and a SHA-256 digest of
every array of the three runs (command, gyro, resolver, true rate, angle,
regime). This prints the per-case times, the ratio this/baseline of their
totals, measured in the same run, and how many designs are identical.

    git worktree add /tmp/base 8415f27    # the plain Python loop (stop 43)
    python benchmarks/reference_speed.py --baseline /tmp/base --seeds 0 1 --cases none,cogging,resonance,lugre
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIELDS = ("u", "omega", "omega_clean", "theta", "rate", "angle", "regime")


def child(seeds: list[int], cases: list[str]) -> None:
    """Design every (seed, case) with the `isp_twin` on sys.path; one JSON line each."""
    from isp_twin.reference import design_experiment

    design_experiment(0, None)  # untimed: loads (or compiles) the integrator
    for seed in seeds:
        for case in cases:
            start = time.process_time()
            exp = design_experiment(seed, None if case == "none" else case)
            cpu = time.process_time() - start
            digest = hashlib.sha256()
            for name in sorted(exp.runs):
                for field in FIELDS:
                    digest.update(getattr(exp.runs[name], field).tobytes())
            print(
                json.dumps({"seed": seed, "case": case, "cpu_s": cpu, "digest": digest.hexdigest()})
            )


def designs(root: Path, seeds: list[int], cases: list[str]) -> dict[tuple[int, str], dict]:
    """`child` run from the checkout `root`: its records by (seed, case)."""
    argv = [sys.executable, str(Path(__file__).resolve()), "--child", "--seeds"]
    argv += [str(s) for s in seeds] + ["--cases", ",".join(cases)]
    proc = subprocess.run(
        argv,
        env=dict(os.environ, PYTHONPATH=str(root)),
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines()
        raise SystemExit(f"{root}: exit {proc.returncode}: {lines[-1] if lines else ''}")
    records = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    return {(r["seed"], r["case"]): r for r in records}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--baseline", type=Path, metavar="DIR", help="the other checkout (required)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--cases", default="none,cogging,resonance,lugre", help="comma-separated")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    if args.child:
        child(args.seeds, cases)
        return 0
    if args.baseline is None:
        p.error("--baseline DIR is required")
    this = designs(ROOT, args.seeds, cases)
    base = designs(args.baseline.resolve(), args.seeds, cases)
    same = 0
    for key in sorted(this):
        a, b = this[key], base[key]
        same += a["digest"] == b["digest"]
        print(
            f"seed {key[0]} {key[1]:14s} this {a['cpu_s']:7.3f} s  baseline {b['cpu_s']:7.3f} s  "
            f"data {'identical' if a['digest'] == b['digest'] else 'DIFFERENT'}"
        )
    total_this = sum(r["cpu_s"] for r in this.values())
    total_base = sum(r["cpu_s"] for r in base.values())
    print(
        f"design CPU: this {total_this:.2f} s, baseline {total_base:.2f} s, "
        f"this/baseline {total_this / total_base:.3f}; identical data {same}/{len(this)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
