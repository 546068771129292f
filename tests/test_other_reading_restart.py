"""The least squares again at the other gyro reading (`fit._other_reading_restart`),
docs/identification.md "Stop 42".

Reference clean seed 237 (a 7.8 ms axis whose gyro averages over the sample)
shaped it: with the breakaway's midpoint friction the third of the budget
spent from the start at each reading ended lower at the point reading, the
whole budget went there, and the fit stopped at 1.30/1.73 noise floors on
the training runs. This test pins that axis; it does not validate the
stage (the benchmark in the docs does, on other seeds).
"""

from __future__ import annotations

from identified_runs import identified_reference


def test_the_fit_of_seed_237_moves_to_the_averaged_reading_and_the_noise(tmp_path):
    result, truth = identified_reference(tmp_path, 237)
    assert truth["sensors"]["gyro_averaged"]
    assert "least squares at gyro rate averaged over the sample" in result["status"]
    assert result["timing"]["gyro_average"] is True
    per_set = result["verdict"]["per_set"]
    assert per_set["train1"]["rmse_over_noise_floor"] <= 1.1
    assert per_set["train2"]["rmse_over_noise_floor"] <= 1.1


def test_at_the_noise_a_probe_at_the_averaged_reading_moves_seed_349_there(tmp_path):
    """Reference clean seed 349 (the benchmark's held-out design) shaped the
    probe (`fit.PROBE_EVALUATIONS`, docs/identification.md "Stop 54"): the
    fit ended at the point reading within `NEAR_NOISE` (1.025/1.022 truth
    sigmas on training), 2.17 sigmas held out; the truth reads 1.01 there."""
    result, truth = identified_reference(tmp_path, 349, held_out="covered")
    assert truth["sensors"]["gyro_averaged"]
    assert result["timing"]["gyro_average"] is True
    sigma = truth["noise_sigma_deg_s"]
    assert result["rmse_validation"]["heldout"] / sigma <= 1.1
    for name in ("train1", "train2"):
        assert result["rmse_train"][name] / sigma <= 1.05
