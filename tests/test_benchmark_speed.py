"""The reference benchmark judges the issue's speed targets on commands run
alone (`benchmarks/identify_reference.py`, `speed_lines`).

Issue 8's times are for one command on 2 cores. Two axes run at once on those
2 cores share them: their times are printed, not counted for or against the
target.
"""

from __future__ import annotations

from reference_benchmark import reference_benchmark


def _speed_lines():
    return reference_benchmark().speed_lines


def _axis(identify_s: float, axes_at_once: int | None) -> dict:
    rec = {"identify_s": identify_s, "identify_cpu_s": identify_s, "diagnose_s": 30.0}
    rec["diagnose_cpu_s"] = 30.0
    if axes_at_once is not None:
        rec.update(axes_at_once=axes_at_once, cores=2)
    return rec


def _identify_line(records: list[dict]) -> str:
    return next(line for line in _speed_lines()(records) if line.startswith("identify"))


def test_a_slow_command_beside_another_axis_is_not_judged():
    line = _identify_line([_axis(8.0, 1), _axis(12.0, 1), _axis(35.0, 2)])
    assert "2/2 within 20 s (target: all) MET" in line


def test_a_slow_command_run_alone_misses_the_target():
    line = _identify_line([_axis(8.0, 1), _axis(21.0, 1), _axis(5.0, 2)])
    assert "1/2 within 20 s (target: all) NOT MET" in line


def test_records_without_the_count_are_not_judged():
    line = _identify_line([_axis(8.0, None), _axis(9.0, 2)])
    assert "not judged" in line and "MET;" not in line


def test_a_shared_run_over_two_minutes_is_counted_not_judged():
    shared = _axis(10.0, 2)
    shared["diagnose_s"] = 130.0
    lines = _speed_lines()([_axis(8.0, 1), shared])
    line = next(line for line in lines if line.startswith("runs over"))
    assert "0 of the axes run alone (target 0) MET; 1 of all 2" in line
