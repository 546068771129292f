"""The `sensor_bias` joint start where `identify`'s base did not converge on
the readings (`equation_error.sensor_bias_joint_starts`, `rounds._best_start`).

Reference sensor_bias seed 100 (the independent simulator; a bias of 17
noise sigmas, scale +1.05 %, on a 0.12 s axis, slow 0.34 Hz cosines): the
bias reads as motion wherever the axis rests, and `identify` leaves the
first training run at ~146 noise floors. The start that mapped that base
back to the true rate restarted to a bias 3.8x the measured one, and the
answer was `none` (sensor bias and a dead zone tentative, 62 noise floors
held out). This seed shaped the change: the test is a regression test; the
benchmark's other seeds are its validation (docs/diagnosis.md "Stop 37").
"""

from __future__ import annotations

import json
import math

import pytest
import yaml

from isp_twin.cli import main

SEED = 100


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    d = tmp_path_factory.mktemp("sb100")
    argv = ["generate", "--reference", "--seed", str(SEED), "--effect", "sensor_bias"]
    assert main([*argv, "--out", str(d), "--quiet"]) == 0
    argv = ["identify", str(d / "train1.csv"), str(d / "train2.csv"), "--out", str(d / "p.yaml")]
    assert main([*argv, "--no-report", "--quiet"]) == 0
    js = d / "diag.json"
    argv = ["diagnose", str(d / "train1.csv"), str(d / "train2.csv"), "--params", str(d / "p.yaml")]
    argv += ["--holdout", str(d / "heldout.csv"), "--json", str(js), "--no-recording"]
    # The rival that stood in for the bias at the old start, and one round.
    argv += ["--candidates", "sensor_bias,deadzone", "--max-rounds", "1"]
    assert main([*argv, "--out", str(d / "dg.yaml"), "--quiet"]) == 0
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    return json.loads(js.read_text()), truth


def test_the_gyro_error_is_found_where_identify_left_the_base_far_off(diagnosed):
    result, truth = diagnosed
    true = truth["effects"][0]["params"]
    assert result["selected_effect"] == "sensor_bias"
    fitted = result["effect_parameters"]
    assert fitted["bias_rad_s"] == pytest.approx(true["bias_rad_s"], rel=0.1)
    assert fitted["scale"] == pytest.approx(true["scale"], rel=0.1)


def test_the_held_out_error_reaches_the_effects_bound(diagnosed):
    result, truth = diagnosed
    sigma = truth["noise_sigma_deg_s"] * math.pi / 180.0
    assert result["rmse_after"] <= 1.5 * sigma
