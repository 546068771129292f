"""Round 1's training leader gets `identify`'s global step after a leading
command effect took one and left nothing significant at the noise
(`rounds._training_leader_too`): benchmark unbalance seed 1, where a
saturation took the step and lost its significance, and the unbalance (0.12
of the base's training cost, 13.7 noise floors held out) was never refitted
(docs/diagnosis.md "Stop 29"). Not where a significant candidate already
fits the training runs at the noise: reference resonance seed 449, the
resonance at 1.06 noise floors on training, 4.06 held out (stop 82)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from round_state_double import RoundStateDouble, fit_double

from isp_twin.diagnosis import rounds


def _verdict(name, significant):
    return SimpleNamespace(name=name, significant=significant)


def _state(saturation_held=12.0, saturation_training=3.0):
    fits = {
        "saturation": fit_double("saturation", sse=0.156, bic=-133565.0),
        "unbalance": fit_double("unbalance", sse=0.021, bic=-157170.0),
        "cogging": fit_double("cogging", sse=0.171, bic=-132444.0),
    }
    held = {"saturation": [np.full(50, saturation_held)], "unbalance": [np.full(50, 13.7)],
            "cogging": [np.full(50, 12.4)]}  # fmt: skip
    # The double's floor is 1: the saturation's training RMS error in noise floors.
    fits["saturation"].rmse = saturation_training
    st = RoundStateDouble(fits, held, fit_double("base", sse=0.182, bic=-131757.0))
    st.base_held = [np.full(50, 12.8)]
    return st


@pytest.fixture
def stages(monkeypatch):
    """`_torque_global_stage` recorded; every fit can be the effect."""
    called = []

    def stage(data, st, verdicts, starts, top):
        called.append(top)
        return verdicts + [top]

    monkeypatch.setattr(rounds, "_torque_global_stage", stage)
    monkeypatch.setattr(rounds, "_not_the_effect", lambda data, st, name: "")
    return called


def test_the_training_leader_gets_its_global_step(stages):
    verdicts = [_verdict("saturation", False), _verdict("unbalance", False)]
    out = rounds._training_leader_too(None, _state(), verdicts, {})
    assert stages == ["unbalance"]
    assert out[-1] == "unbalance"


def test_not_when_a_significant_candidate_is_at_the_noise(stages):
    verdicts = [_verdict("saturation", True), _verdict("unbalance", False)]
    out = rounds._training_leader_too(None, _state(saturation_held=1.1), verdicts, {})
    assert stages == []
    assert out == verdicts


def test_a_significant_candidate_above_the_noise_does_not_stop_it(stages):
    verdicts = [_verdict("saturation", True), _verdict("unbalance", False)]
    rounds._training_leader_too(None, _state(saturation_held=3.0), verdicts, {})
    assert stages == ["unbalance"]


def test_not_when_a_significant_candidate_fits_the_training_runs(stages):
    # `rounds.TRAINING_FIT_RATIO`: held out above the noise, training within it.
    verdicts = [_verdict("saturation", True), _verdict("unbalance", False)]
    at = rounds.TRAINING_FIT_RATIO
    out = rounds._training_leader_too(
        None, _state(saturation_held=3.0, saturation_training=at * 0.99), verdicts, {}
    )
    assert stages == []
    assert out == verdicts
    rounds._training_leader_too(
        None, _state(saturation_held=3.0, saturation_training=at * 1.01), verdicts, {}
    )
    assert stages == ["unbalance"]


def test_an_insignificant_candidate_at_the_noise_on_training_does_not_stop_it(stages):
    verdicts = [_verdict("saturation", False), _verdict("unbalance", False)]
    rounds._training_leader_too(None, _state(saturation_training=0.5), verdicts, {})
    assert stages == ["unbalance"]
