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
import importlib.util
import time
from pathlib import Path

from isp_twin.cli import main as cli
from isp_twin.parameters import save_parameters

HERE = Path(__file__).resolve().parent
DATA = HERE.parents[1] / "shared" / "data" / "hsm150"
MAP = ["t=data:0", "u=data:4", "omega=data:3*rad/s", "theta=data:2*rad"]
TRAIN = ["idf_neg_0.04_1", "idf_pos_0.06_1", "idf_neg_0.05_1", "idf_pos_0.07_1"]
HOLDOUT = ["idf_neg_0.045_1", "idf_pos_0.065_1"]


def _prior(folder: Path) -> Path:
    spec = importlib.util.spec_from_file_location("identify_hsm150", HERE / "identify_hsm150.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return save_parameters(module.prior(), folder / "hsm150_prior.yaml")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--params", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=Path("hsm150_diagnosis"))
    parser.add_argument("--train", nargs="+", default=TRAIN)
    parser.add_argument("--holdout", nargs="+", default=HOLDOUT)
    parser.add_argument("--max-rounds", type=int, default=2)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    params = args.params or _prior(args.out)
    files = lambda names: [str(DATA / f"{n}.mat") for n in names]
    argv = [
        "diagnose",
        *files(args.train),
        "--holdout",
        *files(args.holdout),
        "--params",
        str(params),
        "--side",
        "right",
        "--max-rounds",
        str(args.max_rounds),
        "--out",
        str(args.out / "hsm150_diagnosed.yaml"),
        "--report",
        str(args.out),
        "--json",
        str(args.out / "hsm150_diagnosis.json"),
    ]
    for m in MAP:
        argv += ["--map", m]
    print("isp-twin " + " ".join(argv))
    start = time.perf_counter()
    code = cli(argv)
    print(f"exit {code}, wall {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
