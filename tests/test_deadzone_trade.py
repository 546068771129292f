"""A dead zone placed along its trade with the friction levels by the held-out
run (`isp_twin.diagnosis.trade.placed_along_trade`; docs/diagnosis.md
"Stop 53").

On the cosine runs a wider band under levels lowered by the motor gain
times the extra width fits alike: the training runs leave the width where
the refit's start put it. The fits here are the truth of reference axes
(the reference simulator shares no code with the model) moved along that
trade to half and 1.5 times the true width. Seeds 501 and 506 are the two
of the drawn seeds 500-507 where the move costs the training runs less
than 0.05 %: the held-out run alone can tell. On all eight the width came
back within 1 % from both sides.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from truth_error import measured_runs, truth_rate_vector

from isp_twin.commands.diagnose import _interval
from isp_twin.diagnosis.candidates import CandidateFit
from isp_twin.diagnosis.prepared_runs import fused_runs
from isp_twin.diagnosis.result import Diagnosis, RoundResult
from isp_twin.diagnosis.trade import TRADE_UNSEEN, placed_along_trade
from isp_twin.estimation.simulation_error import residuals_many, stack_runs
from isp_twin.estimation.verdict import json_safe
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import RATE_LAYOUT
from isp_twin.model.substep_model import DEFAULT_INTEGRATION
from isp_twin.reference import design_experiment
from isp_twin.units import DEG


def _stack(runs):
    return stack_runs(
        fused_runs(runs, Timing(0.0, True), DEFAULT_INTEGRATION),
        side=None,
        gyro_average=True,
        integration=DEFAULT_INTEGRATION,
    )


def _case(seed: int):
    exp = design_experiment(seed, "deadzone", held_out="covered")
    truth = exp.truth()
    runs = measured_runs(exp)
    train = _stack([d for n, d in runs.items() if n != "heldout"])
    held = _stack([runs["heldout"]])
    sigma = truth["noise_sigma_deg_s"] * DEG
    width = truth["effects"][0]["params"]["width_digits"]
    return train, held, truth_rate_vector(truth), width, sigma


def _sse(stack, x, width) -> float:
    res = residuals_many(stack, [(x[None], "deadzone", {"width_digits": np.array([width])})])[0]
    return float(np.sum(res**2))


def _moved_fit(train, x, width, share) -> CandidateFit:
    """The truth moved along the trade to `share` times the true width."""
    moved = x.copy()
    gain = RATE_LAYOUT.column(x, "gain")
    for field in ("static", "coulomb"):
        idx = list(RATE_LAYOUT.field_indices(field))
        moved[idx] -= gain * (share - 1.0) * width
    return CandidateFit(
        name="deadzone",
        params={"width_digits": share * width},
        ci95={"width_digits": float("nan")},
        rate_vector=moved,
        rate_ci95=np.full(x.size, np.nan),
        sse=_sse(train, moved, share * width),
        n_samples=train.n_samples,
        n_params=RATE_LAYOUT.size + 1,
        bic=0.0,
        status=None,
    )


@pytest.mark.parametrize("seed", [501, 506])
def test_the_held_out_run_places_a_width_the_training_runs_cannot_tell(seed):
    train, held, x, width, sigma = _case(seed)
    for share in (0.5, 1.5):
        fit = _moved_fit(train, x, width, share)
        placed = placed_along_trade(train, held, fit, np.inf)
        assert abs(placed.params["width_digits"] / width - 1.0) < 0.02
        # Set by the held-out run, the width is not charged by the training BIC.
        assert placed.placed == ("width_digits",)
        assert placed.n_params == fit.n_params - 1
        # The training runs do not see the move (or fit better)...
        assert placed.sse <= fit.sse * (1.0 + TRADE_UNSEEN)
        assert placed.sse == pytest.approx(
            _sse(train, placed.rate_vector, placed.params["width_digits"])
        )
        # ... and the held-out run comes to the noise.
        rms = np.sqrt(
            _sse(held, placed.rate_vector, placed.params["width_digits"]) / held.n_samples
        )
        assert (
            rms
            < 1.1 * sigma
            < np.sqrt(_sse(held, fit.rate_vector, fit.params["width_digits"]) / held.n_samples)
        )


def test_no_move_above_the_ceiling_and_none_for_an_effect_without_a_trade():
    train, held, x, width, _ = _case(501)
    fit = _moved_fit(train, x, width, 0.5)
    # On this axis every point of the trade fits the training runs within
    # 0.05 % of the fit: a ceiling 0.1 % below the fit's training sse (a
    # base that fits better) leaves the fit where it is.
    assert placed_along_trade(train, held, fit, fit.sse * (1.0 - 1e-3)) is fit
    cogging = CandidateFit(
        name="cogging",
        params={"amplitude_rad_s2": 0.1, "period_rad": 0.1, "phase_rad": 0.0},
        ci95={},
        rate_vector=x,
        rate_ci95=np.full(x.size, np.nan),
        sse=1.0,
        n_samples=train.n_samples,
        n_params=RATE_LAYOUT.size + 3,
        bic=0.0,
        status=None,
    )
    assert placed_along_trade(train, held, cogging, np.inf) is cogging


def test_the_answer_says_the_held_out_run_placed_the_width():
    fit = SimpleNamespace(
        name="deadzone",
        params={"width_digits": 114.0},
        ci95={"width_digits": float("nan")},
        placed=("width_digits",),
    )
    rnd = RoundResult(
        baseline=SimpleNamespace(name="none"),
        fits={"deadzone": fit},
        verdicts=(),
        selected="deadzone",
        holdout_before=(np.ones(10),),
        holdout_after=(np.ones(10),),
        noise_floor=1.0,
    )
    diag = Diagnosis(
        axis="inner_az",
        rounds=(rnd,),
        rmse_before=1.0,
        rmse_after=1.0,
        noise_floor=1.0,
        params_out=None,
        analysis_before=None,
        analysis_after=None,
    )
    got = json_safe(diag._effects_json())
    assert got["effect_placed_by_held_out"] == ["width_digits"]
    assert got["all_selected"][0]["placed_by_held_out"] == ["width_digits"]
    assert got["effect_ci95"] == {"width_digits": None}
    assert "placed by the held-out run" in _interval(fit, "width_digits")
