"""The alike restart's start (`rounds._matched_start`): the other effect of
an alike pair matched to the leader's acceleration over the training angles.

Properties: a leader matched to its own kind gives its own parameters back
(the class's `guesses` are exact on noiseless data of their own form); over a
small travel an unbalance ``A sin(y + phi)`` matched to a spring has the
spring's local slope ``k = -A cos(phi)`` up to the travel's curvature; the
matched start stays inside the effect's bounds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isp_twin.diagnosis.candidates import BASELINE, CandidateFit
from isp_twin.diagnosis.rounds import _matched_start
from isp_twin.estimation.simulation_error import RunStack
from isp_twin.model.effects import effect_class


def _stack(travel: float) -> RunStack:
    t = np.arange(2000) * 1e-3
    angle = travel * np.sin(2 * np.pi * 1.0 * t)[None]  # two whole cycles
    omega = np.gradient(angle[0], 1e-3)[None]
    mask = np.ones_like(angle, bool)
    mask[:, 0] = False
    return RunStack(("r",), np.zeros_like(angle), omega, angle, mask, 1e-3)


def _leader(name: str, params: dict) -> CandidateFit:
    assert name != BASELINE
    return CandidateFit(
        name=name,
        params=params,
        ci95={},
        rate_vector=np.zeros(20),
        rate_ci95=np.zeros(20),
        sse=0.0,
        n_samples=1,
        n_params=1,
        bic=0.0,
        status=None,
    )


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("unbalance", {"amplitude_rad_s2": 7.0, "phase_rad": 2.4}),
        ("unbalance", {"amplitude_rad_s2": 0.3, "phase_rad": -1.1}),
        ("cable_spring", {"stiffness_1_s2": 12.0, "offset_rad_s2": -0.8}),
    ],
)
def test_an_effect_matched_to_its_own_kind_gives_its_parameters_back(name, params):
    got = _matched_start(_stack(0.4), _leader(name, params), name)
    if name == "unbalance":
        assert got["amplitude_rad_s2"] == pytest.approx(params["amplitude_rad_s2"], rel=1e-9)
        assert math.remainder(got["phase_rad"] - params["phase_rad"], 2 * math.pi) == (
            pytest.approx(0.0, abs=1e-9)
        )
    else:
        assert got == pytest.approx(params, rel=1e-9)


@pytest.mark.parametrize("phase", [0.3, 2.4, -2.0])
def test_a_small_travel_unbalance_matches_the_spring_of_its_local_slope(phase):
    amp, travel = 5.0, 0.02
    got = _matched_start(
        _stack(travel),
        _leader("unbalance", {"amplitude_rad_s2": amp, "phase_rad": phase}),
        "cable_spring",
    )
    # accel ~ A sin(phi) + A cos(phi) y: offset A sin(phi), stiffness -A cos(phi),
    # the next term (A/2) sin(phi) y^2 of relative size travel^2.
    assert got["stiffness_1_s2"] == pytest.approx(-amp * math.cos(phase), abs=amp * travel**2)
    assert got["offset_rad_s2"] == pytest.approx(amp * math.sin(phase), abs=amp * travel**2)


def test_the_matched_start_stays_inside_the_bounds():
    # A spring far stronger than any unbalance the bounds allow.
    got = _matched_start(
        _stack(0.01),
        _leader("cable_spring", {"stiffness_1_s2": 4000.0, "offset_rad_s2": 0.0}),
        "unbalance",
    )
    lo, hi = effect_class("unbalance").bounds["amplitude_rad_s2"]
    assert lo <= got["amplitude_rad_s2"] <= hi
