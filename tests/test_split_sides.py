"""A sub-step in which the angle changes side (`Integration.split_sides`, ``--split-sides``).

The half-plane's regime changes at the angle's zero crossing, which falls
anywhere inside a sub-step. Read at the sub-step's start, the switch lags by
up to a sub-step: a jump of the motor gain between the sides then drives the
wrong impulse at every crossing, and a payload mode rings with it
(docs/diagnosis.md "Stop 34").
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq
from truth_error import truth_error

from isp_twin.commands.data_options import (
    add_data_options,
    integration_from_args,
    model_from_file,
)
from isp_twin.identification.read_out import Timing, fitted_with
from isp_twin.model.parameters import (
    RateParams,
    load_parameters,
    save_parameters,
)
from isp_twin.model.substep_model import EQ6, Integration, simulate_substeps
from isp_twin.resources import default_parameters_path

T = 1e-3
N = 30
TAU_S = 0.02
POLE = float(np.exp(-T / TAU_S))
U = 800.0
GAIN_R, GAIN_L = 3e-4, 1.5e-4  # rate form per digit per sample: R (angle > 0), L
THETA0 = -0.0016  # rad: the crossing falls in the middle of the first sample


def _crossing_run() -> tuple[np.ndarray, np.ndarray, float]:
    """(rate, angle) at the sample instants of a frictionless axis crossing
    from L into R at its L steady state, exactly, and the rate's step there."""
    lam = 1.0 / TAU_S
    w_l, w_r = (g * U / (1.0 - POLE) for g in (GAIN_L, GAIN_R))

    def angle(t, w_start, w_inf, th_start):
        return th_start + w_inf * t + (w_start - w_inf) * (1.0 - np.exp(-lam * t)) / lam

    tc = brentq(lambda t: angle(t, w_l, w_l, THETA0), 0.0, 1.0)
    t = np.arange(N) * T
    after = np.maximum(t - tc, 0.0)
    w = np.where(t < tc, w_l, w_r + (w_l - w_r) * np.exp(-lam * after))
    theta = np.where(t < tc, angle(t, w_l, w_l, THETA0), angle(after, w_l, w_r, 0.0))
    return w, theta, w_r - w_l


def _error(integration: Integration, given_angle: bool) -> float:
    w, theta, _ = _crossing_run()
    params = RateParams(
        pole=np.full(4, POLE),
        gain=np.array([GAIN_R, GAIN_R, GAIN_L, GAIN_L]),  # R+, R-, L+, L-
        static=np.zeros(4),
        coulomb=np.zeros(4),
        alpha=np.zeros(4),
    )
    got = simulate_substeps(
        params,
        np.full(N, U),
        T,
        omega0=w[0],
        angle0=THETA0,
        angle_measured=theta if given_angle else None,
        integration=integration,
    )
    return float(np.max(np.abs(got.omega - w)))


@pytest.mark.parametrize("given_angle", [True, False])
def test_a_gain_jump_at_the_crossing_is_integrated_to_first_order(given_angle):
    # Frictionless and linear: the exact rate is two exponentials joined at
    # the crossing. Read at the sub-step's start, the switch lags by half a
    # sub-step here (0.24 % of the rate's step); split, what is left is the
    # error of the given angle's linear interpolation inside the sample, or
    # with the model's own angle (exact before the crossing: the rate is
    # steady) nearly nothing: less than 100 unsplit sub-steps leave.
    _, _, step = _crossing_run()
    unsplit = _error(Integration(split_sides=False), given_angle)
    split = _error(Integration(split_sides=True), given_angle)
    assert unsplit > 1e-3 * step
    assert split < 0.05 * unsplit
    if not given_angle:
        assert split < 0.05 * _error(Integration(substeps=100, split_sides=False), False)


def _args(*argv: str) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_data_options(p)
    return p.parse_args(list(argv))


def test_the_option_is_asked_for_and_the_parameter_file_records_it(tmp_path):
    # On by default since stop 38 (Integration's docstring says why); Eq. 6
    # holds the regime of the sample's start unless asked. identify's record
    # carries it through the file; a file written without the key is
    # replayed without it (the files written before the option).
    assert not EQ6.split_sides and Integration().split_sides
    assert integration_from_args(_args()).split_sides
    assert not integration_from_args(_args("--no-split-sides")).split_sides
    assert not integration_from_args(_args("--substeps", "1")).split_sides
    assert integration_from_args(_args("--split-sides", "--substeps", "1")).split_sides
    params = load_parameters(default_parameters_path())
    ax = params.axis("inner_az")
    for split in (True, False):
        record = fitted_with(Integration(split_sides=split), Timing())
        path = save_parameters(
            params.with_axis("inner_az", replace(ax, fitted_with=record)), tmp_path / "p.yaml"
        )
        axis = load_parameters(path).axis("inner_az")
        assert axis.fitted_with.split_sides == split
        integration, _, override = model_from_file(_args(), axis, "p.yaml")
        assert integration.split_sides == split and override is None
    # --split-sides on a file fitted without it: the file's sub-steps, split,
    # and a line saying so.
    integration, timing, override = model_from_file(_args("--split-sides"), axis, "p.yaml")
    assert integration.split_sides and integration.substeps == record.substeps
    assert timing is None and override.startswith("--split-sides overrides p.yaml")
    # Another sub-step count refits with it; a split the file was fitted
    # with stays (not asked again on the command line).
    split_file = replace(axis, fitted_with=fitted_with(Integration(split_sides=True), Timing()))
    integration, _, override = model_from_file(_args("--substeps", "4"), split_file, "p.yaml")
    assert integration.substeps == 4 and integration.split_sides
    assert override.startswith("--substeps 4 overrides p.yaml")
    # --no-split-sides on a file fitted with it: the file's sub-steps, not split.
    integration, _, override = model_from_file(_args("--no-split-sides"), split_file, "p.yaml")
    assert not integration.split_sides and integration.substeps == record.substeps
    assert override.startswith("--no-split-sides overrides p.yaml.fitted_with.split_sides true")
    text = path.read_text().replace("      split_sides: false\n", "")
    assert "split_sides" not in text.split("inner_el")[0]
    path.write_text(text)
    assert not load_parameters(path).axis("inner_az").fitted_with.split_sides


def test_reference_payload_rung_by_a_gain_jump_reaches_the_noise_with_its_truth():
    # Reference resonance seed 79 (9 ms axis, the motor gain 46 % higher on
    # the left side): with its true parameters the library read 1.36-1.38
    # gyro sigmas on every run, its 56 Hz payload rung by the gain's jump at
    # each crossing; split, at the noise.
    before = truth_error(79, "resonance", Integration(split_sides=False))
    after = truth_error(79, "resonance", Integration(split_sides=True))
    assert min(before) > 1.25
    assert max(after) < 1.05
