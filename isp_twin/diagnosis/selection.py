"""The acceptance rule: is a candidate's improvement real?

A candidate effect is *significant* when all three hold:

1. Held-out improvement beyond chance: with ``d[k] = r_before[k]^2 -
   r_after[k]^2`` on the held-out samples, averaged over blocks of `BLOCK`
   = 25 samples (residuals are correlated over ~1/(1-a) ~ 10 samples, so
   single samples are not independent), either the mean of d (= MSE before
   minus MSE after) exceeds `Z_MIN` = 2 block standard errors, or a one-sided
   Wilcoxon signed-rank test of the block means gives p < `P_MAX` = 0.01.
   The first catches a large gain on a few blocks (a saturation at the
   peaks), the second a consistent gain everywhere whose size varies a lot
   from block to block (a gyro bias, a ringing mode), which makes the mean
   test weak.
2. Material against the noise: the MSE drops by more than `MIN_GAIN` = 5 %
   of the noise variance (noise floor squared). An effect that explains less
   than that is indistinguishable from fitting noise with 20+ parameters,
   whatever its z.
3. Information criterion: its training BIC is lower than the model's without
   it (BIC = M ln(SSE/M) + k ln M; the effect's extra parameters must pay for
   themselves).

Among significant candidates the one with the lowest held-out RMSE is
selected. If none is significant the answer is "no missing effect found".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Z_MIN", "P_MAX", "BLOCK", "MIN_GAIN", "Verdict", "judge", "select"]

Z_MIN = 2.0
BLOCK = 25
MIN_GAIN = 0.05
P_MAX = 0.01


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
    d_runs = [np.asarray(b) ** 2 - np.asarray(a) ** 2 for b, a in zip(before, after)]
    means = _blocks(d_runs, block)
    d = np.concatenate(d_runs)
    mean = float(d.mean())
    se = float(means.std(ddof=1) / np.sqrt(means.size)) if means.size > 1 else float("inf")
    z = mean / se if se > 0 else (np.inf if mean > 0 else 0.0)
    rmse = float(np.sqrt(np.mean(np.concatenate([np.asarray(a) for a in after]) ** 2)))
    dbic = float(bic_after - bic_before)
    gain = mean / noise_floor**2 if noise_floor > 0 else float("inf")
    p_rank = 1.0
    if means.size >= 6 and np.any(means != 0):
        from scipy.stats import wilcoxon

        p_rank = float(wilcoxon(means, alternative="greater").pvalue)
    ok_z, ok_gain, ok_bic = (z > z_min or p_rank < P_MAX), gain > min_gain, dbic < 0
    if ok_z and ok_gain and ok_bic:
        reason = (
            f"held-out MSE lower by {z:.1f} standard errors (rank test p={p_rank:.1g}; "
            f"{gain:.2g} x noise variance), BIC lower by {-dbic:.1f}"
        )
    elif not ok_z:
        reason = (
            f"held-out improvement {z:.1f} standard errors (needs > {z_min:g}), "
            f"rank test p={p_rank:.2g} (needs < {P_MAX:g})"
        )
    elif not ok_gain:
        reason = f"held-out MSE gain {gain:.2g} x noise variance, needs > {min_gain:g}"
    else:
        reason = f"BIC higher by {dbic:.1f}"
    return Verdict(name, rmse, float(z), dbic, ok_z and ok_gain and ok_bic, reason)


def select(verdicts: Sequence[Verdict]) -> Verdict | None:
    """The significant verdict with the lowest held-out RMSE, or None."""
    ok = [v for v in verdicts if v.significant]
    return min(ok, key=lambda v: v.holdout_rmse) if ok else None
