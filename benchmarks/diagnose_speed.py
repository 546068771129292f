"""Wall time of a full diagnosis: the whole effect library on 3 data sets of
6000 samples (target: at most 60 s on a 2-core machine).

Run: python benchmarks/diagnose_speed.py [--effect cogging] [--seed 0]

Two set-ups: 2 training runs + 1 held-out run, and 3 training runs with
leave-one-run-out cross-validation. Prints wall time, the selected effect
and the held-out errors.
"""

from __future__ import annotations

import argparse
import time

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.diagnosis.search import DEFAULT_ITERATIONS, diagnose
from isp_twin.diagnosis.synthetic import excitation, make_run, random_effect
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import EQ6
from isp_twin.resources import default_parameters_path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--effect", default="cogging")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=6000)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument(
        "--iterations",
        type=int,
        default=DEFAULT_ITERATIONS,
        help="Levenberg-Marquardt iterations per fit",
    )
    args = ap.parse_args()
    params = load_parameters(default_parameters_path())
    rate = params.axis("inner_az").rate_params()
    rng = np.random.default_rng(args.seed)
    us = [excitation(rng, args.samples, 1e-3) for _ in range(3)]
    effect = random_effect(args.effect, rng, us[0])
    runs = [
        make_run(f"run{i}", rate, u, 1e-3, rng, [effect], 0.003, angle0=rng.uniform(-0.2, 0.2))
        for i, u in enumerate(us)
    ]
    print(f"truth: {effect.name} {effect.params}")
    for label, train, held in (
        ("2 train + 1 held out", runs[:2], runs[2:]),
        ("3 train, cross-validation", runs, []),
    ):
        t0 = time.perf_counter()
        # The runs are made by Eq. 6 itself (`make_run`, gyro read at the
        # sample): diagnosed with Eq. 6 (m = 1) and that read-out.
        diag = diagnose(
            train,
            params,
            "inner_az",
            held,
            max_rounds=args.rounds,
            max_iter=args.iterations,
            integration=EQ6,
            timing=Timing(),
        )
        wall = time.perf_counter() - t0
        j = diag.to_json()
        print(
            f"{label}: {wall:.1f} s wall; selected {j['selected_effect']} "
            f"{ {k: round(v, 5) for k, v in j['effect_parameters'].items()} }; "
            f"held-out RMS before {j['rmse_before']:.5f}, after {j['rmse_after']:.5f}, "
            f"noise floor {j['noise_floor']:.5f} rad/s"
        )


if __name__ == "__main__":
    main()
