"""Eq. 10 and the campaign statistics on signals with known answers."""

import math

import numpy as np
import pytest

from isp_twin.experiments.metrics import (
    axis_metrics,
    campaign_stats,
    isolation_percent,
    run_metrics,
)
from isp_twin.units import DEG


def test_isolation_of_a_scaled_copy_is_the_scale():
    t = np.linspace(0, 6, 6001)
    w = math.pi * DEG * np.cos(2 * math.pi * t / 6)
    assert isolation_percent(0.2 * w, w) == pytest.approx(20.0)


def test_errors_in_deg_s_rms_of_a_sine():
    t = np.arange(0, 2, 1e-3)
    w = math.pi * DEG * np.sin(2 * math.pi * 0.5 * t)
    w1 = 0.5 * DEG * np.sin(2 * math.pi * 3 * t)
    m = axis_metrics(w1, w)
    assert m["max_abs_error_deg_s"] == pytest.approx(0.5, rel=1e-3)
    assert m["rms_error_deg_s"] == pytest.approx(0.5 / math.sqrt(2), rel=1e-3)
    assert m["isolation_percent"] == pytest.approx(50 / math.pi, rel=1e-3)


def test_isolation_is_the_ratio_of_peaks_not_of_means():
    """Eq. 10 takes max|omega_1| / max|omega|: spikes set it, however short."""
    t = np.arange(0, 2.3, 1e-3)  # not a whole number of periods
    w = DEG * np.sin(2 * math.pi * 0.7 * t)
    w[1500] = 3.0 * DEG  # the carrier's peak is this one sample
    w1 = 0.1 * DEG * np.sin(2 * math.pi * 5.0 * t)
    w1[700] = -0.6 * DEG  # a negative burst: its magnitude counts
    assert isolation_percent(w1, w) == pytest.approx(20.0)
    # a mean-based ratio of the same signals is far from it
    assert 100 * np.mean(np.abs(w1)) / np.mean(np.abs(w)) < 12.0


def test_isolation_of_a_partial_period_uses_the_window_peak():
    # omega = A sin over a quarter period peaks at A only at the window's end;
    # omega_1 = B t^2 peaks at its end too: J = B T^2 / A.
    t = np.linspace(0.0, 0.5, 501)
    a, b = 2.0 * DEG, 0.4 * DEG
    w = a * np.sin(2 * math.pi * 0.5 * t)
    w1 = b * t**2
    assert isolation_percent(w1, w) == pytest.approx(100 * b * 0.25 / a)
    m = axis_metrics(w1, w)
    assert m["max_abs_error_deg_s"] == pytest.approx(0.1)
    # RMS of B t^2 over [0, T]: B T^2 / sqrt(5)
    assert m["rms_error_deg_s"] == pytest.approx(0.1 / math.sqrt(5), rel=2e-3)


def test_only_the_steady_state_window_counts():
    t = np.arange(0, 4, 1e-3)
    w = DEG * np.ones_like(t)
    w1 = np.where(t < 2.0, 10 * DEG, 0.1 * DEG)  # a start-up transient
    sig = {"inner_az/omega_inertial": w1, "inner_az/omega_carrier": w}
    m = run_metrics(t, sig, skip_s=2.0, axes=("inner_az",))
    assert m["inner_az"]["isolation_percent"] == pytest.approx(10.0)
    assert run_metrics(t, sig, skip_s=10.0, axes=("inner_az",)) == {}


def test_isolation_is_undefined_without_carrier_motion():
    assert axis_metrics(np.ones(10) * 1e-3, np.zeros(10))["isolation_percent"] is None
    t = np.arange(10) * 1e-3
    sig = {"inner_el/omega_inertial": np.ones(10) * 1e-3, "inner_el/omega_carrier": np.zeros(10)}
    assert run_metrics(t, sig, 0.0, axes=("inner_el",)) == {}


def test_campaign_stats_of_known_values():
    s = campaign_stats([10.0, 12.0, 14.0])
    assert (s.average, s.best, s.worst, s.range) == (12.0, 10.0, 14.0, 4.0)
    # sample variance of the fractions 0.10, 0.12, 0.14
    assert s.variance == pytest.approx(0.0004)
    with pytest.raises(ValueError):
        campaign_stats([])
