"""Diagnose the real HSM150 bench runs (../shared/data/hsm150): what does the
Eq. 6 model of that DC motor miss?

    python benchmarks/diagnose_hsm150.py --params HSM150.yaml [--out DIR]

HSM150.yaml: the motor identified by `python benchmarks/identify_hsm150.py`
(its `hsm150.yaml`); without --params the catalogue prior of that script is
used and the diagnosis's own refit does the identification. The motor spins
freely, so the half-plane split is off (``--side right``) as in the
identification. Prints the command it runs and its output; the report,
figure, recording and JSON are in DIR.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# The sibling script (run as a script, benchmarks/ is on sys.path) owns the
# data location, the column mapping and the catalogue prior.
from identify_hsm150 import DATA, data_files, prior, run_cli

from isp_twin.model.parameters import save_parameters

TRAIN = ["idf_neg_0.04_1", "idf_pos_0.06_1", "idf_neg_0.05_1", "idf_pos_0.07_1"]
HOLDOUT = ["idf_neg_0.045_1", "idf_pos_0.065_1"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the HSM150 .mat files")
    parser.add_argument("--params", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=Path("hsm150_diagnosis"))
    parser.add_argument("--train", nargs="+", default=TRAIN)
    parser.add_argument("--holdout", nargs="+", default=HOLDOUT)
    parser.add_argument("--max-rounds", type=int, default=2)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    params = args.params or save_parameters(prior(), args.out / "hsm150_prior.yaml")
    argv = [
        "diagnose",
        *data_files(args.train, args.data),
        "--holdout",
        *data_files(args.holdout, args.data),
        "--params",
        str(params),
        "--side",
        "right",
        "--max-rounds",
        str(args.max_rounds),
        # 6 runs x 20 000 samples: above the default long-log limit (100 000),
        # which guards a user against an unexpected cost; this benchmark knows its cost.
        "--max-samples",
        "200000",
        "--out",
        str(args.out / "hsm150_diagnosed.yaml"),
        "--report",
        str(args.out),
        "--json",
        str(args.out / "hsm150_diagnosis.json"),
    ]
    return run_cli(argv)


if __name__ == "__main__":
    sys.exit(main())
