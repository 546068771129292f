"""Benchmark: identify all 24 parameters of the inner azimuth axis (Table 2)
from the four 2000-sample open-loop sets of `isp_twin.identification.experiments.PAPER_SET`.

Prints the wall time and the recovery error of the 20 identifiable rate-form
quantities (b is fixed to the prior, see `isp_twin.identification.fit`), for
noise-free data and for realistic sensor noise (0.02 deg/s gyro, 16-bit
resolver). The search starts from a prior that is 20-40 % off.

    python benchmarks/identify_speed.py [--generations N] [--population N] [--coverage N]

Target (issue 4): at most 20 s on the 2-core machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.identification.experiments import GYRO_NOISE_DEG_S, RESOLVER_LSB_DEG, generate_set
from isp_twin.identification.fit import Settings, identify
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import EQ6
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG


def wrong_prior(axis):
    regs = [
        dataclasses.replace(
            r,
            a=1 - (1 - r.a) * 1.3,
            Ke=r.Ke * 0.7,
            Ts=r.Ts * 1.4,
            Tc=r.Tc * 0.75,
            alpha=r.alpha * 1.3,
        )
        for r in axis.regimes
    ]
    return dataclasses.replace(axis, regimes=tuple(regs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=Settings.generations)
    parser.add_argument("--population", type=int, default=Settings.population)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--coverage",
        type=int,
        default=0,
        metavar="N",
        help="also count, over N noise seeds, how often the truth is inside the 95 %% CI",
    )
    args = parser.parse_args()
    params = load_parameters(default_parameters_path())
    truth = params.axis("inner_az")
    x_true = truth.rate_params().to_vector()
    # The data are made by Eq. 6 itself (`generate_set`): fitted with Eq. 6 (m = 1).
    settings = Settings(
        seed=args.seed,
        generations=args.generations,
        population=args.population,
        integration=EQ6,
    )
    for label, noise, lsb in (
        ("noise-free", 0.0, 0.0),
        ("realistic noise", GYRO_NOISE_DEG_S, RESOLVER_LSB_DEG),
    ):
        data = generate_set(
            params, "inner_az", gyro_noise_deg_s=noise, resolver_lsb_deg=lsb, seed=args.seed
        )
        start = time.perf_counter()
        res = identify(data, wrong_prior(truth), settings)
        wall = time.perf_counter() - start
        rel = np.abs(res.vector / x_true - 1)
        inside = np.abs(res.vector - x_true) <= res.ci95
        print(
            f"{label:16s}: wall {wall:6.2f} s, {res.evaluations} simulated sets, "
            f"RMS error {res.cost / DEG:.4g} deg/s, recovery error max {100 * rel.max():.3f} % "
            f"(median {100 * np.median(rel):.3f} %), truth inside 95 % CI: {inside.sum()}/{inside.size}"
        )
        print(f"{'':16s}  {res.status}")
    if args.coverage:
        inside = []
        for seed in range(args.seed + 1, args.seed + 1 + args.coverage):
            data = generate_set(
                params,
                "inner_az",
                gyro_noise_deg_s=GYRO_NOISE_DEG_S,
                resolver_lsb_deg=RESOLVER_LSB_DEG,
                seed=100 * seed,
            )
            res = identify(data, wrong_prior(truth), dataclasses.replace(settings, seed=seed))
            inside.extend((np.abs(res.vector - x_true) <= res.ci95)[res.identifiable])
        print(
            f"coverage over {args.coverage} noise seeds: truth inside the 95 % CI for "
            f"{sum(inside)}/{len(inside)} = {100 * np.mean(inside):.1f} % of the identifiable quantities"
        )


if __name__ == "__main__":
    main()
