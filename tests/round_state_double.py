"""Test helpers: a stand-in for a diagnosis round's state
(`isp_twin.diagnosis.rounds._RoundState`) that records what a stage wrote
back, and for its candidate fits, for stage tests that stub the refits."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any


def fit_double(name: str, params: dict | None = None, sse: float = 0.0, bic: float = 0.0):
    """A candidate fit as the stages read it: name, effect params, training sse
    and BIC, and the training RMS error as of one sample (rmse = sqrt(sse))."""
    params = {} if params is None else params
    return SimpleNamespace(name=name, params=params, sse=sse, bic=bic, rmse=sse**0.5)


@dataclass
class RoundStateDouble:
    """`fits`, `held_of`, `base`, `floor` and `failed` as the stage reads
    them; `updated` collects every refit the stage kept (`update`);
    `judged_again` appends the refitted names to the verdicts."""

    fits: dict
    held_of: dict = field(default_factory=dict)
    base: Any = None
    floor: float = 1.0
    failed: set = field(default_factory=set)
    updated: dict = field(default_factory=dict)

    def update(self, data, refits):
        self.updated.update(refits)
        self.fits.update(refits)

    def judged_again(self, verdicts, again):
        return verdicts + sorted(again)
