"""Gyro, resolver, bound and the outer follower."""

import math

import numpy as np
import pytest

from isp_twin.control.bound import Bound
from isp_twin.control.follower import OuterFollower
from isp_twin.control.gyro import Gyro
from isp_twin.control.resolver import Resolver
from isp_twin.units import DEG

DT = 1e-3


def make_gyro(seed=0, **kw):
    args = dict(
        scale_count_per_deg_s=65.0,
        noise_deg_s=0.0,
        bandwidth_hz=1e9,
        sample_every=1,
        dt=DT,
        rng=np.random.default_rng(seed),
    )
    args.update(kw)
    return Gyro(**args)


def test_gyro_quantises_to_whole_counts_of_its_scale():
    g = make_gyro()
    counts = g.read(1.0 * DEG)
    assert counts == 65.0
    assert g.to_rate(counts) == pytest.approx(1.0 * DEG)
    assert make_gyro().read(0.004 * DEG) == 0.0  # below half a count


def test_gyro_step_response_is_the_sampled_first_order_lag():
    bw = 20.0
    g = make_gyro(bandwidth_hz=bw, scale_count_per_deg_s=1e6)
    reads = [g.to_rate(g.read(1.0)) for _ in range(30)]
    expected = [1 - math.exp(-2 * math.pi * bw * (k + 1) * DT) for k in range(30)]
    assert reads == pytest.approx(expected, abs=1e-6)


def test_gyro_noise_has_the_stated_deviation_and_repeats_with_the_seed():
    a = make_gyro(seed=3, noise_deg_s=0.1, scale_count_per_deg_s=1e4)
    b = make_gyro(seed=3, noise_deg_s=0.1, scale_count_per_deg_s=1e4)
    ra = np.array([a.to_rate(a.read(0.0)) for _ in range(20000)])
    rb = np.array([b.to_rate(b.read(0.0)) for _ in range(20000)])
    assert np.array_equal(ra, rb)
    assert np.std(ra) / DEG == pytest.approx(0.1, rel=0.03)


def test_gyro_holds_between_samples():
    g = make_gyro(sample_every=4, scale_count_per_deg_s=DEG)  # 1 count per rad/s
    reads = [g.read(float(k)) for k in range(8)]
    assert reads == [0.0] * 4 + [4.0] * 4


def test_resolver_rate_of_a_ramp_is_exact_on_its_grid():
    res = Resolver(resolution_deg=0.001, rate_window=10, dt=DT)
    rate = 2.0 * DEG  # 2 deg/s = 2 quanta per sample
    out = [res.read(rate * DT * k) for k in range(1, 30)]
    assert out[-1][1] == pytest.approx(rate, rel=1e-9)
    assert out[-1][0] == pytest.approx(rate * DT * 29, abs=0.0005 * DEG)


def test_bound_clamps_symmetrically():
    b = Bound(100.0)
    assert [b.step(x) for x in (-500.0, -50.0, 50.0, 500.0)] == [-100.0, -50.0, 50.0, 100.0]
    with pytest.raises(ValueError):
        Bound(0.0)


def test_follower_drives_the_follow_error_to_zero_against_coulomb_friction():
    # outer gimbal: rate[k+1] = a*rate + g*u - friction; the inner angle (the
    # follow error) shrinks as the outer turns toward it.
    a, g, coulomb = 0.95, 0.004 * DEG, 1.2 * DEG
    f = OuterFollower(kp=2000 / DEG, ki=2 / DEG, kd=20 / DEG, limit=2000.0)
    error, rate = 1.0 * DEG, 0.0
    for _ in range(5000):
        u = f.step(error, rate)
        drive = g * u
        if rate == 0.0 and abs(drive) <= coulomb:
            new = 0.0
        else:
            new = a * rate + drive - math.copysign(coulomb, rate if rate else drive)
            if rate and new * rate < 0:
                new = 0.0
        rate = new
        error -= rate * DT
    assert abs(error) < 0.01 * DEG
