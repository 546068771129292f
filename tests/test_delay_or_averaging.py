"""A sub-sample input delay found at the point gyro reading, judged against
the averaged reading without it (`search._delay_or_averaging`).

A gyro that averages over the sample lags its point value by half a sample.
Reference clean seed 455 (stop 79; the reference gyro averages, no delay):
`identify` kept the point reading (the slow training cosines cannot tell the
two), and `diagnose` answered a 0.25 ms `input_delay` at 1.21 noise floors
held out, where the model without an effect read at the average reaches
1.00. The decision is checked here with the round at the averaged reading
and the final model as stand-ins and the acceptance rule (`judge`) real;
the numbers are chosen so that each condition decides.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from isp_twin.commands.diagnose import _none_found
from isp_twin.diagnosis import search
from isp_twin.diagnosis.report import _none_note
from isp_twin.diagnosis.result import Diagnosis, RoundResult
from isp_twin.estimation.verdict import CONVERGED_RATIO
from isp_twin.identification.read_out import Timing

FLOOR = 5e-4  # rad/s
N = 6000
DT = 1e-3  # s
NOISE = np.random.default_rng(455).standard_normal(N) * FLOOR
#: A smooth model error of 0.8 noise floors RMS (sqrt(1 + 0.8**2) = 1.28 in all).
SMOOTH = 0.8 * FLOOR * np.sqrt(2.0) * np.sin(np.linspace(0.0, 40.0 * np.pi, N))


def _delay_diagnosis(delay_s: float, gyro_average: bool = False, second: str | None = None):
    """`diagnose`'s answer before the judgement: the delay adopted at 1.0
    noise floors held out (its BIC below the base's), read at the point
    (`gyro_average` False) or averaged; `second`: a second adopted effect."""
    spec = SimpleNamespace(name="input_delay", params={"delay_s": delay_s})
    fit = SimpleNamespace(
        name="input_delay", params={"delay_s": delay_s}, bic=-100.0, effects=lambda: (spec,)
    )
    rnd = RoundResult(
        baseline=SimpleNamespace(name="none", rate_vector=np.zeros(20), bic=0.0),
        fits={"input_delay": fit},
        verdicts=(),
        selected="input_delay",
        holdout_before=(NOISE + SMOOTH,),
        holdout_after=(NOISE,),
        noise_floor=FLOOR,
    )
    rounds = [rnd]
    if second is not None:
        other = SimpleNamespace(name=second, params={}, bic=-200.0)
        rounds.append(replace(rnd, fits={second: other}, selected=second))
    return Diagnosis(
        axis="inner_az",
        rounds=tuple(rounds),
        rmse_before=1.28 * FLOOR,
        rmse_after=FLOOR,
        noise_floor=FLOOR,
        params_out=None,
        analysis_before=None,
        analysis_after=None,
        timing=Timing(0.0, gyro_average),
    )


def _data(side_source: str = "measured"):
    return SimpleNamespace(side_source=side_source, train=SimpleNamespace(dt=np.full(2, DT)))


def _averaged(monkeypatch, selected: str = "none", held=(NOISE,), base_bic: float = -150.0):
    """The round at the averaged reading (`round_at_read_out`) as a stand-in:
    it selects `selected`, its model without an effect reads `held`; the
    final model is the round's answer. Returns the calls' record."""
    calls = []

    def at_read_out(there, starts, fixed):
        calls.append((there.timing, starts))
        return RoundResult(
            baseline=SimpleNamespace(name="none", bic=base_bic),
            fits={},
            verdicts=(),
            selected=selected,
            holdout_before=held,
            holdout_after=held,
            noise_floor=FLOOR,
        )

    def prepared_at(checked, options, timing):
        return SimpleNamespace(timing=timing, ax=SimpleNamespace(effects=()))

    def final(data, params, axis, rounds, before_held, kept=None):
        return replace(
            _delay_diagnosis(1e-4), rounds=tuple(rounds), timing=data.timing, rmse_after=FLOOR
        )

    monkeypatch.setattr(search, "round_at_read_out", at_read_out)
    monkeypatch.setattr(search, "_prepared_at", prepared_at)
    monkeypatch.setattr(search, "_final_diagnosis", final)
    return calls


def _judged(diag, data=None):
    return search._delay_or_averaging(diag, data or _data(), None, None, None, None)


def test_a_quarter_sample_delay_equal_to_the_averaged_reading_is_set_aside(monkeypatch):
    calls = _averaged(monkeypatch)
    got = _judged(_delay_diagnosis(0.25e-3))
    assert got.selected_effect == "none"
    assert got.delay_as_read_out == pytest.approx(0.25e-3)
    assert got.timing.gyro_average is True
    # judged once, at the averaged reading, the delay restarted from its value
    # and the model without an effect from round 1's base
    (timing, starts), *more = calls
    assert not more and timing.gyro_average is True
    assert starts["input_delay"][1].params == {"delay_s": 0.25e-3}
    j = got._verdict_json()
    assert j["delay_as_read_out_s"] == pytest.approx(0.25e-3)
    assert "gyro's averaging" in _none_found(got)
    assert "gyro's averaging" in _none_note(got)


def test_without_the_judgement_the_record_is_empty():
    diag = replace(_delay_diagnosis(0.25e-3), rounds=())
    assert diag._verdict_json()["delay_as_read_out_s"] is None
    assert _none_found(diag) == "no missing effect found"


@pytest.mark.parametrize(
    ("diag", "why"),
    [
        (_delay_diagnosis(DT), "a delay of a whole sample is more than the averaging"),
        (_delay_diagnosis(3.2e-3), "a delay of several samples"),
        (_delay_diagnosis(0.25e-3, gyro_average=True), "already read as the average"),
        (_delay_diagnosis(0.25e-3, second="sensor_bias"), "two effects adopted"),
    ],
)
def test_the_judgement_is_not_made(monkeypatch, diag, why):
    def never(*args):
        raise AssertionError(f"not judged: {why}")

    monkeypatch.setattr(search, "_prepared_at", never)
    assert _judged(diag) is diag, why


def test_not_on_a_fixed_or_raw_half_plane(monkeypatch):
    _averaged(monkeypatch)
    diag = _delay_diagnosis(0.25e-3)
    assert _judged(diag, _data("raw")) is diag
    assert _judged(diag, _data("right")) is diag


@pytest.mark.parametrize(
    ("selected", "held", "base_bic", "why"),
    [
        ("input_delay", (NOISE,), -150.0, "the delay is significant at the averaged reading too"),
        (
            "none",
            (NOISE + 2.0 * SMOOTH,),
            -150.0,
            "the averaged reading without it is not at the noise",
        ),
        (
            "none",
            (NOISE + SMOOTH,),
            0.0,
            "at the noise averaged (1.28), but the delay is significantly better held out",
        ),
    ],
)
def test_the_delay_stays_where_the_averaged_reading_does_not_do_as_well(
    monkeypatch, selected, held, base_bic, why
):
    ratio = float(np.sqrt(np.mean(np.concatenate(held) ** 2))) / FLOOR
    if "not at the noise" in why:
        assert ratio > CONVERGED_RATIO
    elif "significantly better" in why:
        assert ratio <= CONVERGED_RATIO
    _averaged(monkeypatch, selected, held, base_bic)
    diag = _delay_diagnosis(0.25e-3)
    assert _judged(diag) is diag, why
