"""A fit at the noise on the training runs is refined once more from its own
end (`Settings.restart_at_noise`, docs/identification.md "Stop 26").

Reference clean seed 12 (the independent simulator, `isp_twin.reference`):
the least squares from the data's start stops at about 1.02 noise sigmas on
training, so the global search never ran, and held out the model is about
two sigmas off; restarted from that end it goes on to the truth's basin.
Seed 12 is one of the three axes (12, 15, 18) on which the restart was
chosen: this pins the mechanism, the rates are the benchmark's. Since stop
42 (the breakaway's friction at its mean rate) the fit without the restart
is no longer in the wrong basin here (1.12 held out).
"""

from __future__ import annotations

import pytest

from isp_twin.identification.cost import rmse
from isp_twin.identification.fit import Settings, identify
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.parameters import load_parameters
from isp_twin.reference import design_experiment
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG

SEED = 12


def _data(exp, name: str) -> MeasuredData:
    r = exp.runs[name]
    return MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])


@pytest.fixture(scope="module")
def fits():
    exp = design_experiment(SEED)
    train = [_data(exp, "train1"), _data(exp, "train2")]
    held = [_data(exp, "heldout")]
    prior = load_parameters(default_parameters_path()).axis("inner_az")
    sigma = exp.truth()["noise_sigma_deg_s"] * DEG
    out = {}
    for restart in (False, True):
        res = identify(train, prior, Settings(restart_at_noise=restart))
        rate = res.rate
        errors = [
            float(rmse(rate, [d], timing=res.timing, integration=res.integration) / sigma)
            for d in (*train, *held)
        ]
        out[restart] = (res, errors)
    return out


def test_without_the_restart_the_fit_stops_at_the_noise(fits):
    """Judged at the noise, so the global search does not run. (Held out it
    was 2 sigmas off until stop 42; with the breakaway sub-step's friction
    at its mean rate it reads 1.12: that wrong basin is gone on this axis.)"""
    res, errors = fits[False]
    assert max(errors[:2]) < Settings().converged_ratio


def test_restarted_it_reaches_the_noise_held_out(fits):
    res, errors = fits[True]
    assert max(errors) <= 1.3
    # A restart can only keep or lower the search's training cost (its
    # history's last entry). `res.cost` is the cost at the stored point,
    # rounded to the parameter file's digits, which may move it either way
    # by a few millionths (2.7e-6 relative here with the side angle of stop 49).
    assert res.history[-1] <= fits[False][0].history[-1]


def test_the_restart_is_stated_in_the_status(fits):
    assert "least squares from its own end" in fits[True][0].status
    assert "least squares from its own end" not in fits[False][0].status


def test_diagnose_fits_without_the_restart(monkeypatch):
    """`diagnose`'s fits keep identify's search as it was before the restart
    (on benchmark input_delay seed 0 the restart turned a right answer
    tentative: docs/diagnosis.md "Stop 26")."""
    from types import SimpleNamespace

    from isp_twin.diagnosis import rounds

    seen = []
    monkeypatch.setattr(rounds, "identify", lambda runs, ax, settings: seen.append(settings))
    data = SimpleNamespace(
        side_source="measured",
        seed=0,
        train=SimpleNamespace(integration=None),
        runs=SimpleNamespace(raw=[]),
        ax=SimpleNamespace(),
        identified={},
    )
    monkeypatch.setattr(rounds, "replace", lambda ax, effects: ax)
    rounds.identify_held(data, (), timing=None, generations=0)
    assert seen[0].restart_at_noise is False
    assert seen[0].regime_spread is None
