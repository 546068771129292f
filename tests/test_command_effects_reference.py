"""A dead zone, an input delay and a saturation found by `diagnose` on data
its own code did not make: axes of the independent reference simulator (`isp_twin.reference`),
identified with defaults, then diagnosed with the command-side candidates.

The seeds (1000 with each effect) are development seeds of issue 8: they
shaped the read-out retry of `isp_twin.diagnosis.search` (docs/diagnosis.md,
"Command effects and the read-out"), and saturation 1000 the global refit
of a leading saturation (stop 18: it answered `none` before; this pins the
fix, it does not validate it); the benchmark seeds 0-39 shaped nothing. The bounds are the issue's: the right effect, the width within 10 %
(the delay within one sample), the held-out error after within 1.5 noise
sigmas of the truth. The candidates are the three command-side effects
(each must not be mistaken for the others): the whole library costs a
minute per axis.

The dead zone's axis is identified with ``--no-split-sides``, the model the
read-out retry was shaped with. With the default since stop 38 (the side
change split inside the sub-step) its dead zone still leads the first
round, its width within 1 %, and at the averaged read-out the training
runs are at the noise; but held out it reads 1.53 noise floors (1.40
unsplit), so it is tentative (an input delay beside it at the file's
point read-out) and the answer `none`. The training runs do not pin its Stribeck
levels (the fit's training cost is below the truth's, docs/diagnosis.md
"Stop 34"): where the held-out error lands in that flat valley is not a
property of the split. This pins the retry, not the default model's answer
on that axis (docs/diagnosis.md "Stop 38").
"""

from __future__ import annotations

import json
import math

import pytest
import yaml

from isp_twin.cli import main
from isp_twin.estimation.verdict import CONVERGED_RATIO

SEED = "1000"


@pytest.fixture(scope="module", params=["deadzone", "input_delay", "saturation"])
def diagnosed(request, tmp_path_factory):
    effect = request.param
    d = tmp_path_factory.mktemp(effect)
    argv = ["generate", "--reference", "--seed", SEED, "--effect", effect, "--out", str(d)]
    assert main(argv + ["--quiet"]) == 0
    argv = ["identify", str(d / "train1.csv"), str(d / "train2.csv")]
    argv += ["--out", str(d / "p.yaml"), "--quiet", "--no-report"]
    argv += ["--no-split-sides"] if effect == "deadzone" else []
    assert main(argv) == 0
    js = d / "diag.json"
    argv = ["diagnose", str(d / "train1.csv"), str(d / "train2.csv"), "--params", str(d / "p.yaml")]
    argv += ["--holdout", str(d / "heldout.csv"), "--json", str(js), "--no-recording"]
    argv += ["--out", str(d / "new.yaml"), "--candidates", "deadzone,input_delay,saturation"]
    assert main(argv + ["--quiet"]) == 0
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    return effect, json.loads(js.read_text()), truth, d


def test_the_command_effect_is_found_at_the_noise(diagnosed):
    effect, result, truth, _ = diagnosed
    assert result["selected_effect"] == effect
    sigma = truth["noise_sigma_deg_s"] * math.pi / 180
    assert result["rmse_after"] <= CONVERGED_RATIO * sigma


def test_the_command_effect_parameter_is_recovered(diagnosed):
    effect, result, truth, _ = diagnosed
    true = truth["effects"][0]["params"]
    fitted = result["effect_parameters"]
    if effect == "deadzone":
        assert fitted["width_digits"] == pytest.approx(true["width_digits"], rel=0.10)
    elif effect == "saturation":
        assert fitted["limit_digits"] == pytest.approx(true["limit_digits"], rel=0.10)
    else:
        assert abs(fitted["delay_s"] - true["delay_s"]) <= truth["sample_time_s"]


def test_the_output_file_records_the_read_out_the_effect_was_fitted_with(diagnosed):
    """The read-out may differ from the one `identify` chose for the base
    model (a gyro averaging over the sample): the output file records the
    model the effect was fitted with, so the twin reads it the same way."""
    effect, result, _, d = diagnosed
    new = yaml.safe_load((d / "new.yaml").read_text())["axes"]["inner_az"]
    assert [e["name"] for e in new["effects"]] == [effect]
    assert new["fitted_with"]["gyro_average"] == result["timing"]["gyro_average"]
