"""An effect placed along its trade with the friction levels by the held-out run.

On runs whose drive and motion keep one sign (the Eq. 7 cosine runs) an
effect may trade exactly against the friction levels: beyond a dead zone
the drive loses the motor gain times the width, as while sliding it loses
the Coulomb level. A wider band under levels lowered by as much fits the
training runs alike, and the refit leaves the width where its start put it.
A held-out run of another excitation (a multisine, whose drive reverses
while the axis still moves) tells them apart.

`placed_along_trade` scans the effect's `Effect.trade_parameter` along that
trade (the levels moved with it, nothing else), keeps the points whose
training cost stays within `TRADE_UNSEEN` of the fit's and the base's, and
takes the one the held-out run fits best. The training runs do not see the
move; the held-out run sets the one thing they leave open, so for that
parameter it is a fitting run, as it is already the run that selects the
effect (docs/diagnosis.md "Stop 53").

Reference dead zone 344 (covered design, a 114-digit band; the case that
shaped this): the refits from the width starts ended at 75, 152, 228 and
305 digits, all within 0.5 % of each other on the training runs, 7 to 49
noise floors held out. Along the trade from any of them the training cost
stays the same to four digits and the held-out run is lowest at 114 digits,
0.95 noise floors.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from isp_twin.diagnosis.candidates import BASELINE, CandidateFit, levels_taken
from isp_twin.estimation.information import bic
from isp_twin.estimation.simulation_error import RunStack, residuals_many
from isp_twin.model.effects import effect_class
from isp_twin.model.parameters import RATE_LAYOUT

__all__ = ["placed_along_trade"]

#: A move along the trade that raises the training sse by less than this
#: share of the fit's is one the training runs do not see (the project's
#: "clearly better" is 1 %; a tenth of it).
TRADE_UNSEEN = 1e-3
#: The scan runs from 0 to this many times the larger of the fitted value
#: and the value that would take the median regime's Coulomb level to 0.
TRADE_REACH = 2.0
#: Points of the coarse scan, and of the fine one between the coarse best's
#: neighbours.
TRADE_COARSE = 41
TRADE_FINE = 21


def placed_along_trade(
    train: RunStack, held: RunStack, fit: CandidateFit, ceiling: float
) -> CandidateFit:
    """`fit` moved along its effect's trade with the friction levels to the
    point the `held` runs fit best, among those whose training sse stays
    below both the fit's times (1 + `TRADE_UNSEEN`) and `ceiling` (the
    base's: a candidate never fits worse than the model without it); `fit`
    itself where its effect has no `trade_parameter` or no such point is
    better held out. The intervals are the fit's, the placed parameter's
    NaN (the training runs do not bound it). The placed parameter is
    recorded (`CandidateFit.placed`) and no longer charged by the training
    BIC: the training runs do not see it, and the held-out rules
    (`isp_twin.diagnosis.selection`) are its evidence."""
    cls = None if fit.name == BASELINE else effect_class(fit.name)
    name = None if cls is None else cls.trade_parameter
    if name is None:
        return fit
    v0 = float(fit.params[name])
    per_unit = _levels_moved(cls, fit, name, np.array([0.0, 1.0]), train.dt)
    per_unit = per_unit[1] - per_unit[0]
    if not np.all(per_unit > 0):
        return fit
    span = float(np.median(RATE_LAYOUT.column(fit.rate_vector, "coulomb") / per_unit))
    coarse = np.linspace(0.0, TRADE_REACH * max(v0, span), TRADE_COARSE)
    best = _best_on_trade(train, held, fit, cls, name, coarse, ceiling)
    if best is None:
        return fit
    i = int(np.argmin(np.abs(coarse - best[0])))
    fine = np.linspace(coarse[max(i - 1, 0)], coarse[min(i + 1, TRADE_COARSE - 1)], TRADE_FINE)
    best = _best_on_trade(train, held, fit, cls, name, fine, ceiling)
    if best is None:
        return fit
    value, row, sse = best
    k = fit.n_params - (name not in fit.placed)
    return replace(
        fit,
        params={**fit.params, name: value},
        # The training Jacobian's interval does not apply to it.
        ci95={**fit.ci95, name: float("nan")},
        rate_vector=row,
        sse=sse,
        n_params=k,
        bic=bic(sse, fit.n_samples, k),
        placed=tuple(sorted({*fit.placed, name})),
    )


def _best_on_trade(
    train, held, fit, cls, name, values, ceiling
) -> tuple[float, np.ndarray, float] | None:
    """(value, rate vector, training sse) of the point among `values` the
    held-out runs fit best with the training sse within bounds
    (`placed_along_trade`); None where the fit's own point, competing on
    the held-out runs, is that one. The held-out runs are simulated only at
    the points within bounds."""
    rows = _rows(cls, fit, name, values, train.dt)
    ok = np.all(_levels(rows) > 0.0, axis=1)
    if not ok.any():
        return None
    values, rows = values[ok], rows[ok]
    trained = _sse(train, fit, name, rows, values)
    seen = trained <= min(fit.sse * (1.0 + TRADE_UNSEEN), ceiling)
    # The fit's own point last, in the same batch.
    held_sse = _sse(
        held,
        fit,
        name,
        np.vstack([rows[seen], np.asarray(fit.rate_vector, float)]),
        np.append(values[seen], float(fit.params[name])),
    )
    k = int(np.argmin(held_sse))
    if k == len(held_sse) - 1:
        return None
    return float(values[seen][k]), rows[seen][k], float(trained[seen][k])


def _levels_moved(cls, fit, name, values, dt: float) -> np.ndarray:
    """(G, regimes): what the effect at each of `values` takes off the
    static and Coulomb levels per sample (`candidates.levels_taken`), its
    other parameters at the fit's."""
    gain = RATE_LAYOUT.column(fit.rate_vector, "gain")
    return levels_taken(cls, [{**fit.params, name: v} for v in values], gain, dt)


def _rows(cls, fit, name, values, dt: float) -> np.ndarray:
    """(G, `RATE_LAYOUT.size`): the fit's rate vector with the levels moved
    by the difference of what the effect takes at each value and at the
    fitted one."""
    moved = _levels_moved(cls, fit, name, np.append(values, fit.params[name]), dt)
    shift = moved[:-1] - moved[-1]
    rows = np.tile(np.asarray(fit.rate_vector, float), (len(values), 1))
    for field in ("static", "coulomb"):
        idx = list(RATE_LAYOUT.field_indices(field))
        rows[:, idx] -= shift
    return rows


def _levels(rows) -> np.ndarray:
    """(G, 2 x regimes): the static and Coulomb levels of each row."""
    idx = [*RATE_LAYOUT.field_indices("static"), *RATE_LAYOUT.field_indices("coulomb")]
    return rows[:, idx]


def _sse(stack, fit, name, rows, values) -> np.ndarray:
    """(G,): the sum of squared residuals on `stack` of each row, the
    effect at the row's value, its other parameters at the fit's."""
    params = {p: np.full(len(values), float(v)) for p, v in fit.params.items()}
    params[name] = np.asarray(values, float)
    res = residuals_many(stack, [(rows, fit.name, params)], fit.fixed)[0]
    return np.einsum("ij,ij->i", res, res)
