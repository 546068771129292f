"""The side change inside a sub-step as the default model (docs/diagnosis.md "Stop 38").

Reference seed 102 (a 111 ms axis, gyro noise 0.013 deg/s, the lowest of
benchmark seeds 100-104) with an input delay: read at the sub-step's start,
the regime switch lags the angle's zero crossing, and on so quiet an axis
the lag alone reads 1.4 gyro sigmas on a training run with the true
parameters. The fits then bend the friction levels, or move the half-plane
read-out, to absorb it. Seed 102 is the axis that shaped the change (its
misses in the stop 37 benchmark); these tests pin it, they do not validate it.
"""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
import yaml
from truth_error import truth_error

from isp_twin.cli import main
from isp_twin.model.parameters import (
    EffectSpec,
    load_parameters,
    save_parameters,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION
from isp_twin.resources import default_parameters_path

SEED = 102
EFFECT = "input_delay"


def test_the_default_model_holds_the_truth_of_a_quiet_axis_at_the_noise():
    assert DEFAULT_INTEGRATION.split_sides
    before = truth_error(SEED, EFFECT, replace(DEFAULT_INTEGRATION, split_sides=False))
    after = truth_error(SEED, EFFECT, DEFAULT_INTEGRATION)
    assert max(before) > 1.3
    assert max(after) < 1.05


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """`identify` with defaults on the two training runs, the true delay held
    (the prior file's ``effects:``), judged on the held-out run."""
    d = tmp_path_factory.mktemp("quiet")
    argv = ["generate", "--reference", "--seed", str(SEED), "--effect", EFFECT, "--out", str(d)]
    assert main(argv + ["--quiet"]) == 0
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    params = load_parameters(default_parameters_path())
    held = tuple(EffectSpec(e["name"], e["params"]) for e in truth["effects"])
    axis = replace(params.axis("inner_az"), effects=held)
    prior = save_parameters(params.with_axis("inner_az", axis), d / "prior.yaml")
    js = d / "id.json"
    argv = ["identify", str(d / "train1.csv"), str(d / "train2.csv"), "--prior", str(prior)]
    argv += ["--validate", str(d / "heldout.csv"), "--out", str(d / "p.yaml"), "--json", str(js)]
    assert main(argv + ["--quiet", "--no-report"]) == 0
    return json.loads(js.read_text()), truth


def test_identify_with_the_true_delay_held_reaches_the_noise_held_out(identified):
    # Without the split the fit reached the noise on the training runs but
    # 1.9 noise floors held out: a breakaway level of the left side moved
    # to absorb the lag decided a stick on the held-out run.
    result, _ = identified
    per_set = result["verdict"]["per_set"]
    assert per_set["heldout"]["role"] == "held_out"
    assert all(s["rmse_over_noise_floor"] <= 1.3 for s in per_set.values())


def test_the_half_plane_is_read_where_the_reference_switches(identified):
    # The reference switches the regime at the crossing itself: read-out
    # without a shift. Unsplit, identify chose a quarter-step shift as a
    # stand-in for the lag.
    result, truth = identified
    assert result["timing"]["side_shift_steps"] == 0.0
    assert result["timing"]["gyro_average"] == truth["sensors"]["gyro_averaged"]
