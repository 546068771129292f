"""From a fitted rate vector to a parameter file's axis, the one way.

Identify and diagnose both end with a rate-form vector (b fixed), its 95 %
half-widths, the effects of the fitted model and the model it was fitted
with (`FittedWith`); `fitted_axis` turns those into the paper form (Table 2)
of an `AxisParams`, and `stored_form` says what the file's 6 significant
digits give back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from isp_twin.model.parameters import (
    RATE_LAYOUT,
    AxisParams,
    EffectSpec,
    FittedWith,
    RateParams,
    RegimeParams,
)
from isp_twin.units import DEG

__all__ = ["fitted_axis", "stored_form"]


def fitted_axis(
    prior: AxisParams,
    rate_vector: np.ndarray,
    rate_ci95: np.ndarray,
    effects: Sequence[EffectSpec],
    record: FittedWith,
    note: str,
    identified: tuple[bool, ...] | None = None,
) -> AxisParams:
    """The paper form of a fit, b fixed to the prior's b.

    Ke = b·Ke / b etc.; the half-widths scale the same way (b carries no
    uncertainty: it is fixed, its half-width is NaN).

    Args:
        prior: the axis the fit started from (its b, and what it keeps).
        rate_vector: fitted rate form, (`RATE_LAYOUT.size`,) (`RateParams.to_vector`).
        rate_ci95: its 95 % half-widths, same shape (NaN: no interval).
        effects: the fitted model's effects (written as the axis' ``effects:``).
        record: the model the fit used (the axis' ``fitted_with:``).
        note: the axis' note.
        identified: per regime, False where the fit froze it at the prior
            (that regime keeps the prior's values and gets no interval);
            None: every regime fitted, the prior's flags kept.
    """
    b = tuple(r.b for r in prior.regimes)
    regimes = list(RateParams.from_vector(rate_vector).to_regimes(b))
    ci_regimes: list[RegimeParams | None] = [
        replace(ci, b=float("nan")) for ci in RateParams.from_vector(rate_ci95).to_regimes(b)
    ]
    for r in range(RATE_LAYOUT.n_regimes):
        if identified is not None and not identified[r]:
            regimes[r], ci_regimes[r] = prior.regimes[r], None
    return replace(
        prior,
        regimes=tuple(regimes),
        ci95=tuple(ci_regimes),
        identified=prior.identified if identified is None else tuple(identified),
        effects=tuple(EffectSpec(e.name, dict(e.params)) for e in effects),
        note=note,
        fitted_with=record,
    )


def stored_form(x: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rate-form vectors (..., `RATE_LAYOUT.size`) as they come back from a parameter file.

    The file holds the paper form (b fixed, one b per regime, shape (n_regimes,))
    to 6 significant digits (`isp_twin.model.parameters.save_parameters`); this
    applies the same rounding.
    """
    x = RATE_LAYOUT.as_table(np.asarray(x, dtype=float))
    levels = [RATE_LAYOUT.field_index(f) for f in ("gain", "static", "coulomb")]
    alpha = RATE_LAYOUT.field_index("alpha")
    paper = x.copy()
    paper[..., levels] = x[..., levels] / DEG / b[:, None]
    paper[..., alpha] = x[..., alpha] * DEG
    rounded = np.vectorize(lambda v: float(f"{v:.6g}"))(paper)
    out = rounded.copy()
    out[..., levels] = rounded[..., levels] * DEG * b[:, None]
    out[..., alpha] = rounded[..., alpha] / DEG
    return RATE_LAYOUT.from_table(out)
