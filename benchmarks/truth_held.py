"""The library with the reference's *true* parameters against reference data.

For each reference axis (`isp_twin.reference.design_experiment`, seed and
effect), the sub-stepped model (`isp_twin.model.substep_model`, defaults:
m = 10, gyro averaged over the sample, half-plane from the measured angle)
is run with the truth's rate form and the truth's effect parameters
(`truth.yaml`), and its RMS error over the gyro noise sigma is printed per
run (train1, train2, held-out), beside the same without the effect. A model
that holds the reference's physics reaches about 1 (the noise) with the truth
held: this is what the library can reach at best, whatever the fit. For
`resonance` the truth is the two-mass form (its payload fraction, integrated
in the sub-steps: friction on the motor side) and the middle figure per run
is the gyro-only form (the truth with ``payload_fraction`` 0, what the
library's `resonance` was before docs/diagnosis.md "Stop 18 R"). The runs
are read together, as the commands read theirs (`one_gyro_error`, since
docs/identification.md "Stop 80").

    python benchmarks/truth_held.py --effects lugre,resonance --seeds 1000-1005
    python benchmarks/truth_held.py --effects none --seeds 327-330 --held-out covered
"""

from __future__ import annotations

import argparse

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.errors import ParameterError
from isp_twin.identification.cost import rmse
from isp_twin.identification.gyro_error import one_gyro_error
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import RATE_LAYOUT, EffectSpec, RateParams
from isp_twin.reference import design_experiment
from isp_twin.units import DEG

RUNS = ("train1", "train2", "heldout")


def truth_held_row(seed: int, effect: str, held_out: str = "free") -> dict[str, tuple[float, ...]]:
    """Per run: (error without the effect[, gyro-only form], error with the
    true effect) / noise sigma; on a clean axis (`effect` none) only the first."""
    exp = design_experiment(seed, None if effect == "none" else effect, held_out=held_out)
    truth = exp.truth()
    sigma = truth["noise_sigma_deg_s"] * DEG
    regimes = truth["rate_form"]["regimes"]
    x = np.concatenate([[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    rate = RateParams.from_vector(x)
    if not truth["effects"]:
        specs = []
    else:
        spec = EffectSpec(effect, truth["effects"][0]["params"])
        specs = [(spec,)]
    if effect == "resonance":
        gyro_only = EffectSpec(effect, {**spec.params, "payload_fraction": 0.0})
        specs.insert(0, (gyro_only,))
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    out = {}
    # The three runs together, as `identify` and `diagnose` read their runs.
    runs = one_gyro_error(
        [
            MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])
            for name, r in ((name, exp.runs[name]) for name in RUNS)
        ]
    )
    for name, run in zip(RUNS, runs):
        data = [run]
        without = rmse(rate, data, timing=timing) / sigma
        held = [float(rmse(rate, data, effects=e, timing=timing) / sigma) for e in specs]
        out[name] = (float(without), *held)
    return out


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = (int(s) for s in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effects", default="lugre,resonance")
    parser.add_argument("--seeds", default="1000-1005", help="e.g. 1000-1005 or 1000,1003")
    parser.add_argument(
        "--held-out",
        default="free",
        choices=("free", "covered"),
        help="the held-out run's design (identify_reference.py's --held-out)",
    )
    args = parser.parse_args()
    print(
        "| effect | seed | " + " | ".join(f"{n}: none [/ gyro-only] / truth" for n in RUNS) + " |"
    )
    print("|---|---|" + "---|" * len(RUNS))
    for effect in args.effects.split(","):
        for seed in _seeds(args.seeds):
            try:
                row = truth_held_row(seed, effect, args.held_out)
            except ParameterError as exc:  # no experiment for this draw
                reason = str(exc).replace("|", "")  # no bars inside a table cell
                print(f"| {effect} | {seed} | no experiment: {reason} |||", flush=True)
                continue
            cells = " | ".join(" / ".join(f"{v:.2f}" for v in row[n]) for n in RUNS)
            print(f"| {effect} | {seed} | {cells} |", flush=True)


if __name__ == "__main__":
    main()
