"""Round 1's payload stage (`rounds._payload_stage`) where the gyro and the
resolver show the mode (`rounds._payload_peak`): it runs even where another
candidate leads the training BIC, and holds the mode at the sensors'
frequency where the local refit ended far from it (reference resonance
seed 30: LuGre led, the payload's refit stayed at 7.1 Hz, the mode at
25.5 Hz; docs/diagnosis.md "Stop 31")."""

from __future__ import annotations

import numpy as np
import pytest
from round_state_double import RoundStateDouble, fit_double

from isp_twin.diagnosis import rounds

MODE = {"freq_hz": 7.1, "damping_ratio": 0.01, "coupling": 0.02, "payload_fraction": 0.0}


def _state():
    fits = {
        "resonance": fit_double("resonance", dict(MODE), sse=987.0, bic=-1188.0),
        "lugre": fit_double("lugre", {"accel_rad_s2": 23.0}, sse=46.0, bic=-37584.0),
    }
    held = {"resonance": [np.full(50, 380.0)], "lugre": [np.full(50, 148.0)]}
    return RoundStateDouble(fits, held, fit_double("base", sse=1000.0, bic=0.0))


@pytest.fixture
def refits(monkeypatch):
    """`_refit_globally` recorded (each hold's fit at a lower sse), the cycles a no-op."""
    held = []

    def refit(data, fit, hold=None):
        held.append(hold)
        return fit_double(fit.name, hold, sse=1.0, bic=-9e4)

    monkeypatch.setattr(rounds, "_refit_globally", refit)
    monkeypatch.setattr(rounds, "_global_cycles", lambda data, g: g)
    return held


def test_without_the_sensors_peak_a_payload_behind_the_bic_leader_is_left(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: None)
    out = rounds._payload_stage(None, _state(), ["lugre", "resonance"])
    assert refits == []
    assert out == ["lugre", "resonance"]


def test_the_sensors_peak_holds_the_mode_at_its_frequency(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 26.3)
    st = _state()
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert [h["payload_fraction"] for h in refits] == list(rounds.PAYLOAD_FRACTIONS)
    assert all(h["freq_hz"] == 26.3 and h["coupling"] == 1.0 for h in refits)
    assert all(h["damping_ratio"] == rounds.PEAK_DAMPING for h in refits)
    assert "resonance" in st.updated


def test_a_refit_near_the_sensors_peak_keeps_its_own_mode(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 7.3)
    rounds._payload_stage(None, _state(), ["lugre", "resonance"])
    assert all(h["freq_hz"] == 7.1 and h["damping_ratio"] == 0.01 for h in refits)


def test_the_sensors_peak_refits_a_payload_whose_local_refit_failed(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 44.3)
    st = _state()
    st.failed = {"resonance"}
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert [h["freq_hz"] for h in refits] == [44.3] * len(rounds.PAYLOAD_FRACTIONS)
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: None)
    refits.clear()
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert refits == []
