"""diagnose's global refits run `identify` without its differential evolution
(`rounds._refit_globally`, `rounds.GLOBAL_GENERATIONS`; docs/diagnosis.md
"Stop 57"), as every other `identify_held` of diagnose already did.

On reference LuGre seed 367 the 20 generations and the least squares from
their best lowered the training cost of its three global refits by at most
a third of a percent, at up to 46 s each. These tests pin the wiring; the
figures, and the paired benchmark of the change, are in the docs."""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest
from round_state_double import fit_double

from isp_twin.diagnosis import rounds
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import EffectSpec


@pytest.mark.parametrize("free", [True, False])
def test_the_global_refit_asks_identify_for_no_generations(monkeypatch, free):
    seen = {}

    def identify_held(data, effects, timing, **options):
        seen.update(options)
        return SimpleNamespace(vector=np.arange(20.0))

    def fit_candidates(train, x, names, fixed, starts, max_iter):
        return {names[0]: fit_double(names[0], starts[names[0]], 1.0)}

    monkeypatch.setattr(rounds, "identify_held", identify_held)
    monkeypatch.setattr(rounds, "fit_candidates", fit_candidates)
    data = SimpleNamespace(timing=Timing(0.0, True), train="stack", max_iter=8)
    fit = SimpleNamespace(name="cogging", params={"amplitude_rad_s2": 1.0}, fixed=())
    rounds._refit_globally(data, fit, free_read_out=free)
    assert rounds.GLOBAL_GENERATIONS == 0
    assert seen == {"generations": 0}


@dataclass(frozen=True)
class _Axis:
    effects: tuple = ()


def test_identify_held_hands_the_generations_to_identify_with_diagnose_settings(monkeypatch):
    seen = {}

    def identify(runs, ax, settings):
        seen["settings"], seen["ax"] = settings, ax
        return "result"

    monkeypatch.setattr(rounds, "identify", identify)
    integration = object()
    data = SimpleNamespace(
        side_source="measured",
        seed=3,
        train=SimpleNamespace(integration=integration),
        runs=SimpleNamespace(raw=["run"]),
        ax=_Axis(),
        identified={},
    )
    held = EffectSpec("cogging", {"amplitude_rad_s2": 1.0})
    assert rounds.identify_held(data, [held], Timing(0.5, True), generations=0) == "result"
    s = seen["settings"]
    assert (s.generations, s.timing, s.seed) == (0, Timing(0.5, True), 3)
    assert s.regime_spread is None and not s.restart_at_noise
    assert s.integration is integration
    assert seen["ax"] == _Axis(effects=(held,))
