"""The PI block: its series and parallel forms, zero steady-state error, anti-windup."""

import math

import pytest

from isp_twin.control.pi import PIController


def test_output_follows_the_series_form_for_a_constant_error():
    pi = PIController(kp=2.0, ki=0.1)
    # u[k] = kp*(e + ki*(k+1)*e) for a constant error e
    outs = [pi.step(3.0) for _ in range(5)]
    assert outs == pytest.approx([2.0 * (3.0 + 0.1 * (k + 1) * 3.0) for k in range(5)])


def test_output_follows_the_parallel_form_for_a_constant_error():
    pi = PIController(kp=2.0, ki=0.1, form="parallel")
    # u[k] = kp*e + ki*(k+1)*e: the integral gain does not scale with kp
    outs = [pi.step(3.0) for _ in range(5)]
    assert outs == pytest.approx([2.0 * 3.0 + 0.1 * (k + 1) * 3.0 for k in range(5)])


def test_an_unknown_form_is_refused():
    with pytest.raises(ValueError, match="series"):
        PIController(kp=1.0, ki=0.1, form="ideal")


def test_zero_steady_state_error_on_a_first_order_plant_with_a_disturbance():
    # y[k+1] = a*y[k] + g*(u[k] - d): a constant load d needs integral action.
    a, g, d, ref = 0.9, 0.05, 40.0, 1.0
    pi = PIController(kp=3.0, ki=0.05)
    y = 0.0
    for _ in range(3000):
        u = pi.step(ref - y)
        y = a * y + g * (u - d)
    assert y == pytest.approx(ref, abs=1e-9)


def test_proportional_only_leaves_the_textbook_error():
    a, g, kp = 0.9, 0.05, 3.0
    pi = PIController(kp=kp, ki=0.0)
    y = 0.0
    for _ in range(2000):
        y = a * y + g * pi.step(1.0 - y)
    # steady state: y = g*kp*(1-y)/(1-a)
    loop = g * kp / (1 - a)
    assert y == pytest.approx(loop / (1 + loop), rel=1e-9)


def test_integrator_freezes_while_saturated_and_pushed_further():
    pi = PIController(kp=1.0, ki=1.0, limit=10.0)
    for _ in range(100):
        pi.step(5.0)
    # without anti-windup the sum would be 500
    assert pi.integral < 10.0
    pi.reset()
    assert pi.integral == 0.0


def test_integrator_unwinds_when_the_error_reverses():
    pi = PIController(kp=1.0, ki=1.0, limit=10.0)
    for _ in range(20):
        pi.step(5.0)
    before = pi.integral
    pi.step(-1.0)
    assert pi.integral == before - 1.0


@pytest.mark.parametrize("kp, ki", [(math.nan, 0.1), (1.0, -0.1), (-1.0, 0.0)])
def test_bad_gains_are_rejected(kp, ki):
    with pytest.raises(ValueError, match="PI gains"):
        PIController(kp, ki)
