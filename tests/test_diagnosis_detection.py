"""Data with an undeclared effect: the diagnosis must find it, with its
parameters, and reach the noise floor; data without one: "none".

Each case draws the effect's strength at random (seeded) from the physically
plausible ranges of `isp_twin.diagnosis.synthetic.EFFECT_RANGES`, generates
two training runs and one held-out run with the fast model plus gyro noise,
and diagnoses them with the paper's Table 2 parameters (which lack the
effect). To keep the suite fast each case tests its effect against the two
candidates most easily confused with it; the whole library is run on clean
data and on one effect.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from isp_twin.diagnosis.prepared_runs import LIBRARY
from isp_twin.diagnosis.search import diagnose as _diagnose
from isp_twin.diagnosis.synthetic import excitation, make_run, random_effect
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import EQ6
from isp_twin.resources import default_parameters_path

#: The runs are made by Eq. 6 itself (`axis_model`, gyro read at the sample):
#: diagnosed with Eq. 6 (m = 1) and that read-out.
diagnose = partial(_diagnose, integration=EQ6, timing=Timing())

DT = 1e-3
N = 2000
NOISE = 0.003

CONFUSERS = {
    "cogging": ("unbalance", "cable_spring"),
    "cable_spring": ("unbalance", "torque_offset"),
    "unbalance": ("cable_spring", "cogging"),
    "torque_offset": ("cable_spring", "deadzone"),
    "input_delay": ("lugre", "resonance"),
    "deadzone": ("lugre", "saturation"),
    "saturation": ("deadzone", "input_delay"),
    "sensor_bias": ("torque_offset", "deadzone"),
    "lugre": ("deadzone", "input_delay"),
    "resonance": ("input_delay", "lugre"),
}

#: Parameter -> (relative tolerance, absolute tolerance) of the recovered value.
TOLERANCE = {
    "amplitude_rad_s2": (0.15, 0.0),
    "period_rad": (0.01, 0.0),
    "stiffness_1_s2": (0.1, 0.0),
    "accel_rad_s2": (0.15, 0.0),
    "delay_s": (0.0, 3e-4),
    "width_digits": (0.1, 0.0),
    "limit_digits": (0.02, 0.0),
    "bias_rad_s": (0.0, 0.002),
    "scale": (0.0, 0.01),
    "presliding_rad": (0.25, 0.0),
    "freq_hz": (0.02, 0.0),
    "damping_ratio": (0.2, 0.0),
    "coupling": (0.1, 0.0),
}


@pytest.fixture(scope="module")
def params():
    return load_parameters(default_parameters_path())


def make_case(params, name, seed, n=N):
    rng = np.random.default_rng(seed)
    rate = params.axis("inner_az").rate_params()
    us = [excitation(rng, n, DT) for _ in range(3)]
    effect = random_effect(name, rng, us[0]) if name != "none" else None
    runs = [
        make_run(
            f"run{i}",
            rate,
            u,
            DT,
            rng,
            [effect] if effect else [],
            NOISE,
            angle0=rng.uniform(-0.2, 0.2),
        )
        for i, u in enumerate(us)
    ]
    return effect, runs[:2], runs[2:]


#: Held-out RMS error allowed after, in noise floors, where an effect needs
#: more than the 1.2 of issue 5 (none does since the effect-only polish of
#: `isp_twin.diagnosis.candidates`).
RMSE_FACTOR: dict[str, float] = {}


def check_found(diag, effect):
    j = diag.to_json()
    assert j["selected_effect"] == effect.name, j["ranking"]
    for k, truth in effect.params.items():
        rel, abs_ = TOLERANCE.get(k, (None, None))
        if rel is None:
            continue
        assert j["effect_parameters"][k] == pytest.approx(truth, rel=rel, abs=abs_), k
    assert j["noise_floor"] == pytest.approx(NOISE, rel=0.15)
    assert j["rmse_after"] <= RMSE_FACTOR.get(effect.name, 1.2) * j["noise_floor"]
    assert j["rmse_after"] < j["rmse_before"]


@pytest.mark.parametrize("name", [n for n in LIBRARY if n != "torque_offset"])
def test_an_undeclared_effect_is_found_with_its_parameters(params, name):
    effect, train, held = make_case(params, name, seed=LIBRARY.index(name) + 10)
    diag = diagnose(
        train, params, "inner_az", held, candidates=(name,) + CONFUSERS[name], max_rounds=1
    )
    check_found(diag, effect)


@pytest.mark.parametrize("seed", [6, 7])
def test_lugre_reaches_the_floor_on_other_seeds(params, seed):
    # Seed 6 needed more than 6 joint iterations (bristle force against the
    # Coulomb levels and alpha), seed 7 ends with alpha a few % off.
    effect, train, held = make_case(params, "lugre", seed=seed)
    diag = diagnose(
        train, params, "inner_az", held, candidates=("lugre",) + CONFUSERS["lugre"], max_rounds=1
    )
    check_found(diag, effect)


def test_a_torque_offset_is_found_or_absorbed_by_the_per_direction_friction(params):
    # A constant torque equals shifting Ts, Tc of the + regimes by -c and of
    # the - regimes by +c (Eq. 5): either explanation must reach the floor,
    # and if the effect is named its value must be right. Longer runs: the
    # offset trades off against the friction of every regime, so each must
    # be visited often enough in training to be pinned down.
    effect, train, held = make_case(params, "torque_offset", seed=13, n=3000)
    diag = diagnose(
        train,
        params,
        "inner_az",
        held,
        candidates=("torque_offset",) + CONFUSERS["torque_offset"],
        max_rounds=1,
    )
    j = diag.to_json()
    assert j["selected_effect"] in ("torque_offset", "none")
    if j["selected_effect"] == "torque_offset":
        assert j["effect_parameters"]["accel_rad_s2"] == pytest.approx(
            effect.params["accel_rad_s2"], rel=0.2
        )
    else:
        assert j["refit_adopted"]
    assert j["rmse_after"] <= 1.2 * j["noise_floor"]


@pytest.mark.parametrize("seed", [1, 2])
def test_clean_data_gives_none_with_the_whole_library(params, seed):
    _, train, held = make_case(params, "none", seed)
    diag = diagnose(train, params, "inner_az", held, max_rounds=1)
    j = diag.to_json()
    assert j["selected_effect"] == "none", j["ranking"]
    assert not j["refit_adopted"]
    assert diag.params_out is params
    assert j["rmse_after"] <= 1.2 * j["noise_floor"]


def test_the_whole_library_picks_the_right_effect_and_then_stops(params):
    effect, train, held = make_case(params, "deadzone", seed=21)
    diag = diagnose(train, params, "inner_az", held, max_rounds=2)
    check_found(diag, effect)
    assert [r.selected for r in diag.rounds] == ["deadzone", "none"]
    assert [e.name for e in diag.params_out.axis("inner_az").effects] == ["deadzone"]
