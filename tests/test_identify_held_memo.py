"""`rounds.identify_held` runs `identify` once per question on the same data
(`DiagnosisData.identified`; docs/diagnosis.md "Stop 66"): the read-out
stages of diagnose asked it twice for the same fit (reference input delay
seed 408, 7 s of 56). These tests pin the memo on a stand-in `identify`
that counts its calls."""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import SimpleNamespace

import pytest

from isp_twin.diagnosis import rounds
from isp_twin.diagnosis.prepared_runs import DiagnosisData
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import EffectSpec
from isp_twin.model.substep_model import DEFAULT_INTEGRATION

DELAY = EffectSpec("input_delay", {"delay_s": 0.004})


@dataclass(frozen=True)
class _Axis:
    """What `identify_held` asks of the axis: its effects, to replace."""

    effects: tuple = ()


@pytest.fixture
def calls(monkeypatch):
    """The (effects, timing, generations) of each `identify` call; each
    call returns a new object."""
    seen = []

    def identify(runs, ax, settings):
        seen.append((ax.effects, settings.timing, settings.generations))
        return object()

    monkeypatch.setattr(rounds, "identify", identify)
    return seen


def _data() -> DiagnosisData:
    runs = SimpleNamespace(raw=[], train=[], holdout=[])
    train = SimpleNamespace(integration=DEFAULT_INTEGRATION)
    timing = Timing(0.0, True)
    return DiagnosisData(
        runs, _Axis(), train, None, (), "measured", timing, DEFAULT_INTEGRATION, 0, 8, 4
    )


def test_the_same_question_twice_runs_identify_once(calls):
    data = _data()
    first = rounds.identify_held(data, (DELAY,), timing=None, generations=0)
    again = rounds.identify_held(data, [EffectSpec("input_delay", {"delay_s": 0.004})],
                                 timing=None, generations=0)  # fmt: skip
    assert again is first
    assert len(calls) == 1


@pytest.mark.parametrize(
    "other",
    [
        dict(effects=(EffectSpec("input_delay", {"delay_s": 0.005}),), timing=None),
        dict(effects=(), timing=None),
        dict(effects=(DELAY,), timing=Timing(0.0, True)),
        dict(effects=(DELAY, EffectSpec("cogging", {"amplitude_rad_s2": 1.0})), timing=None),
    ],
)
def test_another_question_runs_identify_again(calls, other):
    data = _data()
    first = rounds.identify_held(data, (DELAY,), timing=None, generations=0)
    assert rounds.identify_held(data, generations=0, **other) is not first
    assert len(calls) == 2


def test_other_options_run_identify_again(calls):
    data = _data()
    first = rounds.identify_held(data, (DELAY,), timing=None, generations=0)
    assert rounds.identify_held(data, (DELAY,), timing=None, generations=20) is not first
    assert [c[2] for c in calls] == [0, 20]


def test_other_data_do_not_share_the_results(calls):
    data = _data()
    rounds.identify_held(data, (DELAY,), timing=None, generations=0)
    raw = replace(data, side_source="raw")
    assert raw.identified == {}
    rounds.identify_held(raw, (DELAY,), timing=None, generations=0)
    rounds.identify_held(_data(), (DELAY,), timing=None, generations=0)
    assert len(calls) == 3
