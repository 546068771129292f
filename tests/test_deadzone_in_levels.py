"""A dead zone the base carries in its friction levels is found from starts
with those levels lowered (`Deadzone.refined_starts`, `drive_taken_digits`,
`candidates._friction_lowered`; docs/diagnosis.md "Stop 50").

On cosine runs a drive beyond the band loses the motor gain times the width,
as it loses the Coulomb friction while sliding: a base fitted without the
dead zone raises its levels by that much, and a width guessed at those levels
fits no better. The base here is that equivalent base, made from the truth
of a reference axis (the reference simulator shares no code with the model):
the true rate parameters with every regime's static and Coulomb levels
raised by its gain times the true width.
"""

from __future__ import annotations

import numpy as np
from truth_error import training_stack, truth_rate_vector

from isp_twin.diagnosis.candidates import fit_candidates
from isp_twin.model.effects.deadzone import Deadzone
from isp_twin.model.parameters import RATE_LAYOUT
from isp_twin.reference import design_experiment

SEED = 334  # reference dead zone 334, covered design: a 126-digit band


def _case():
    exp = design_experiment(SEED, "deadzone", held_out="covered")
    truth = exp.truth()
    x = truth_rate_vector(truth)
    width = truth["effects"][0]["params"]["width_digits"]
    return training_stack(exp), x, width


def _carried(x: np.ndarray, width: float) -> np.ndarray:
    """`x` with each regime's static and Coulomb levels raised by its gain
    times `width`: the base that carries the dead zone in its levels."""
    out = x.copy()
    gain = RATE_LAYOUT.column(x, "gain")
    for field in ("static", "coulomb"):
        idx = list(RATE_LAYOUT.field_indices(field))
        out[idx] = out[idx] + gain * width
    return out


def test_the_band_is_found_beneath_the_levels_that_carry_it():
    train, x, width = _case()
    base_x = _carried(x, width)
    fits = fit_candidates(train, base_x, ["none", "deadzone"], (), max_iter=8)
    base, dz = fits["none"], fits["deadzone"]
    assert abs(dz.params["width_digits"] / width - 1.0) < 0.05
    # With the band the training runs are fitted better than the base can.
    assert dz.sse < 0.98 * base.sse


def test_starts_span_the_levels_in_digits():
    # The starts are shares of the base's Coulomb level over its gain.
    train, x, width = _case()
    base_x = _carried(x, width)
    levels = RATE_LAYOUT.column(base_x, "coulomb") / RATE_LAYOUT.column(base_x, "gain")
    ctx = type("Ctx", (), {"coulomb_digits": float(np.median(levels))})()
    widths = [s["width_digits"] for s in Deadzone.refined_starts(ctx)]
    assert widths == sorted(widths)
    assert 0.0 < widths[0] and widths[-1] < float(np.min(levels))
    ctx.coulomb_digits = float("nan")
    assert Deadzone.refined_starts(ctx) == []
