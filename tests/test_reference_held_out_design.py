"""The reference's held-out designs (`isp_twin.reference.experiment`, stop 47).

``free`` draws the held-out run like the training runs; ``covered`` keeps it,
in each regime, within the speeds the training runs reach there. The seeds
below are clean axes whose free held-out run goes beyond the training runs
(by 2.3, 41 and 4.4 times in the worst regime): the covered design must
change exactly those, and leave a seed whose free run already stays within
(315) as it was.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from reference_benchmark import reference_benchmark

from isp_twin.cli import main
from isp_twin.errors import ParameterError
from isp_twin.reference import RUN_NAMES, design_experiment, regime_reach
from isp_twin.reference.experiment import MAX_ANGLE_DEG, MIN_MOVING, REACH_QUANTILE

BEYOND_SEEDS = (311, 313, 318)


def _reach_ratio(exp) -> np.ndarray:
    seen = regime_reach([exp.runs[n] for n in RUN_NAMES[:2]])
    return regime_reach([exp.runs["heldout"]]) / seen


@pytest.mark.parametrize("seed", BEYOND_SEEDS)
def test_free_goes_beyond_and_covered_stays_within_the_training_speeds(seed):
    free = design_experiment(seed)
    assert free.held_out == "free" and np.max(_reach_ratio(free)) > 1.5
    covered = design_experiment(seed, held_out="covered")
    assert covered.held_out == "covered"
    assert np.all(_reach_ratio(covered) <= 1.0)
    # still a qualifying run: every regime visited, within the angle limit
    held = covered.runs["heldout"]
    assert np.all(held.moving_per_regime() >= MIN_MOVING)
    assert np.max(np.abs(held.angle)) < np.radians(MAX_ANGLE_DEG)
    assert covered.excitations["heldout"].kind in ("multisine", "steps")


def test_covered_is_reproducible_and_leaves_a_run_already_within_unchanged():
    one, two = (design_experiment(313, held_out="covered") for _ in range(2))
    for name in RUN_NAMES:
        np.testing.assert_array_equal(one.runs[name].omega, two.runs[name].omega)
    free, covered = design_experiment(315), design_experiment(315, held_out="covered")
    assert np.max(_reach_ratio(free)) <= 1.0
    for name in RUN_NAMES:
        np.testing.assert_array_equal(free.runs[name].omega, covered.runs[name].omega)
    assert free.truth()["held_out_design"] == "free"
    assert covered.truth()["held_out_design"] == "covered"


def test_regime_reach_is_the_quantile_of_the_true_speed_per_regime():
    exp = design_experiment(315)
    run = exp.runs["train1"]
    reach = regime_reach([run])
    for k in range(4):
        speed = np.abs(run.rate[run.regime == k])
        assert reach[k] == pytest.approx(np.quantile(speed, REACH_QUANTILE))
    # pooled over two runs: between the two runs' own reaches
    pooled = regime_reach([run, exp.runs["train2"]])
    alone = np.stack([reach, regime_reach([exp.runs["train2"]])])
    assert np.all(pooled <= alone.max(axis=0) + 1e-12)
    assert np.all(pooled >= alone.min(axis=0) - 1e-12)


def test_an_unknown_design_is_refused():
    with pytest.raises(ParameterError, match="covred"):
        design_experiment(1, held_out="covred")


def test_cli_writes_the_design_into_the_truth(tmp_path, capsys):
    out = tmp_path / "ref"
    assert (
        main(
            ["generate", "--reference", "--seed", "311", "--held-out", "covered"]
            + ["--out", str(out)]
        )
        == 0
    )
    truth = yaml.safe_load((out / "truth.yaml").read_text())
    assert truth["held_out_design"] == "covered"


@pytest.mark.parametrize(
    "argv, names",
    [
        (["--reference", "--held-out", "covred"], ("covred", "covered")),
        (["--held-out", "covered"], ("--held-out", "--reference")),
    ],
)
def test_cli_refuses_a_wrong_design_in_one_line(tmp_path, capsys, argv, names):
    out = tmp_path / "ref"
    assert main(["generate", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(n in err for n in names)
    assert not out.exists()


def test_the_benchmark_table_names_the_design_and_says_when_it_pools_two():
    lines = reference_benchmark().design_lines
    assert lines([{"held_out_design": "covered"}] * 2) == ["held-out design: covered (2 axes)"]
    (line,) = lines([{"held_out_design": "covered"}, {}])
    assert "pools 2 designs" in line and "free (1 axes)" in line and "covered (1 axes)" in line
