"""The held-out samples the training runs determine, for one fitted model.

A regime's static level decides when the axis breaks away from rest there.
Where the model never breaks away in a regime on the training runs, they do
not measure that level (`isp_twin.estimation.coverage`, "untrained
breakaways"). A held-out run that rests against such a regime is judged,
from that rest on, on a level no data placed. The samples before the
model's first such rest are the part the training runs determine
(`coverage.first_untrained_rest`).

`determined_part` judges a model with an effect against the refit without
it on that part alone: the same acceptance rule as the rounds
(`selection.judge`), and the model's error there over the noise floor.
`search._explains_training` adopts an effect that explains the training
runs and reaches the noise on the determined part even where it removes
less than `search.EXPLAINED_SHARE` of the whole held-out excess
(docs/diagnosis.md "Stop 75").

The part is taken from the model with the effect: it asks whether that
model is right where the training runs determine it. Both residuals are
cut at the same sample, so the comparison is paired.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isp_twin.diagnosis.candidates import CandidateFit
from isp_twin.diagnosis.prepared_runs import DiagnosisData
from isp_twin.diagnosis.selection import BLOCK, judge
from isp_twin.estimation.coverage import (
    breakaway_counts,
    first_untrained_rest,
    rest_counts,
    untrained_breakaways,
)
from isp_twin.estimation.simulation_error import RunStack, predict_one
from isp_twin.vocabulary import REGIMES

__all__ = ["MIN_BLOCKS", "DeterminedHeldOut", "determined_part", "untrained_cuts"]

#: The determined part must hold at least this many of the rule's blocks
#: (`selection.BLOCK` samples each) before it is judged: the rule's
#: standard error comes from the blocks' spread, and with 20 of them a
#: z of 3 is still a p of about 0.004 on Student's t with 19 degrees of
#: freedom (with 4 blocks, 0.03).
MIN_BLOCKS = 20


@dataclass(frozen=True)
class DeterminedHeldOut:
    """A model judged on the held-out part the training runs determine.

    Attributes:
        samples: held-out residual samples in the part, over all runs.
        of_samples: held-out residual samples in all.
        over_noise: the model's RMS error on the part over the noise floor.
        base_over_noise: the refit without the effect's, on the same part.
        improvement_z: the rule's z on the part (`selection.judge`).
        significant: the rule holds on the part.
    """

    samples: int
    of_samples: int
    over_noise: float
    base_over_noise: float
    improvement_z: float
    significant: bool


def _own_runs(stack: RunStack, fit: CandidateFit) -> tuple[list, list]:
    """Per run of `stack`, the model's own rate [rad/s] (exactly 0 at rest)
    and the regime index of each step, up to the run's last sample."""
    r = predict_one(stack, fit.rate_vector, fit.effects())
    own = r.omega if r.omega_true is None else r.omega_true
    ends = [int(np.flatnonzero(m)[-1]) + 1 if m.any() else 0 for m in stack.mask]
    return [own[i, :n] for i, n in enumerate(ends)], [r.regime[i, :n] for i, n in enumerate(ends)]


def untrained_cuts(data: DiagnosisData, fit: CandidateFit) -> tuple[int, ...] | None:
    """Per held-out run, the sample where `fit`'s model first rests against
    a regime it never breaks away in on the training runs (the run's length
    where it never does); None without held-out runs."""
    if data.held is None:
        return None
    rates, regimes = _own_runs(data.train, fit)
    trained = breakaway_counts(rates, regimes)
    h_rates, h_regimes = _own_runs(data.held, fit)
    untrained = untrained_breakaways(trained, rest_counts(h_rates, h_regimes))
    wanted = [REGIMES.index(b.regime) for b in untrained]
    return tuple(first_untrained_rest(w, g, wanted) for w, g in zip(h_rates, h_regimes))


def determined_part(
    data: DiagnosisData,
    fit: CandidateFit,
    base: CandidateFit,
    before: Sequence[np.ndarray],
    after: Sequence[np.ndarray],
    noise_floor: float,
) -> DeterminedHeldOut | None:
    """`fit` (held-out residuals `after`, one array per run over its counted
    samples, `RunStack.mask`) against `base` (`before`) on the samples
    before `fit`'s first untrained rest (`untrained_cuts`) [rad/s]; None
    without held-out runs or where the part holds fewer than `MIN_BLOCKS`
    blocks."""
    cuts = untrained_cuts(data, fit)
    if cuts is None:
        return None
    # The residuals start after the stack's warm-up: count the counted
    # samples before each cut.
    keep = [int(m[:c].sum()) for m, c in zip(data.held.mask, cuts)]
    b = [np.asarray(x)[:k] for x, k in zip(before, keep)]
    a = [np.asarray(x)[:k] for x, k in zip(after, keep)]
    n = sum(x.size for x in a)
    if n < MIN_BLOCKS * BLOCK:
        return None
    v = judge(fit.name, b, a, base.bic, fit.bic, noise_floor)

    def over(parts):
        return float(np.sqrt(np.mean(np.concatenate(parts) ** 2))) / noise_floor

    total = sum(np.size(x) for x in after)
    return DeterminedHeldOut(n, total, over(a), over(b), v.improvement_z, v.significant)
