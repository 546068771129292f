"""One gyro, one error: the fusion corrects the reading only where the runs agree on it.

The angle fusion corrects the rate reading for a gyro bias and scale error
it measures against the resolver (`reading_error`). A gyro on a flexible
payload reads the payload's rate, whose integral differs from the motor
side's angle by the deflection; a cosine makes that proportional to the
angle, a "scale error" that changes with the run's frequency. Where the
runs of one command disagree on it, nothing is corrected
(`isp_twin.identification.gyro_error.one_gyro_error`; docs/identification.md
"Stop 80"). Data from the reference simulator, which shares no code with
the model.
"""

from __future__ import annotations

import numpy as np
from reference_axes import FAST_AXIS
from truth_error import true_rate_params

from isp_twin.identification.cost import rmse
from isp_twin.identification.gyro_error import (
    GyroError,
    _agree,
    fusion_json,
    one_gyro_error,
)
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.identification.side_angle import fused_angle
from isp_twin.model.parameters import EffectSpec
from isp_twin.reference import Sensors, simulate
from isp_twin.reference import effects as ref

AXIS = FAST_AXIS
SIGMA = 2.5e-4  # gyro noise [rad/s]
SENSORS = Sensors(gyro_noise_rad_s=SIGMA, gyro_averaged=True, resolver_bits=14)
LSB = 2.0 * np.pi / 2**14
PAYLOAD = ref.PayloadMode(0.17, 15.6, 0.005)  # a 20 Hz free mode
#: Two Eq. 7-style cosines (frequency [Hz], amplitude [digits]) with an offset.
RUNS = ((1.5, 700.0), (5.0, 900.0))


def _runs(effect, seed: int):
    t = np.arange(5000) * 1e-3
    out, angles = [], []
    for i, (f, a) in enumerate(RUNS):
        r = simulate(
            AXIS, 100.0 + a * np.cos(2.0 * np.pi * f * t), [effect], SENSORS, seed=seed + i
        )
        out.append(MeasuredData(f"run{i}", r.t, r.u, r.omega, r.theta, None, 1e-3))
        angles.append(r.angle)
    return out, angles


def test_a_payload_makes_the_runs_disagree_and_its_truth_reaches_near_the_noise():
    spec = (EffectSpec("resonance", PAYLOAD.truth(AXIS.inertia_kg_m2)),)
    truth = true_rate_params(AXIS)
    for seed in (0, 10, 20):
        runs, _ = _runs(PAYLOAD, seed)
        one = one_gyro_error(runs)
        assert not any(d.gyro_error_fused for d in one), seed

        def error(d):
            return float(rmse(truth, [d], effects=spec, timing=Timing(0.0, True))) / SIGMA

        # Corrected by the payload's "scale error" (+0.9 % at 1.5 Hz, +10 %
        # at 5 Hz), the slow run's truth stands at about 110 sigmas.
        assert error(runs[0]) > 20.0, seed
        assert max(error(d) for d in one) < 2.0, seed


def test_a_gyro_error_the_runs_agree_on_is_corrected():
    gyro = ref.GyroError(0.002, -0.03)
    for seed in (0, 10, 20):
        runs, angles = _runs(gyro, seed)
        one = one_gyro_error(runs)
        assert all(d.gyro_error_fused for d in one), seed
        for d, angle in zip(one, angles):
            assert np.max(np.abs(fused_angle(d, anchored=False) - angle)) < 0.5 * LSB, seed


def _estimate(scale: float, bias: float, scale_ci: float = 1e-4, bias_ci: float = 1e-5):
    return GyroError(bias, scale, bias_ci, scale_ci, 0.0, 1e-4)


def test_estimates_agree_unless_apart_both_by_their_errors_and_by_a_share():
    base = _estimate(-0.0300, 0.0030)
    # Six standard errors apart but 1 % of the scale: one gyro.
    assert _agree([base, _estimate(-0.0303, 0.0030)])
    # Half the scale, far beyond the errors: not one gyro.
    assert not _agree([base, _estimate(-0.0150, 0.0030)])
    # Half the scale, within the errors: one gyro.
    assert _agree([base, _estimate(-0.0150, 0.0030, scale_ci=0.02)])
    # The bias alone apart.
    assert not _agree([base, _estimate(-0.0300, 0.0060)])
    # Any pair of three.
    assert not _agree([base, base, _estimate(-0.0150, 0.0030)])


def test_fewer_than_two_readable_runs_change_nothing():
    runs, _ = _runs(PAYLOAD, 0)
    assert one_gyro_error(runs[:1])[0].gyro_error_fused
    still = MeasuredData(
        "still", runs[0].t, runs[0].u, runs[0].omega, 0.0 * runs[0].angle, None, 1e-3
    )
    assert all(d.gyro_error_fused for d in one_gyro_error([runs[0], still]))


def test_both_commands_record_in_their_json_that_the_fusion_left_the_reading(tmp_path):
    import json

    from isp_twin.cli import main
    from isp_twin.identification.measured import save_measured

    runs, _ = _runs(PAYLOAD, 0)
    files = [str(save_measured(d, tmp_path / f"run{i}.csv")) for i, d in enumerate(runs)]
    params, summary = tmp_path / "p.yaml", tmp_path / "id.json"
    argv = ["identify", *files, "--out", str(params), "--no-report", "--quiet"]
    argv += ["--generations", "0", "--refine-evaluations", "5", "--json", str(summary)]
    assert main(argv) == 0
    diagnosed = tmp_path / "diag.json"
    argv = ["diagnose", files[0], "--holdout", files[1], "--params", str(params)]
    argv += ["--candidates", "sensor_bias", "--max-rounds", "1", "--iterations", "2"]
    argv += ["--no-recording", "--quiet", "--json", str(diagnosed)]
    argv += ["--report", str(tmp_path / "report")]
    assert main(argv) == 0
    for path in (summary, diagnosed):
        said = json.loads(path.read_text())
        assert said["angle_fusion_corrects_gyro_error"] is False, path.name
        assert "payload" in said["angle_fusion_note"], path.name


def test_the_json_says_the_fusion_corrects_where_the_runs_agree():
    runs, _ = _runs(ref.GyroError(0.002, -0.03), 0)
    said = fusion_json(one_gyro_error(runs))
    assert said == {"angle_fusion_corrects_gyro_error": True, "angle_fusion_note": None}
