"""Test helper: a stand-in for a diagnosis round's state
(`isp_twin.diagnosis.rounds._RoundState`) that records what a stage wrote
back, for stage tests that stub the refits."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


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
