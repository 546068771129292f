"""A regime whose Stribeck shape a refit walked far from the others' is
given their shape where that fits the training runs better
(`candidates.consensus_shapes`, `_consensus_shapes`; docs/diagnosis.md
"Stop 67").

The runs come from the reference simulator (it shares no code with the
model); the start is its true rate form with one regime's shape spoiled
the way the dead-zone refit of reference seed 409 left two regimes
(alpha a thousand times the others', static six times its Coulomb level).
"""

from __future__ import annotations

import numpy as np
import pytest
from truth_error import training_stack, truth_rate_vector

from isp_twin.diagnosis.candidates import (
    SHAPE_SPREAD,
    consensus_shapes,
    fit_candidates,
    shape_groups,
)
from isp_twin.model.parameters import RATE_LAYOUT
from isp_twin.reference import design_experiment

SEED = 202  # reference clean axis 202, covered design
ALPHA = RATE_LAYOUT.field_index("alpha")
STATIC = RATE_LAYOUT.field_index("static")
COULOMB = RATE_LAYOUT.field_index("coulomb")


def _table(alphas, ratios) -> np.ndarray:
    """A rate table (regimes x fields) with the given alphas and static/Coulomb ratios."""
    t = np.tile([0.97, 1.5e-5, 0.0, 0.001, 0.0], (RATE_LAYOUT.n_regimes, 1))
    t[:, COULOMB] = [0.001, 0.0012, 0.0009, 0.0011]
    t[:, ALPHA] = alphas
    t[:, STATIC] = t[:, COULOMB] * np.asarray(ratios)
    return t


def test_a_regime_within_the_spread_is_left_alone():
    t = _table([250.0, 280.0, 240.0, 700.0], [2.0, 2.2, 2.1, 1.5])
    assert consensus_shapes(RATE_LAYOUT.from_table(t)) == []


def test_an_outlier_takes_the_others_shape_and_keeps_its_level():
    t = _table([1.8e5, 280.0, 240.0, 260.0], [6.2, 2.2, 2.1, 2.4])
    shaped = consensus_shapes(RATE_LAYOUT.from_table(t))
    # First the three alike lend their shape to the outlier, then the
    # outlier its shape to them (together and one at a time).
    assert len(shaped) == 1 + 4
    s = RATE_LAYOUT.as_table(shaped[0])
    assert s[0, ALPHA] == pytest.approx(260.0)
    assert s[0, STATIC] / s[0, COULOMB] == pytest.approx(2.2)
    assert s[0, COULOMB] == t[0, COULOMB]
    # Everything else is as it was.
    s[0, [ALPHA, STATIC]] = t[0, [ALPHA, STATIC]]
    np.testing.assert_array_equal(s, t)


def test_two_groups_each_lend_their_shape_to_the_others():
    # Two against two: alpha alone cannot tell which pair is off, so each
    # pair's shape is tried on the other, together and one at a time.
    t = _table([1.8e5, 280.0, 240.0, 1.2e5], [2.6, 2.2, 2.1, 1.9])
    shaped = [RATE_LAYOUT.as_table(x) for x in consensus_shapes(RATE_LAYOUT.from_table(t))]
    moved = [tuple(np.flatnonzero((s != t).any(axis=1))) for s in shaped]
    assert moved == [(0, 3), (0,), (3,), (1, 2), (1,), (2,)]
    assert shaped[0][[0, 3], ALPHA] == pytest.approx([260.0, 260.0])
    assert shaped[3][[1, 2], ALPHA] == pytest.approx([1.5e5, 1.5e5])


def test_a_static_level_far_above_the_others_is_an_outlier_too():
    # The input-delay refit of reference seed 409: L- static 21 times its
    # Coulomb level, the others 2.2-2.9, every alpha alike.
    t = _table([385.0, 272.0, 224.0, 807.0], [2.9, 2.3, 2.2, 21.0])
    shaped = consensus_shapes(RATE_LAYOUT.from_table(t))
    assert len(shaped) == 1 + 4
    s = RATE_LAYOUT.as_table(shaped[0])
    assert s[3, STATIC] / s[3, COULOMB] == pytest.approx(2.3)
    assert s[3, ALPHA] == pytest.approx(272.0)
    assert (s[:3] == t[:3]).all()


def test_groups_split_at_gaps_wider_than_the_spread():
    alpha = np.array([100.0, 250.0, 700.0, 1e4])
    assert shape_groups(alpha) == [[0, 1, 2], [3]]
    assert shape_groups(alpha[::-1]) == [[3, 2, 1], [0]]
    assert shape_groups(np.array([100.0, 290.0, 850.0, 2500.0])) == [[0, 1, 2, 3]]


def _training_stack():
    exp = design_experiment(SEED, "none", held_out="covered")
    return training_stack(exp), truth_rate_vector(exp.truth())


def test_a_spoiled_shape_is_restored_where_it_fits_better():
    train, x = _training_stack()
    spoiled = RATE_LAYOUT.as_table(x).copy()
    spoiled[0, ALPHA] *= 1000.0
    spoiled[0, STATIC] = 6.0 * spoiled[0, COULOMB]
    start = RATE_LAYOUT.from_table(spoiled)
    # One iteration cannot walk the shape back.
    fit = fit_candidates(train, start, ["none"], max_iter=1)["none"]
    t = RATE_LAYOUT.as_table(fit.rate_vector)
    ratio = t[:, STATIC] / t[:, COULOMB]
    spread = np.log(SHAPE_SPREAD)
    assert abs(np.log(t[0, ALPHA] / np.median(t[1:, ALPHA]))) < spread
    assert abs(np.log(ratio[0] / np.median(ratio[1:]))) < spread
    # ... and the training runs are fitted as well as from the truth.
    truth = fit_candidates(train, x, ["none"], max_iter=1)["none"]
    assert fit.sse <= 1.05 * truth.sse
