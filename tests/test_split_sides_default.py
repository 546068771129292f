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

import numpy as np
import pytest
import yaml

from isp_twin.cli import main
from isp_twin.identification.cost import rmse
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    EffectSpec,
    RateParams,
    load_parameters,
    save_parameters,
)
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.reference import design_experiment
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG

SEED = 102
EFFECT = "input_delay"


def _truth_error(integration: Integration) -> list[float]:
    """The library with the reference's true parameters: RMS error over the
    gyro sigma per run (train1, train2, held-out)."""
    exp = design_experiment(SEED, EFFECT)
    truth = exp.truth()
    regimes = truth["rate_form"]["regimes"]
    x = np.concatenate([[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    effects = [EffectSpec(e["name"], e["params"]) for e in truth["effects"]]
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    sigma = truth["noise_sigma_deg_s"] * DEG
    out = []
    for name, r in sorted(exp.runs.items()):
        data = [MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])]
        e = rmse(RateParams.from_vector(x), data, effects=effects, timing=timing,
                 integration=integration)  # fmt: skip
        out.append(float(e) / sigma)
    return out


def test_the_default_model_holds_the_truth_of_a_quiet_axis_at_the_noise():
    assert DEFAULT_INTEGRATION.split_sides
    before = _truth_error(replace(DEFAULT_INTEGRATION, split_sides=False))
    after = _truth_error(DEFAULT_INTEGRATION)
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
