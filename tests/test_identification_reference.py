"""Identification judged on data its own code did not make: an axis of the
independent reference simulator (`isp_twin.reference`), far from Table 2,
identified with defaults and no prior in the search.

Seed 0 was picked after identifying reference seeds 0-5 (training at the noise
on 0, 1, 4; not on 2, 3, 5; held out at the noise on none of them, see
docs/identification.md): this test pins the behaviour on one axis, the rates
over many axes are the benchmark's (`benchmarks/identify_reference.py`).
Since the sub-stepped model (issue 8) the held-out run of this axis is at the
noise too, and the issue's bound (1.3 noise sigmas for clean data) is asserted
on it.
"""

from __future__ import annotations

import json
import math

import pytest
import yaml

from isp_twin.cli import main
from isp_twin.estimation.verdict import CONVERGED_RATIO


def _strict(text: str) -> dict:
    def refuse(token):
        raise ValueError(f"not JSON: {token}")

    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref0")
    assert main(["generate", "--reference", "--seed", "0", "--out", str(d), "--quiet"]) == 0
    out = d / "p.yaml"
    js = d / "p.json"
    argv = ["identify", str(d / "train1.csv"), str(d / "train2.csv")]
    argv += ["--validate", str(d / "heldout.csv"), "--out", str(out), "--json", str(js)]
    assert main(argv + ["--quiet", "--no-report"]) == 0
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    return _strict(js.read_text()), truth, d


def test_diagnose_finds_no_effect_on_the_clean_reference_axis(identified):
    """Issue 8: on clean data `diagnose` answers none, at the noise. The
    candidates are the three the issue saw reported on clean reference axes
    (a false input delay, cogging) and the cable spring (a base-model error
    that varies with the angle): the whole library costs a minute."""
    _, truth, d = identified
    js = d / "diag.json"
    argv = ["diagnose", str(d / "train1.csv"), str(d / "train2.csv"), "--params", str(d / "p.yaml")]
    argv += ["--holdout", str(d / "heldout.csv"), "--json", str(js), "--no-recording"]
    argv += ["--report", str(d / "report"), "--candidates", "input_delay,cogging,cable_spring"]
    assert main(argv + ["--quiet"]) == 0
    result = _strict(js.read_text())
    assert result["selected_effect"] == "none"
    assert result["rmse_after"] <= 1.3 * truth["noise_sigma_deg_s"] * math.pi / 180


def test_training_error_is_at_the_reference_noise_without_the_papers_prior(identified):
    summary, truth, _ = identified
    sigma = truth["noise_sigma_deg_s"]
    for name, rmse_deg_s in summary["rmse_train"].items():
        assert rmse_deg_s <= 1.3 * sigma, name
    # ...and on the held-out run of another excitation (issue 8's bound).
    assert summary["rmse_validation"]["heldout"] <= 1.3 * sigma
    # The data's own noise floor estimate is the truth's noise.
    assert summary["noise_floor_deg_s"] == pytest.approx(sigma, rel=0.05)


def test_the_verdict_states_every_set_against_its_noise_floor(identified):
    summary, _, _ = identified
    v = summary["verdict"]
    assert set(v["per_set"]) == {"train1", "train2", "heldout"}
    ratios = [s["rmse_over_noise_floor"] for s in v["per_set"].values()]
    assert summary["rmse_over_noise_floor"] == pytest.approx(max(ratios))
    assert summary["converged"] is (max(ratios) <= CONVERGED_RATIO)
    if summary["converged"]:
        assert v["advice"] == ""
    else:
        assert "diagnose" in v["advice"]


def test_a_coulomb_level_at_zero_in_the_start_is_moved_inside():
    """`interior_start`: a b·Tc the bounded equation-error fit left at (near) 0
    starts at half the static level (its log-variable has a gradient there);
    every other quantity, and a b·Tc away from 0, is kept as it is."""
    import numpy as np

    from isp_twin.identification.search_space import interior_start
    from isp_twin.model.parameters import RATE_LAYOUT

    table = np.array(
        [
            [0.99, 1e-6, 3e-4, 1e-12, 40.0],  # Tc at the bound: lifted
            [0.99, 1e-6, 3e-4, 2.9e-6, 40.0],  # Tc < 1 % of Ts: lifted
            [0.99, 1e-6, 3e-4, 1e-4, 40.0],  # kept
            [0.80, 1e-4, 2e-2, 2e-2, 100.0],  # Tc = Ts: kept
        ]
    )
    out = RATE_LAYOUT.as_table(interior_start(RATE_LAYOUT.from_table(table)))
    coulomb = RATE_LAYOUT.field_index("coulomb")
    np.testing.assert_array_equal(out[:, coulomb], [1.5e-4, 1.5e-4, 1e-4, 2e-2])
    others = [i for i in range(RATE_LAYOUT.n_fields) if i != coulomb]
    np.testing.assert_array_equal(out[:, others], table[:, others])


def test_a_slow_reference_axis_whose_start_has_no_coulomb_level_reaches_the_noise(
    tmp_path,
):
    """Regression on dev axis 1002 (time constant 0.34 s; it shaped
    `interior_start`, so this pins the fix, it does not validate it): the
    equation-error start put b·Tc of two regimes at 0 and the least squares
    ran out of budget with the Stribeck curve of R+ off (held-out 3.6 noise
    sigmas). Started inside, train and held-out are within issue 8's 1.3."""
    d = tmp_path
    assert main(["generate", "--reference", "--seed", "1002", "--out", str(d), "--quiet"]) == 0
    js = d / "p.json"
    argv = ["identify", str(d / "train1.csv"), str(d / "train2.csv")]
    argv += ["--validate", str(d / "heldout.csv"), "--out", str(d / "p.yaml"), "--json", str(js)]
    assert main(argv + ["--quiet", "--no-report"]) == 0
    summary = _strict(js.read_text())
    sigma = yaml.safe_load((d / "truth.yaml").read_text())["noise_sigma_deg_s"]
    for name, rmse_deg_s in summary["rmse_train"].items():
        assert rmse_deg_s <= 1.3 * sigma, name
    assert summary["rmse_validation"]["heldout"] <= 1.3 * sigma
