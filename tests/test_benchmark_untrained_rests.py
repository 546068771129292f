"""The reference benchmark counts the held-out bound apart on the axes whose
held-out run rests where the training runs never break away
(`benchmarks/identify_reference.py`, `coverage_lines`).

There the training runs do not measure the static level that decides the
breakaway (diagnose's ``held_out_breakaways_untrained``); the issue's
targets still count every axis.
"""

from __future__ import annotations

import json

from reference_benchmark import reference_benchmark

PREFIX = "cogging: held-out rests where the training runs never break away"


def _axis(seed: int, answer: str, after: float, untrained: list[str] | None) -> dict:
    rec = {"case": "cogging", "seed": seed, "diagnose_answer": answer}
    rec["diagnose_heldout_over_noise"] = after
    if untrained is not None:
        rec["held_out_rests_untrained"] = untrained
    return rec


def _rests_line(records: list[dict]) -> list[str]:
    lines = reference_benchmark().coverage_lines(records, "cogging")
    return [line for line in lines if line.startswith(PREFIX)]


def test_the_bound_is_counted_apart_on_axes_with_untrained_rests():
    records = [
        _axis(1, "right", 1.2, ["R+"]),
        _axis(2, "right", 2.4, ["L-", "R-"]),
        _axis(3, "right", 1.1, []),
        _axis(4, "right", 1.4, []),
        _axis(5, "none", 1.0, []),
        _axis(6, "other", 1.2, []),
    ]
    assert _rests_line(records) == [
        f"{PREFIX} on 2/6 axes; right effect and held-out <= 1.5x on 1/2 of those, "
        "2/4 of the others"
    ]


def test_records_without_the_field_are_left_out():
    records = [_axis(1, "right", 1.2, ["R+"]), _axis(2, "right", 1.1, None)]
    assert _rests_line(records) == [
        f"{PREFIX} on 1/1 axes; right effect and held-out <= 1.5x on 1/1 of those, 0/0 of the others"
    ]
    assert _rests_line([_axis(2, "right", 1.1, None)]) == []


def test_an_older_record_reads_the_regimes_from_its_diagnose_json(tmp_path):
    folder = tmp_path / "cogging" / "seed7"
    folder.mkdir(parents=True)
    untrained = [
        {"regime": "R-", "training_breakaways": 0, "held_out_rests": 3},
        {"regime": "L+", "training_breakaways": 0, "held_out_rests": 1},
    ]
    diag = {"tentative_effects": [], "equivalent_effects": []}
    diag["held_out_breakaways_untrained"] = untrained
    (folder / "diagnose.json").write_text(json.dumps(diag))
    rec = reference_benchmark()._with_tentative({"case": "cogging", "seed": 7}, tmp_path)
    assert rec["held_out_rests_untrained"] == ["R-", "L+"]
    kept = {"case": "cogging", "seed": 7, "held_out_rests_untrained": []}
    kept.update(diagnose_tentative=[], diagnose_equivalent=[])
    assert reference_benchmark()._with_tentative(kept, tmp_path)["held_out_rests_untrained"] == []


def _determined(seed: int, answer: str, after: float, before: float | None) -> dict:
    rec = _axis(seed, answer, after, ["L-"] if before is not None else [])
    rec["held_out_determined_over_noise"] = before
    return rec


def test_the_misses_within_the_bound_before_the_first_untrained_rest_are_counted():
    records = [
        _determined(1, "none", 88.0, 1.05),  # a miss the training runs cannot decide
        _determined(2, "right", 9.6, 2.0),  # a miss before the rest too
        _determined(3, "right", 1.2, 1.1),  # within the bound: not a miss
        _determined(4, "right", 4.0, None),  # no untrained rest
    ]
    lines = reference_benchmark().determined_lines(records, "cogging")
    assert lines == [
        "cogging: held-out above 1.5x with untrained rests on 2/3 axes; "
        "within 1.5x before the first of those rests on 1/2"
    ]
    assert reference_benchmark().determined_lines(records[3:], "cogging") == []


def test_the_record_keeps_the_worst_held_out_run_before_its_untrained_rest():
    parts = [{"rmse_over_noise_floor": 1.2}, {"rmse_over_noise_floor": 3.5}]
    lists = reference_benchmark()._diagnose_lists({"held_out_before_untrained_rest": parts})
    assert lists["held_out_determined_over_noise"] == 3.5
    assert reference_benchmark()._diagnose_lists({})["held_out_determined_over_noise"] is None
    nothing = [{"rmse_over_noise_floor": None}]  # a rest at the first samples
    lists = reference_benchmark()._diagnose_lists({"held_out_before_untrained_rest": nothing})
    assert lists["held_out_determined_over_noise"] == float("inf")
