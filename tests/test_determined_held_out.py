"""A model judged on the held-out part the training runs determine
(`isp_twin.diagnosis.determined`; docs/diagnosis.md "Stop 75").

The cut on a reference run against the one the verdicts report for the
same model through `identify`'s path (`held_out_determined`), the
alignment of residual samples with run samples, the minimum part, and a
model judged against itself. The decision that uses the part
(`search._explains_training`) is in tests/test_training_explained.py.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from truth_error import prepared_reference, truth_rate_vector

from isp_twin.diagnosis import determined
from isp_twin.diagnosis.selection import BLOCK
from isp_twin.estimation.coverage import untrained_breakaways
from isp_twin.estimation.simulation_error import WARMUP
from isp_twin.identification.cost import held_out_determined, model_breakaways
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import RateParams

FLOOR = 1e-3  # rad/s


def _fit(x: np.ndarray, bic: float = 0.0):
    return SimpleNamespace(name="none", rate_vector=x, effects=lambda: (), bic=bic)


@pytest.fixture(scope="module")
def clean_348():
    """Reference clean axis 348 with the truth's rate form: its held-out
    random steps rest in R+ and L-, where the truth never breaks away on
    the training cosines (tests/test_determined_part.py)."""
    checked, data, _, truth = prepared_reference(348, None, "inner_az", Timing(0.0, True), [])
    return checked, data, truth_rate_vector(truth)


def test_the_cut_is_the_one_the_verdicts_report(clean_348):
    checked, data, x = clean_348
    (cut,) = determined.untrained_cuts(data, _fit(x))
    rate, (train, held) = RateParams.from_vector(x), checked[:2]
    counts = model_breakaways(rate, train, held, "measured", timing=data.timing)
    untrained = untrained_breakaways(*counts)
    assert untrained  # the axis rests where the training runs never break away
    (part,) = held_out_determined(rate, held, untrained, "measured", timing=data.timing)
    assert cut == part.samples
    assert 1 < cut < part.of_samples


def test_a_model_against_itself_gains_nothing(clean_348):
    _, data, x = clean_348
    (cut,) = determined.untrained_cuts(data, _fit(x))
    counted = int(data.held.mask[0].sum())
    r = np.random.default_rng(0).normal(0.0, FLOOR, counted)
    got = determined.determined_part(data, _fit(x), _fit(x), [r], [r], FLOOR)
    # The residuals start after the stack's warm-up (sample WARMUP).
    assert got.samples == cut - WARMUP and got.of_samples == counted
    assert (
        got.over_noise
        == got.base_over_noise
        == pytest.approx(np.sqrt(np.mean(r[: cut - WARMUP] ** 2)) / FLOOR)
    )
    assert got.improvement_z == 0.0 and not got.significant


def _held(n: int = 6000):
    """Stand-in data: one held-out run of `n` samples, the first WARMUP not counted."""
    mask = np.ones((1, n), dtype=bool)
    mask[0, :WARMUP] = False
    return SimpleNamespace(held=SimpleNamespace(mask=mask))


def test_the_part_is_the_counted_samples_before_the_cut(monkeypatch):
    """Run samples WARMUP..cut-1: residuals 0..cut-WARMUP-1. The base is
    off by 10 floors there and at the noise after; the model at the noise
    before the cut and off after it."""
    cut, n = 1051, 6000 - WARMUP
    monkeypatch.setattr(determined, "untrained_cuts", lambda data, fit: (cut,))
    noise = np.random.default_rng(1).normal(0.0, FLOOR, n)
    before_cut = np.arange(n) < cut - WARMUP
    base = noise + np.where(before_cut, 10.0 * FLOOR, 0.0)
    model = noise + np.where(before_cut, 0.0, 10.0 * FLOOR)
    got = determined.determined_part(_held(), _fit(None, -1.0), _fit(None), [base], [model], FLOOR)
    assert got.samples == cut - WARMUP
    assert got.over_noise == pytest.approx(1.0, abs=0.1)
    assert got.base_over_noise == pytest.approx(np.sqrt(101.0), rel=0.02)
    assert got.significant and got.improvement_z > 3.0


def test_a_short_part_is_not_judged(monkeypatch):
    short = WARMUP + determined.MIN_BLOCKS * BLOCK  # one counted sample short of the minimum
    monkeypatch.setattr(determined, "untrained_cuts", lambda data, fit: (short - 1,))
    r = np.zeros(6000 - WARMUP)
    assert determined.determined_part(_held(), _fit(None), _fit(None), [r], [r], FLOOR) is None
    monkeypatch.setattr(determined, "untrained_cuts", lambda data, fit: (short,))
    assert determined.determined_part(_held(), _fit(None), _fit(None), [r], [r], FLOOR) is not None


def test_no_held_out_runs_no_part(clean_348):
    _, data, x = clean_348
    assert determined.untrained_cuts(replace(data, held=None), _fit(x)) is None
