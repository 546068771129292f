"""How often the reference experiment's held-out run leaves the training runs' speeds.

For each seed, the reference simulator's experiment (`isp_twin.reference.
design_experiment`: two Eq. 7 cosine training runs, a held-out multisine)
is drawn, and `isp_twin.estimation.coverage.beyond_training` names the
regimes where the held-out run goes faster than the training runs. There
the training runs do not determine the friction law, whatever the fit: the
share of such axes is a ceiling the experiment design puts on the issue 8
held-out targets. No fit is run; one line per seed, then the share overall
and by the axis' mechanical time constant.

    python benchmarks/held_out_coverage.py --seeds 0-99 --jobs 2
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from isp_twin.experiments.sweep.execute import dask_client  # noqa: E402

#: Time-constant bins [s] of the summary.
TAU_EDGES = (0.005, 0.03, 0.1, 0.3, 1.0)


def one_seed(seed: int, effect: str | None) -> dict:
    """The seed's time constant and the regimes beyond, with their speed ratios."""
    from isp_twin.estimation.coverage import beyond_training
    from isp_twin.estimation.verdict import noise_floor_of
    from isp_twin.identification.measured import MeasuredData
    from isp_twin.reference import RUN_NAMES, design_experiment

    exp = design_experiment(seed, effect)
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])
        for n, r in ((n, exp.runs[n]) for n in RUN_NAMES)
    ]
    floor = noise_floor_of([d.omega for d in runs[:2]])
    beyond = beyond_training(runs[:2], runs[2:], floor)
    return {
        "seed": seed,
        "tau_s": exp.truth()["physical"]["time_constant_s"],
        "beyond": {b.regime: b.held_out_rad_s / b.training_rad_s for b in beyond},
    }


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", default="0-39", help="a range, e.g. 0-99")
    p.add_argument("--effect", default="none", help="the reference effect (none: clean)")
    p.add_argument("--jobs", type=int, default=None, help="local Dask workers")
    p.add_argument("--scheduler", default=None, help="a running Dask scheduler's address")
    args = p.parse_args(argv)
    seeds = _seeds(args.seeds)
    effect = None if args.effect == "none" else args.effect
    from distributed import as_completed

    client, cluster = dask_client(args.scheduler, args.jobs, len(seeds))
    rows = []
    try:
        futures = [client.submit(one_seed, s, effect, pure=False) for s in seeds]
        for fut in as_completed(futures):
            r = fut.result()
            rows.append(r)
            worst = max(r["beyond"].values(), default=float("nan"))
            names = ", ".join(r["beyond"]) or "-"
            print(
                f"seed {r['seed']:4d}  tau {r['tau_s']:.3f} s  beyond: {names}  (x{worst:.2f})",
                flush=True,
            )
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    n_out = sum(1 for r in rows if r["beyond"])
    print(f"\nheld-out run beyond the training speeds: {n_out}/{len(rows)} axes")
    for lo, hi in zip(TAU_EDGES, TAU_EDGES[1:]):
        inside = [r for r in rows if lo <= r["tau_s"] < hi]
        k = sum(1 for r in inside if r["beyond"])
        print(f"  time constant {lo:g}-{hi:g} s: {k}/{len(inside)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
