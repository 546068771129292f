"""The acceptance rule: is a candidate's improvement real?

A candidate effect is *significant* when all four hold:

1. Held-out improvement beyond chance: with the held-out residuals r0
   (without) and r1 (with the effect) and their difference ``delta = r0 -
   r1`` (what the effect explains), the MSE gain is the mean of
   ``d = r0^2 - r1^2 = delta^2 + 2*delta*r1``. Only the cross term is random
   (the noise left in r1 times the explained part); the gain must exceed
   `Z_MIN` = 3 standard errors of it. The standard error comes from means of
   ``2*delta*r1`` over blocks of `BLOCK` = 25 samples (residuals are
   correlated over ~1/(1-a) ~ 10 samples). A candidate that only fits noise
   explains nothing on held-out data: its ``delta`` is uncorrelated with r1
   and the gain is about ``-mean(delta^2) < 0``.
2. Material against the noise: the MSE drops by more than `MIN_GAIN` = 5 %
   of the noise variance (noise floor squared). An effect that explains less
   than that is indistinguishable from fitting noise with 20+ parameters,
   whatever its z.
3. Material against the error: the MSE drops by at least `MIN_SHARE` = 2 %
   of the baseline's held-out MSE. Where the model misses far more than the
   noise (real data), a real but negligible effect is not worth a term.
4. Information criterion: its training BIC is lower than the model's without
   it (`isp_twin.estimation.information.bic`: M ln(SSE/M) + k ln M; the
   effect's extra parameters must pay for themselves). A parameter the
   held-out run placed (`CandidateFit.placed`, `isp_twin.diagnosis.trade`)
   is not among the k: the training runs do not see it.

Among significant candidates the one with the lowest held-out RMSE is
selected; near-ties (within `MIN_GAIN` of the noise variance) go to the
lowest BIC. If none is significant the answer is "no missing effect found".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["BLOCK", "MIN_GAIN", "Z_MIN", "Verdict", "judge", "select"]

Z_MIN = 3.0
BLOCK = 25
MIN_GAIN = 0.05
MIN_SHARE = 0.02


@dataclass(frozen=True)
class Verdict:
    """A candidate judged against the model without it.

    Attributes:
        name: effect name.
        holdout_rmse: held-out RMS residual with the effect [rad/s].
        improvement_z: mean squared-error improvement / its block standard error.
        delta_bic: BIC(with) - BIC(without) on the training data.
        significant: both rules hold.
        reason: one line saying why (not).
    """

    name: str
    holdout_rmse: float
    improvement_z: float
    delta_bic: float
    significant: bool
    reason: str


def _blocks(d_runs: Sequence[np.ndarray], block: int) -> np.ndarray:
    means = []
    for d in d_runs:
        n = d.size // block
        if n:
            means.extend(d[: n * block].reshape(n, block).mean(axis=1))
        elif d.size:
            means.append(d.mean())
    return np.array(means)


def judge(
    name: str,
    before: Sequence[np.ndarray],
    after: Sequence[np.ndarray],
    bic_before: float,
    bic_after: float,
    noise_floor: float,
    z_min: float = Z_MIN,
    block: int = BLOCK,
    min_gain: float = MIN_GAIN,
) -> Verdict:
    """Apply the rule (module doc) to held-out residuals (one array per run) [rad/s]."""
    before = [np.asarray(b, float) for b in before]
    after = [np.asarray(a, float) for a in after]
    d = np.concatenate([b**2 - a**2 for b, a in zip(before, after)])
    cross = _blocks([2.0 * (b - a) * a for b, a in zip(before, after)], block)
    mean = float(d.mean())
    se = float(cross.std(ddof=1) / np.sqrt(cross.size)) if cross.size > 1 else float("inf")
    z = mean / se if se > 0 else (np.inf if mean > 0 else 0.0)
    rmse = float(np.sqrt(np.mean(np.concatenate([np.asarray(a) for a in after]) ** 2)))
    dbic = float(bic_after - bic_before)
    gain = mean / noise_floor**2 if noise_floor > 0 else float("inf")
    mse_before = float(np.mean(np.concatenate(before) ** 2))
    share = mean / mse_before if mse_before > 0 else 0.0
    ok_z, ok_gain, ok_bic = z > z_min, gain > min_gain and share >= MIN_SHARE, dbic < 0
    if ok_z and ok_gain and ok_bic:
        reason = (
            f"held-out MSE lower by {z:.1f} standard errors ({gain:.2g} x noise variance), "
            f"BIC lower by {-dbic:.1f}"
        )
    elif not ok_z:
        reason = f"held-out improvement {z:.1f} standard errors, needs > {z_min:g}"
    elif gain <= min_gain:
        reason = f"held-out MSE gain {gain:.2g} x noise variance, needs > {min_gain:g}"
    elif not ok_gain:
        reason = f"held-out MSE gain {share:.1%} of the error, needs >= {MIN_SHARE:.0%}"
    else:
        reason = f"BIC higher by {dbic:.1f}"
    return Verdict(name, rmse, float(z), dbic, ok_z and ok_gain and ok_bic, reason)


def select(
    verdicts: Sequence[Verdict], noise_floor: float = 0.0, min_gain: float = MIN_GAIN
) -> Verdict | None:
    """The significant verdict with the lowest held-out RMSE, or None.

    Candidates whose held-out MSE is within ``min_gain * noise_floor^2`` of
    the best are a tie on held-out data (the same margin the rule asks of any
    gain); ties go to the lowest BIC (a cable spring and an unbalance agree
    over a small angle range; the training fit over all runs tells them apart).
    """
    ok = [v for v in verdicts if v.significant]
    if not ok:
        return None
    best = min(v.holdout_rmse for v in ok) ** 2
    ties = [v for v in ok if v.holdout_rmse**2 <= best + min_gain * noise_floor**2]
    return min(ties, key=lambda v: v.delta_bic)
