"""The notch block: exact depth at its centre, unity far from it, Nyquist check."""

import math

import numpy as np
import pytest

from isp_twin.control.notch import NotchFilter

DT = 1e-3


@pytest.mark.parametrize("freq, q, depth", [(80.0, 2.0, 0.05), (300.0, 4.0, 0.1), (20.0, 1.0, 0.0)])
def test_gain_at_centre_is_the_depth_and_unity_at_dc_and_nyquist(freq, q, depth):
    n = NotchFilter(freq, q, depth, DT)
    assert n.gain(freq) == pytest.approx(depth, abs=1e-9)
    assert n.gain(0.0) == pytest.approx(1.0, abs=1e-12)
    assert n.gain(0.5 / DT) == pytest.approx(1.0, abs=1e-9)


def test_time_domain_sine_at_centre_is_attenuated_by_depth():
    freq, depth = 100.0, 0.2
    n = NotchFilter(freq, 3.0, depth, DT)
    t = np.arange(4000) * DT
    y = np.array([n.step(math.sin(2 * math.pi * freq * tk)) for tk in t])
    # amplitude from the RMS over whole periods (10 samples per period)
    assert math.sqrt(2 * np.mean(y[-500:] ** 2)) == pytest.approx(depth, rel=0.01)


def test_low_frequency_passes_with_little_phase_loss():
    # the rate loop's band (a few Hz) must not be touched by a 300 Hz notch
    n = NotchFilter(300.0, 4.0, 0.1, DT)
    assert n.gain(5.0) == pytest.approx(1.0, abs=1e-3)


def test_reset_clears_state():
    n = NotchFilter(50.0, 2.0, 0.1, DT)
    first = [n.step(1.0) for _ in range(10)]
    n.reset()
    assert [n.step(1.0) for _ in range(10)] == first


@pytest.mark.parametrize("freq", [500.0, 600.0, 0.0, -5.0])
def test_centre_outside_zero_to_nyquist_is_rejected(freq):
    with pytest.raises(ValueError, match="Nyquist"):
        NotchFilter(freq, 2.0, 0.1, DT)
