"""The compiled closed loop against the Python blocks it stands for: the same bits, the same errors."""

import dataclasses

import numpy as np
import pytest

from isp_twin.errors import SimulationDiverged
from isp_twin.experiments import closed_loop_kernel as kernel
from isp_twin.experiments.closed_loop import ClosedLoop
from isp_twin.experiments.scenario import parse_scenario
from isp_twin.model import friction
from isp_twin.model.parameters import EffectSpec, load_parameters
from isp_twin.resources import default_parameters_path

BASE = {
    "duration_s": 1.5,
    "metrics": {"skip_s": 0.5},
    "turntable": {
        "table_yaw": {"rate_amplitude_deg_s": 3.141592653589793, "freq_hz": 0.5},
        "table_pitch": {"amplitude_deg": 3.0, "freq_hz": 1.0, "waveform": "cosine"},
    },
    "controller": {"inner_az": {"nfc": {"enabled": True}}, "inner_el": {"nfc": {"enabled": True}}},
}

# Every switch of the blocks: notch off, NFC off / with a rest band and other
# taps, a slow noiseless gyro, a long resolver window, followers off, a start
# away from zero (both half-planes of the NFC and of the friction).
VARIANTS = {
    "paper_like": {},
    "switches": {
        "controller": {
            "inner_az": {"notch": {"enabled": False}, "nfc": {"enabled": True, "taps": 7}},
            "inner_el": {"nfc": {"enabled": True, "rest_rate_deg_s": 0.05}},
        },
        "gyro": {"sample_every": 3, "noise_deg_s": 0.0, "bandwidth_hz": 80.0},
        "resolver": {"rate_window": 3},
        "follower": {"enabled": False},
        "initial_angles_deg": {"inner_az": -1.0, "inner_el": 0.5, "outer_az": 2.0},
    },
    "parallel_pi": {
        "controller": {"inner_az": {"pi_form": "parallel"}, "inner_el": {"pi_form": "parallel"}},
    },
    "pi_only_following_off_centre": {
        "controller": {"inner_az": {"nfc": {"enabled": False}}},
        "follower": {"inner_az_center_deg": 0.3, "kd_digit_per_deg_s": 5.0},
        "initial_angles_deg": {"inner_az": 0.8, "outer_el": -3.0},
        "seed": 5,
    },
}


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for key, value in extra.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and key in out else value
    return out


def _both(raw: dict, **kwargs):
    scenario = parse_scenario(raw, "k.yaml")
    fast = ClosedLoop(scenario, compiled=True, **kwargs)
    slow = ClosedLoop(scenario, compiled=False, **kwargs)
    return fast, slow


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_the_compiled_loop_gives_the_python_loops_bits(variant):
    fast, slow = _both(_merge(BASE, VARIANTS[variant]))
    assert fast.compiled and not slow.compiled
    fast.run()
    slow.run()
    assert np.array_equal(fast.buffer, slow.buffer)
    assert fast.result().metrics == slow.result().metrics
    # the twin is left in the same state: the Python view of it agrees too
    assert fast.twin.sense() == slow.twin.sense()


def test_a_drawn_plant_with_the_nominal_nfc_model_gives_the_same_bits():
    nominal = load_parameters(default_parameters_path())
    ax = nominal.axis("inner_az")
    r0 = dataclasses.replace(ax.regimes[0], Ts=ax.regimes[0].Ts * 1.3)
    plant = nominal.with_axis("inner_az", dataclasses.replace(ax, regimes=(r0, *ax.regimes[1:])))
    fast, slow = _both(BASE, params=plant, nfc_params=nominal, seed=3)
    fast.run()
    slow.run()
    assert np.array_equal(fast.buffer, slow.buffer)


def test_stepping_one_sample_at_a_time_and_in_chunks_gives_the_same_bits():
    fast, slow = _both(BASE)
    slow.run()
    for stop in (1, 2, 3, 500, 777):
        while fast.done < stop:
            fast.step()
    fast.run()
    assert np.array_equal(fast.buffer, slow.buffer)
    fast.reset()
    fast.run()
    assert np.array_equal(fast.buffer, slow.buffer)


@pytest.mark.parametrize(
    "controller, message",
    [
        ({"pi": {"kp_digit_per_count": 1e6}, "bound_digits": 1e9}, r"diverged at t="),
        ({"pi": {"kp_digit_per_count": 1000.0}}, r"unstable at t="),
        ({"pi": {"kp_digit_per_count": 1e10}, "bound_digits": 1e15}, r"twin diverged at t="),
    ],
)
def test_a_runaway_stops_both_loops_at_the_same_sample_with_the_same_message(controller, message):
    # BASE runs PI+NFC: its gains are the ``pi_nfc`` ones
    raw = _merge(BASE, {"controller": {"inner_az": {**controller, "pi_nfc": controller["pi"]}}})
    fast, slow = _both(raw)
    errors = []
    for loop in (fast, slow):
        with pytest.raises(SimulationDiverged, match=message) as info:
            loop.run()
        errors.append(str(info.value))
    assert errors[0] == errors[1]
    assert fast.done == slow.done
    assert np.array_equal(fast.buffer[: fast.done], slow.buffer[: slow.done])


def test_a_plant_with_effects_runs_the_python_blocks():
    params = load_parameters(default_parameters_path())
    ax = params.axis("inner_az")
    spec = EffectSpec("torque_offset", {"accel_rad_s2": 0.01})
    params = params.with_axis("inner_az", dataclasses.replace(ax, effects=(spec,)))
    loop = ClosedLoop(parse_scenario(BASE, "k.yaml"), params=params)
    assert not loop.compiled


def test_a_step_mujoco_rejects_stops_both_loops_with_the_same_message(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT here
    errors = []
    for loop in _both(BASE):
        for _ in range(100):
            loop.step()
        # a non-finite turntable drive: qacc turns NaN and MuJoCo resets the data
        yaw_drive = loop.twin.arrays().index[loop.twin.INDEX["table_act"][0]]
        loop.twin.model.actuator_gear[yaw_drive, 0] = np.nan
        with pytest.raises(SimulationDiverged, match="MuJoCo rejected the accelerations") as info:
            loop.run()
        errors.append((str(info.value), loop.done))
    assert errors[0] == errors[1]


def test_the_compiled_friction_law_is_friction_py_bit_for_bit():
    cases = kernel.law_probe_cases()
    compiled = kernel._law_probe(cases)
    assert set(compiled[:, 1].tolist()) == {0.0, 1.0, 2.0, 3.0}  # every regime probed
    assert np.array_equal(compiled, kernel.python_law(cases))
    assert kernel.compiled_law_is_current()


def test_an_edit_to_friction_py_makes_the_cached_kernels_stale(monkeypatch):
    # What the import-time check sees when friction.py changed after the
    # kernels were cached: the Python law no longer matches the compiled one.
    law = friction.stribeck
    monkeypatch.setattr(friction, "stribeck", lambda *args: law(*args) * (1 + 1e-12))
    assert not kernel.compiled_law_is_current()
