"""Test helper: reference runs identified and diagnosed as a user runs
`isp-twin identify` (defaults, on train1 and train2) and then `diagnose`
(with the held-out run); or identified alone, judged on the held-out run."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from isp_twin.cli import main
from isp_twin.diagnosis.result import Diagnosis
from isp_twin.diagnosis.search import diagnose
from isp_twin.identification.measured import MeasuredData, save_measured
from isp_twin.model.parameters import load_parameters
from isp_twin.reference import design_experiment


def identified_then_diagnosed(
    folder: Path, runs: dict[str, MeasuredData], candidates, max_rounds: int = 1
) -> Diagnosis:
    """Every run saved as `<name>.csv` in `folder`; `isp-twin identify` on
    train1 and train2; `diagnose` of those with the parameters it wrote,
    `heldout` held out, `candidates`, at most `max_rounds` rounds."""
    for name, data in runs.items():
        save_measured(data, folder / f"{name}.csv")
    out = folder / "params.yaml"
    args = ["identify", str(folder / "train1.csv"), str(folder / "train2.csv")]
    assert main([*args, "--out", str(out), "--no-report", "--quiet"]) == 0
    params = load_parameters(out)
    return diagnose(
        [runs["train1"], runs["train2"]],
        params,
        next(iter(params.axes)),
        holdout=[runs["heldout"]],
        candidates=candidates,
        max_rounds=max_rounds,
    )


def reference_identified_then_diagnosed(
    folder: Path, seed: int, effect: str | None, candidates, held_out: str = "free"
):
    """Reference axis `seed` with `effect` (its `held_out` design):
    `identified_then_diagnosed` on its runs; (the experiment, the diagnosis)."""
    exp = design_experiment(seed, effect, held_out=held_out)
    runs = {
        n: MeasuredData(n, r.t, r.u, r.omega, r.theta, None, exp.excitations[n].dt)
        for n, r in exp.runs.items()
    }
    return exp, identified_then_diagnosed(folder, runs, candidates)


def identified_reference(
    folder: Path, seed: int, held_out: str | None = None, options: tuple[str, ...] = ()
) -> tuple[dict, dict]:
    """`isp-twin generate --reference --seed seed` (clean; `held_out`: its
    --held-out design, default the command's) into `folder`, then
    `isp-twin identify` with defaults (and `options`) on train1 and train2,
    the held-out run given to --validate: (its --json content, the
    truth.yaml content)."""
    argv = [
        "generate",
        "--reference",
        "--seed",
        str(seed),
        "--effect",
        "none",
        "--out",
        str(folder),
    ]
    if held_out is not None:
        argv += ["--held-out", held_out]
    assert main(argv + ["--quiet"]) == 0
    js = folder / "id.json"
    argv = ["identify", str(folder / "train1.csv"), str(folder / "train2.csv")]
    argv += ["--out", str(folder / "p.yaml"), "--validate", str(folder / "heldout.csv")]
    assert main(argv + [*options, "--json", str(js), "--quiet", "--no-report"]) == 0
    return json.loads(js.read_text()), yaml.safe_load((folder / "truth.yaml").read_text())
