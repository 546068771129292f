"""A leading payload resonance not at the noise gets `identify`'s global
step at each payload fraction of `rounds.PAYLOAD_FRACTIONS`
(`rounds._payload_stage`): refitted locally from a rigid base, the fraction
stays near the base's 0 (benchmark resonance seed 1: 0.06 against the
truth's 0.21, 23 noise floors held out).

Where the gyro and the resolver show the mode (`rounds._payload_peak`) the
stage runs even where another candidate leads the training BIC or the
local refit failed, and holds the mode at the sensors' frequency where the
local refit ended far from it (reference resonance seed 30: LuGre led, the
payload's refit stayed at 7.1 Hz, the mode at 25.5 Hz; docs/diagnosis.md
"Stop 31")."""

from __future__ import annotations

import numpy as np
import pytest
from round_state_double import RoundStateDouble, fit_double

from isp_twin.diagnosis import rounds

MODE = {"freq_hz": 64.0, "damping_ratio": 0.04, "coupling": 0.97, "payload_fraction": 0.06}


@pytest.fixture(autouse=True)
def no_peak(monkeypatch):
    """The sensors show no mode unless a test says otherwise."""
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: None)


def _state(held_rms=20.0, resonance_bic=-500.0, failed=()):
    fits = {"resonance": fit_double("resonance", dict(MODE), 1.0, resonance_bic),
            "cogging": fit_double("cogging", {}, 2.0, -100.0)}  # fmt: skip
    held = {n: [np.full(100, held_rms)] for n in fits}
    return RoundStateDouble(fits, held, fit_double("base", {}, 3.0, 0.0), failed=set(failed))


def _refits(monkeypatch, sse_of_fraction):
    """`_refit_globally` recorded; the cycles after the best left out."""
    held = []

    def refit(data, fit, params=None):
        held.append(params)
        return fit_double(fit.name, params, sse_of_fraction(params["payload_fraction"]), 0.0)

    monkeypatch.setattr(rounds, "_refit_globally", refit)
    monkeypatch.setattr(rounds, "_global_cycles", lambda data, g: g)
    return held


def test_the_mode_is_held_at_each_fraction_and_the_best_kept(monkeypatch):
    held = _refits(monkeypatch, lambda f: abs(f - 0.2))
    st = _state()
    out = rounds._payload_stage(None, st, [])
    assert [h["payload_fraction"] for h in held] == list(rounds.PAYLOAD_FRACTIONS)
    for h in held:
        assert h["coupling"] == 1.0
        assert (h["freq_hz"], h["damping_ratio"]) == (MODE["freq_hz"], MODE["damping_ratio"])
    assert st.updated["resonance"].params["payload_fraction"] == 0.2
    assert out == ["resonance"]


def test_a_refit_no_better_than_the_local_fit_is_not_kept(monkeypatch):
    _refits(monkeypatch, lambda f: 5.0)
    st = _state()
    assert rounds._payload_stage(None, st, ["v"]) == ["v"]
    assert st.updated == {}


@pytest.mark.parametrize(
    "state",
    [
        pytest.param(dict(held_rms=1.2), id="at the noise held out"),
        pytest.param(dict(resonance_bic=-50.0), id="another fit has a lower BIC"),
        pytest.param(dict(failed=["resonance"]), id="its refit failed"),
    ],
)
def test_no_global_step_where_the_resonance_does_not_lead_or_is_at_the_noise(monkeypatch, state):
    monkeypatch.setattr(rounds, "_refit_globally", lambda *a: pytest.fail("refitted"))
    assert rounds._payload_stage(None, _state(**state), ["v"]) == ["v"]


LED = {"freq_hz": 7.1, "damping_ratio": 0.01, "coupling": 0.02, "payload_fraction": 0.0}


def _led_state():
    fits = {
        "resonance": fit_double("resonance", dict(LED), sse=987.0, bic=-1188.0),
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


def test_without_the_sensors_peak_a_payload_behind_the_bic_leader_is_left(refits):
    out = rounds._payload_stage(None, _led_state(), ["lugre", "resonance"])
    assert refits == []
    assert out == ["lugre", "resonance"]


def test_the_sensors_peak_holds_the_mode_at_its_frequency(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 26.3)
    st = _led_state()
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert [h["payload_fraction"] for h in refits] == list(rounds.PAYLOAD_FRACTIONS)
    assert all(h["freq_hz"] == 26.3 and h["coupling"] == 1.0 for h in refits)
    assert all(h["damping_ratio"] == rounds.PEAK_DAMPING for h in refits)
    assert "resonance" in st.updated


def test_a_refit_near_the_sensors_peak_keeps_its_own_mode(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 7.3)
    rounds._payload_stage(None, _led_state(), ["lugre", "resonance"])
    assert all(h["freq_hz"] == 7.1 and h["damping_ratio"] == 0.01 for h in refits)


def test_the_sensors_peak_refits_a_payload_whose_local_refit_failed(monkeypatch, refits):
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: 44.3)
    st = _led_state()
    st.failed = {"resonance"}
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert [h["freq_hz"] for h in refits] == [44.3] * len(rounds.PAYLOAD_FRACTIONS)
    monkeypatch.setattr(rounds, "_payload_peak", lambda data: None)
    refits.clear()
    rounds._payload_stage(None, st, ["lugre", "resonance"])
    assert refits == []
