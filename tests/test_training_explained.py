"""Effects adopted though the held-out error stays above the noise, where
they explain the training runs (`search._explains_training`).

Until stop 45 every effect that left the held-out error above
`CONVERGED_RATIO` noise floors was set aside as tentative and `diagnose`
answered `none`, even where the model with it fitted the training runs at
the noise and took the held-out error from 233 to 3.6 noise floors
(reference sensor bias seed 305: the bias found to 0.2 %; what is left lies
in a regime the training runs barely visit). The rule is checked here on
rounds built by hand, the numbers chosen so that each condition decides;
seed 305 end to end is pinned in
`benchmarks/pinned_axes/test_training_explained_305.py`.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from isp_twin.commands.diagnose import _none_found
from isp_twin.diagnosis import search
from isp_twin.diagnosis.determined import DeterminedHeldOut
from isp_twin.diagnosis.report import _none_note
from isp_twin.diagnosis.result import Diagnosis, RoundResult, TentativeFit, TrainingExplained
from isp_twin.estimation.verdict import CONVERGED_RATIO

FLOOR = 5e-4  # rad/s
N = 10_000


def _held(ratio: float) -> tuple:
    """A held-out residual whose RMS is `ratio` noise floors."""
    return (np.full(N, ratio * FLOOR),)


def _rounds(train: float, before: float, after: float, name: str = "sensor_bias") -> list:
    """One accepted round: the model with `name` at `train` noise floors on the
    training runs, the refit without it at `before` held out, with it at `after`."""
    fit = SimpleNamespace(name=name, sse=(train * FLOOR) ** 2 * N, n_samples=N)
    rnd = RoundResult(
        baseline=SimpleNamespace(name="none"),
        fits={name: fit},
        verdicts=(),
        selected=name,
        holdout_before=_held(before),
        holdout_after=_held(after),
        noise_floor=FLOOR,
    )
    return [rnd]


def _record(rounds: list) -> TrainingExplained | None:
    kept = search._explains_training(rounds)
    return None if kept is None else kept[1]


def test_an_effect_that_explains_the_training_runs_is_kept():
    rounds = _rounds(train=1.02, before=233.0, after=3.6)
    kept, got = search._explains_training(rounds)
    assert kept == rounds
    assert got.training_over_noise == pytest.approx(1.02)
    assert got.excess_removed == pytest.approx(1.0 - (3.6**2 - 1.0) / (233.0**2 - 1.0))


@pytest.mark.parametrize(
    ("train", "before", "after", "why"),
    [
        (1.6, 233.0, 3.6, "the training runs are not at the noise with the effect"),
        (1.0, 3.32, 3.01, "it removes 20 % of the held-out excess (clean axis 284)"),
        (1.0, 10.0, 5.0, "it removes 75.8 %, under the 90 % share"),
        (1.0, 10.0, 1.2, "the model is at the noise held out: nothing to explain"),
        (1.0, 1.4, 1.45, "the refit without an effect is already at the noise"),
    ],
)
def test_an_effect_that_does_not_is_left_tentative(train, before, after, why):
    assert _record(_rounds(train, before, after)) is None, why


def test_no_accepted_effect_explains_nothing():
    rnd = replace(_rounds(1.0, 233.0, 3.6)[0], selected="none")
    assert _record([rnd]) is None


def test_a_later_effect_that_does_not_explain_the_training_runs_is_set_aside_alone():
    # Round 2 adds an effect whose model leaves the training runs at 1.6
    # noise floors: round 1's effect, which explains them, is kept alone.
    first = _rounds(train=1.02, before=233.0, after=3.6, name="deadzone")[0]
    second = _rounds(train=1.6, before=3.6, after=3.5, name="input_delay")[0]
    kept, got = search._explains_training([first, second])
    assert [r.selected for r in kept] == ["deadzone", "none"]
    assert kept[1].holdout_after == second.holdout_before
    assert got.training_over_noise == pytest.approx(1.02)


def test_the_share_is_the_documented_ninety_per_cent():
    # From 10 noise floors, 90 % of the excess (10**2 - 1) removed leaves
    # after**2 - 1 = 9.9: after = sqrt(10.9), above the converged ratio.
    assert search.EXPLAINED_SHARE == 0.9
    after = float(np.sqrt(10.9))
    assert after > CONVERGED_RATIO
    assert _record(_rounds(1.0, 10.0, after * 0.999)) is not None
    assert _record(_rounds(1.0, 10.0, after * 1.001)) is None


def _diagnosis(
    explained: TrainingExplained | None,
    tentative: tuple[str, ...] = (),
    record: TentativeFit | None = None,
) -> Diagnosis:
    rounds = _rounds(1.02, 233.0, 3.6)
    return Diagnosis(
        axis="inner_az",
        rounds=tuple(rounds),
        rmse_before=233.0 * FLOOR,
        rmse_after=3.6 * FLOOR,
        noise_floor=FLOOR,
        params_out=None,
        analysis_before=None,
        analysis_after=None,
        explained=explained,
        tentative=tentative,
        tentative_fit=record,
    )


def test_the_verdict_says_why_the_effect_was_adopted_and_that_it_is_not_converged():
    got = _diagnosis(TrainingExplained(1.02, 0.9998))._verdict_json()
    assert got["converged"] is False
    assert got["rmse_over_noise_floor"] == pytest.approx(3.6)
    assert "NOT CONVERGED held out" in got["verdict"]
    assert "sensor_bias fits the training runs at 1.02 x the noise floor" in got["verdict"]
    assert "99.98 %" in got["verdict"]
    assert got["training_explained"] == {
        "training_over_noise_floor": 1.02,
        "held_out_excess_removed": 0.9998,
    }


def test_without_the_record_the_verdict_is_the_plain_not_converged():
    got = _diagnosis(None)._verdict_json()
    assert got["training_explained"] is None
    assert got["verdict"].startswith("held-out RMS error 3.60 x the noise floor: NOT CONVERGED: ")


@pytest.mark.parametrize(
    ("train", "tentative", "adopted"),
    [
        (1.06, ("unbalance",), "cable_spring"),
        (1.6, ("unbalance",), None),
        # two effects tentative: the other judged in a second round there
        # (`_others_there`, stubbed: it accepts nothing), the one that
        # explains the training runs adopted (until stop 51 both were left
        # tentative)
        (1.06, ("unbalance", "sensor_bias"), "cable_spring"),
    ],
)
def test_the_read_out_round_adopts_an_effect_that_explains_the_training_runs(
    monkeypatch, train, tentative, adopted
):
    """The round at the read-out a tentative effect chose (`_adopted_there`)
    applies the same rule (from stop 47): benchmark cable spring 312 at
    stop 46 reached 1.06 noise floors on the training runs and 716 -> 1.88
    held out there, and answered `none`. The round and the final model are
    stand-ins: the test pins the decision, `_final_diagnosis` its input."""
    rnd = _rounds(train, 716.0, 1.88, name="cable_spring")[0]
    monkeypatch.setattr(search, "_rival_starts", lambda diag, data, again: {})
    monkeypatch.setattr(search, "round_at_read_out", lambda there, starts, fixed: rnd)
    monkeypatch.setattr(search, "_others_there", lambda there, rnd, tentative: [])

    def final(data, params, axis, rounds, before_held, kept=None):
        assert rounds == [rnd]
        chosen = "none" if kept is None else kept[0][0].selected
        return SimpleNamespace(selected_effect=chosen, explained=None if kept is None else kept[1])

    monkeypatch.setattr(search, "_final_diagnosis", final)
    there = SimpleNamespace(ax=SimpleNamespace(effects=()))
    before = SimpleNamespace(selected_effect="none", tentative=tentative, axis="inner_az")
    got = search._adopted_there(before, None, there, None, None, _held(716.0))
    if adopted is None:
        assert got is before  # left as it was: the unbalance tentative
    else:
        assert got.selected_effect == adopted
        assert got.explained.training_over_noise == pytest.approx(train)


def _part(over: float, significant: bool = True) -> DeterminedHeldOut:
    return DeterminedHeldOut(2484, 5950, over, 5.17, 119.0 if significant else 2.0, significant)


@pytest.mark.parametrize(
    ("part", "adopted", "why"),
    [
        (_part(1.01), True, "at the noise where the training runs determine it (input delay 421)"),
        (_part(1.6), False, "above the noise there too"),
        (_part(1.01, significant=False), False, "the rule does not hold on the part"),
        (None, False, "no part to judge (no held-out runs, or under the minimum)"),
    ],
)
def test_short_of_the_share_the_determined_part_decides(monkeypatch, part, adopted, why):
    """Stop 75: 88 % of the excess removed (input delay 421, 5.11 -> 2.00),
    under the 90 % share; the part before the first untrained rest decides."""
    monkeypatch.setattr(search, "determined_part", lambda *args: part)
    rounds = _rounds(train=1.02, before=5.11, after=2.0, name="input_delay")
    got = search._explains_training(rounds, data=object())
    assert (got is not None) == adopted, why
    if adopted:
        assert got[1].determined is part
        assert got[1].excess_removed < search.EXPLAINED_SHARE
        assert got[1].to_json()["held_out_determined"]["rmse_over_noise_floor"] == 1.01


def test_the_part_is_not_asked_where_the_share_decides(monkeypatch):
    def never(*args):
        raise AssertionError("the share decided: no part needed")

    monkeypatch.setattr(search, "determined_part", never)
    kept = search._explains_training(_rounds(1.02, 233.0, 3.6), data=object())
    assert kept[1].determined is None
    assert search._explains_training(_rounds(1.6, 5.11, 2.0), data=object()) is None
    assert search._explains_training(_rounds(1.0, 10.0, 1.2), data=object()) is None


def test_without_data_the_share_alone_decides():
    assert _record(_rounds(train=1.02, before=5.11, after=2.0)) is None


def test_the_verdict_states_the_part():
    got = _diagnosis(TrainingExplained(1.02, 0.8808, _part(1.01)))._verdict_json()
    assert "reads 1.01 x the noise floor (without it 5.17) over the 2484 of 5950" in got["verdict"]
    assert got["training_explained"]["held_out_determined"] == {
        "samples": 2484,
        "of_samples": 5950,
        "rmse_over_noise_floor": 1.01,
        "without_effects_over_noise_floor": 5.17,
        "improvement_z": 119.0,
    }


# Stop 78 (`search._tentative_fit`, `result.TentativeFit`; docs/diagnosis.md
# "Stop 78"): a `none` that sets effects aside says how far they got.
# Reference torque offset seed 429: the torque offset took the held-out error
# from 131 to 7.7 noise floors and a resonance after it to 4.1; both were set
# aside (not at the noise), and the verdict read "lacks an effect the library
# does not have", the report "no missing effect found".


def test_the_tentative_record_is_the_last_accepted_models_errors_over_the_floor():
    rounds = _rounds(9.0, 131.0, 7.7, "torque_offset") + _rounds(3.0, 7.7, 4.1, "resonance")
    got = search._tentative_fit(rounds)
    assert got.effects == ("torque_offset", "resonance")
    assert got.training_over_noise == pytest.approx(3.0)
    assert got.held_out_over_noise == pytest.approx(4.1)
    assert got.without_over_noise == pytest.approx(131.0)
    # The same rounds are set aside: the record is of effects that are.
    _, accepted, tentative = search._set_aside_tentative(rounds)
    assert accepted == [] and tentative == got.effects


def test_no_accepted_round_gives_no_tentative_record():
    rnd = replace(_rounds(9.0, 131.0, 7.7)[0], selected="none")
    assert search._tentative_fit([rnd]) is None


@pytest.mark.parametrize(
    ("train", "advice"),
    [
        (3.0, "the fit stops short on the training runs"),
        (1.1, "the training runs leave the model undetermined"),
    ],
)
def test_the_verdict_names_the_tentative_effects_and_how_far_they_got(train, advice):
    record = TentativeFit(("torque_offset", "resonance"), train, 4.1, 131.0)
    got = _diagnosis(None, record.effects, record)._verdict_json()
    assert got["converged"] is False
    v = got["verdict"]
    assert v.startswith("held-out RMS error 3.60 x the noise floor: NOT CONVERGED")
    assert "no effect adopted: with the tentative torque_offset, resonance" in v
    assert f"training runs at {train:.2f} and the held-out run at 4.10" in v
    assert "(without an effect 131.00)" in v
    assert advice in v
    # Not the sentence for a library without the effect.
    assert "does not have" not in v
    assert got["tentative_fit"] == {
        "effects": ["torque_offset", "resonance"],
        "training_over_noise_floor": train,
        "held_out_over_noise_floor": 4.1,
        "without_effects_over_noise_floor": 131.0,
    }


def test_the_tentative_advice_turns_at_the_converged_ratio():
    def advice(train):
        return TentativeFit(("x",), train, 4.0, 9.0).sentence()

    assert "stops short" not in advice(CONVERGED_RATIO)
    assert "stops short" in advice(np.nextafter(CONVERGED_RATIO, 2.0))


def test_without_tentative_effects_the_none_reads_as_before():
    diag = replace(_diagnosis(None), rounds=())
    assert _diagnosis(None)._verdict_json()["tentative_fit"] is None
    assert _none_found(diag) == "no missing effect found"
    assert _none_note(diag) == " (no missing effect found)"


def test_a_none_with_tentative_effects_is_not_called_no_missing_effect():
    record = TentativeFit(("torque_offset",), 9.0, 7.7, 131.0)
    diag = replace(_diagnosis(None, record.effects, record), rounds=())
    assert _none_found(diag) == "no effect adopted (tentative: torque_offset)"
    assert _none_note(diag) == " (no effect adopted; tentative: torque_offset)"
