"""Identify (and optionally diagnose) on clean reference axes, one line per axis.

A development loop for issue 8's clean-axis targets: for each seed, draw the
clean axis (`isp_twin.reference.design_experiment`), write its runs, run
``isp-twin identify`` (and with ``--diagnose`` ``isp-twin diagnose``) as
`identify_reference.py` does, and print train / held-out RMS error over the
truth's noise sigma, the command's CPU time, the simulated parameter sets and
the stages of the search log. Default seeds are the dev seeds 1000-1019
(issue 8's calibration rule: seeds 0-39 are the benchmark's).

    python benchmarks/clean_identify_dev.py --seeds 1000-1019 --jobs 2 --workdir /tmp/clean
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT.parent))
sys.path.insert(0, str(ROOT))

import isp_twin  # noqa: F401, E402  # isort: skip  (first: its OpenBLAS settings precede numpy's)
import numpy as np  # noqa: E402
from identify_reference import run_command  # noqa: E402

from isp_twin.reference import RUN_NAMES  # noqa: E402

BOUND = 1.3


def one(seed: int, workdir: Path, diagnose: bool, timeout_s: float, extra: tuple = ()) -> dict:
    """Write, identify (and diagnose) one clean axis; the ratios and times."""
    import yaml

    from isp_twin.identification.measured import MeasuredData, save_measured
    from isp_twin.reference import design_experiment

    folder = workdir / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    exp = design_experiment(seed, None)
    truth = exp.truth()
    for name in RUN_NAMES:
        run = exp.runs[name]
        save_measured(
            MeasuredData(name, run.t, run.u, run.omega, run.theta, None, 1e-3),
            folder / f"{name}.csv",
        )
    (folder / "truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False))
    sigma = truth["noise_sigma_deg_s"]
    rec = {"seed": seed, "tau_ms": 1e3 * truth["physical"]["time_constant_s"]}
    args = ["identify", "train1.csv", "train2.csv", "--validate", "heldout.csv"]
    args += ["--out", "params.yaml", "--json", "identify.json", "--no-report", "--quiet"]
    args += list(extra)
    code, wall, cpu, last, *_ = run_command(args, folder, timeout_s)
    rec.update(identify_code=code, identify_cpu_s=cpu, identify_wall_s=wall)
    if code != 0:
        rec["error"] = last
        return rec
    ident = json.loads((folder / "identify.json").read_text())
    train = [ident["rmse_train"][n] for n in RUN_NAMES[:2]]
    rec["train"] = math.sqrt(np.mean(np.square(train))) / sigma
    rec["heldout"] = ident["rmse_validation"]["heldout"] / sigma
    rec["evaluations"] = ident.get("evaluations")
    stages = {}
    for step in ident.get("search_log", []):
        stages[step["stage"]] = step.get("evaluations", step.get("simulated"))
    rec["stages"] = stages
    if diagnose:
        args = ["diagnose", "train1.csv", "train2.csv", "--params", "params.yaml"]
        args += ["--holdout", "heldout.csv", "--json", "diagnose.json", "--quiet"]
        args += ["--no-recording", "--report", "diagnosis"]
        code, wall, cpu, last, *_ = run_command(args, folder, timeout_s)
        rec.update(diagnose_code=code, diagnose_cpu_s=cpu)
        if code == 0:
            diag = json.loads((folder / "diagnose.json").read_text())
            rec["selected"] = diag["selected_effect"]
            rec["tentative"] = list(diag.get("tentative_effects", []))
        else:
            rec["error"] = last
    return rec


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="1000-1019", help="FIRST-LAST (inclusive)")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/clean_identify_dev"))
    p.add_argument("--jobs", type=int, default=1, choices=(1, 2))
    p.add_argument("--diagnose", action="store_true")
    p.add_argument("--timeout", type=float, default=300.0)
    p.add_argument(
        "--identify-args", default="", help="more identify options, e.g. '--regime-spread none'"
    )
    args = p.parse_args()
    extra = tuple(args.identify_args.split())
    first, last = (int(v) for v in args.seeds.split("-"))
    seeds = list(range(first, last + 1))
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = [
            pool.submit(one, s, args.workdir, args.diagnose, args.timeout, extra) for s in seeds
        ]
        recs = []
        for f in futures:
            r = f.result()
            recs.append(r)
            print(json.dumps(r), flush=True)
    ok = [r for r in recs if "train" in r]
    both = sum(1 for r in ok if r["train"] <= BOUND and r["heldout"] <= BOUND)
    cpu = [r["identify_cpu_s"] for r in recs]
    print(
        f"clean axes {len(recs)}: train and held-out <= {BOUND}x noise on {both}/{len(recs)}; "
        f"median train {statistics.median(r['train'] for r in ok):.3f}, "
        f"held-out {statistics.median(r['heldout'] for r in ok):.3f}; "
        f"identify CPU median {statistics.median(cpu):.1f} s, max {max(cpu):.1f} s"
    )
    if args.diagnose:
        none = sum(1 for r in recs if r.get("selected") == "none")
        print(f"diagnose none on {none}/{len(recs)}")


if __name__ == "__main__":
    main()
