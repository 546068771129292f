"""Cut the shipped HSM150 excerpts from the full bench runs.

The full runs (27 x 20 s at 1 kHz, public repository `malik-robert/HSM150-data`,
`Data/09-03-2022/`) are not shipped; this script documents, and repeats, how
the two excerpts and the prior beside it were made:

    python examples/hsm150/make_excerpts.py --source ../shared/data/hsm150

Each excerpt keeps rows 9000-10999 (t = 9-11 s, across the torque step at
t = 10 s) of the matrix `data` and the scalars `J`, `B`, `Tvz` unchanged.
The prior is the one of benchmarks/identify_hsm150.py (catalogue J and B).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from scipy.io import loadmat, savemat

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "benchmarks"))

from identify_hsm150 import prior  # noqa: E402

from isp_twin.model.parameters import save_parameters  # noqa: E402

RUNS = ("idf_pos_0.06_1", "idf_pos_0.065_1")
ROWS = slice(9000, 11000)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--source", type=Path, default=HERE.parents[2] / "shared" / "data" / "hsm150"
    )
    args = parser.parse_args()
    for run in RUNS:
        mat = loadmat(str(args.source / f"{run}.mat"))
        out = HERE / f"{run}_t9-11s.mat"
        savemat(
            str(out),
            {"data": mat["data"][ROWS], "J": mat["J"], "B": mat["B"], "Tvz": mat["Tvz"]},
            do_compression=True,
        )
        print(f"wrote {out}")
    print(f"wrote {save_parameters(prior(), HERE / 'hsm150_prior.yaml')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
