"""The payload's mode as the gyro and the resolver show it
(`Resonance.deflection_peak`), not the resolver's quantization
(`RunStack.deflection`): an axis that holds its rate turns quanta at a fixed
repetition rate, and the resolver's difference quotient then carries a line
there that no mode makes."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.estimation.simulation_error import stack_runs
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.report import payload_hint
from isp_twin.model.effects.resonance import DEFLECTION_PROMINENCE, Resonance
from isp_twin.reference import design_experiment
from isp_twin.units import DEG

DT = 1e-3
STEP = 360.0 / 2**14 * DEG  # a 14-bit resolver's quantum [rad]


def _run(rate: np.ndarray, ringing: np.ndarray, name: str = "r") -> MeasuredData:
    """A run whose motor side turns at `rate` [rad/s], read by a 14-bit
    resolver, and whose gyro reads that rate plus `ringing` [rad/s]."""
    n = rate.size
    t = np.arange(n) * DT
    angle = np.concatenate([[0.0], np.cumsum(rate[1:]) * DT])
    resolver = STEP * np.round(angle / STEP)
    return MeasuredData(name, t, np.zeros(n), rate + ringing, resolver, None, DT)


def _plateaus(n: int, speed: float) -> np.ndarray:
    """Rest, then a ramp to a held rate, its plateau and back: 8 s at 1 kHz."""
    t = np.arange(n) * DT
    return speed * np.clip(np.minimum(t - 0.5, 7.5 - t) / 0.5, 0.0, 1.0)


def _peak(runs) -> float | None:
    stack = stack_runs(runs)
    return Resonance.deflection_peak(*stack.deflection(), stack.dt)


def test_a_held_rate_makes_a_quantization_line_the_peak_does_not_take():
    # 8.43 deg/s turns 384 quanta a second: a line at 384 Hz.
    rate = _plateaus(8000, 8.43 * DEG)
    runs = [_run(rate, np.zeros_like(rate))]
    stack = stack_runs(runs)
    deflection, lines = stack.deflection()
    freqs, smooth, band = Resonance._spectrum(deflection, DT)
    line = band[np.argmax(smooth[band])]
    assert abs(freqs[line] - 8.43 * DEG / STEP) < 1.5
    assert smooth[line] >= DEFLECTION_PROMINENCE * np.median(smooth[band])
    # The quantization the stack rebuilds from the gyro makes that line.
    assert Resonance._spectrum(lines, DT)[1][line] > 0.5 * smooth[line]
    assert _peak(runs) is None


@pytest.mark.parametrize("seed", range(8))
def test_a_ringing_mode_is_found_beside_the_line(seed):
    rate = _plateaus(8000, 8.43 * DEG)
    t = np.arange(rate.size) * DT
    gyro = np.random.default_rng(seed).normal(0.0, 0.05 * DEG, t.size)
    wn, zeta = 2.0 * np.pi * 31.0, 0.03
    for start in (0.5, 1.0, 7.0, 7.5):  # after each change of the rate
        after = np.clip(t - start, 0.0, None)
        gyro += 20.0 * DEG * np.exp(-zeta * wn * after) * np.sin(wn * after) * (t >= start)
    assert _peak([_run(rate, gyro)]) == pytest.approx(31.0, abs=1.0)


@pytest.mark.parametrize("seed", range(8))
def test_a_held_rate_with_gyro_noise_names_no_mode(seed):
    # High orders of the line move fast with the rate: the rebuild reads
    # the rate's mean over `LINE_WINDOW` samples.
    rate = _plateaus(8000, 8.43 * DEG)
    noise = np.random.default_rng(seed).normal(0.0, 0.05 * DEG, rate.size)
    assert _peak([_run(rate, noise)]) is None


def test_no_peak_at_the_lower_edge_of_the_band():
    # Slow motion only: the spectrum falls from below the band's lower edge.
    t = np.arange(6000) * DT
    rate = 20.0 * DEG * np.sin(2.0 * np.pi * 0.3 * t)
    noise = np.random.default_rng(1).normal(0.0, 0.05 * DEG, t.size)
    slow = 2.0 * DEG * np.sin(2.0 * np.pi * 3.0 * t)  # a deflection at 3 Hz
    assert _peak([_run(rate, noise + slow)]) is None


def _reference_runs(effect: str, seed: int):
    exp = design_experiment(seed, effect)
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT)
        for n, r in ((n, exp.runs[n]) for n in ("train1", "train2"))
    ]
    return exp, runs


def test_a_saturated_plateau_names_no_mode():
    """Reference saturation seed 4: its plateau at 13.5 deg/s put a line at
    383 Hz (615 quanta a second, aliased) that stood 9.7 times above the band
    (docs/diagnosis.md, "Stop 32")."""
    _, runs = _reference_runs("saturation", 4)
    assert _peak(runs) is None
    assert payload_hint(runs) == ""


def test_a_payload_whose_band_edge_stands_higher_is_found():
    """Reference resonance seed 57: the deflection's spectrum at 5 Hz stood
    higher than at its mode (12.5 against 9.5 times the band's median)."""
    exp, runs = _reference_runs("resonance", 57)
    mode = exp.truth()["effects"][0]["params"]
    free = mode["freq_hz"]
    clamped = free * np.sqrt(1.0 - mode["payload_fraction"])
    assert 0.9 * clamped <= _peak(runs) <= 1.1 * free
