"""A leading torque effect's global step held at its joint equation-error
estimate chooses the read-out timing again (`rounds._torque_global_stage`,
`rounds._refit_globally`'s ``free_read_out``; docs/diagnosis.md "Stop 56").

The data's read-out is the one that fits best at the file's parameters,
which lack the effect. On reference LuGre seed 357 the file reads the gyro
at the sample where the truth averages it, and the global step held there
ended at 3.0 noise floors on training; with the read-out chosen again it
ended at 1.15 and diagnose answered LuGre instead of `none`. These tests pin
the wiring; the benchmark figures are in the docs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from round_state_double import RoundStateDouble, fit_double

from isp_twin.diagnosis import rounds
from isp_twin.identification.read_out import Timing

#: The joint estimate's parameter in `_stage`'s double.
JOINT = 2.0


def _scale_key(held: dict) -> str:
    """A hold's key in `_stage`: "joint" at the joint estimate, else
    "x<factor>" for the joint estimate scaled (`rounds.SCALED_HELD`)."""
    factor = held["accel_rad_s2"] / JOINT
    return "joint" if factor == 1.0 else f"x{factor:g}"


def _scaled_calls(top: str) -> list[tuple[str, bool]]:
    """The scaled holds `_torque_global_stage` makes for `top`, read out again."""
    factors = rounds.SCALED_HELD[top][1] if top in rounds.SCALED_HELD else ()
    return [(f"x{f:g}", True) for f in factors]


def _stage(monkeypatch, top: str, with_joint: bool, sse: dict, peaks=()):
    """`_torque_global_stage` on a leader 10 noise floors out, its refits
    recorded as (held parameters, free_read_out) and given the training sse
    of `sse` by hold ("joint", "own", or a peak's "key"); the effect's other
    basins (`_other_basins`) are `peaks`; the cycles and the offset left out."""
    calls = []

    def refit(data, fit, held=None, free_read_out=False):
        key = "own" if held is None else held["key"] if "key" in held else _scale_key(held)
        calls.append((key, free_read_out))
        return fit_double(fit.name, {"hold": key}, sse.get(key, 1000.0))

    monkeypatch.setattr(rounds, "_refit_globally", refit)
    monkeypatch.setattr(rounds, "_other_basins", lambda data, st, name: [dict(g) for g in peaks])
    monkeypatch.setattr(rounds, "_global_cycles", lambda data, g: g)
    monkeypatch.setattr(rounds, "_offset_alternative", lambda data, st, v, top: v)
    st = RoundStateDouble({top: fit_double(top, {"own": 1.0}, 100.0)}, floor=1.0)
    st.held_of[top] = [np.full(50, 10.0)]
    starts = {top: SimpleNamespace(effect=SimpleNamespace(params={"accel_rad_s2": JOINT}))}
    out = rounds._torque_global_stage(None, st, [], starts if with_joint else {}, top)
    return calls, st, out


@pytest.mark.parametrize("top", ["lugre", "cogging"])
def test_the_joint_hold_chooses_the_read_out_again_the_own_fit_keeps_the_datas(monkeypatch, top):
    calls, st, out = _stage(monkeypatch, top, True, {"joint": 5.0, "own": 7.0})
    # LuGre is held at its own fit too (`OWN_FIT_TOO`), at the data's read-out.
    # LuGre's joint estimate is also held scaled (`SCALED_HELD`), read out again.
    want = [("joint", True)] + _scaled_calls(top)
    want += [("own", False)] if top in rounds.OWN_FIT_TOO else []
    assert calls == want
    assert st.updated[top].params == {"hold": "joint"}
    assert out == [top]


def test_without_a_joint_estimate_the_own_fit_keeps_the_datas_read_out(monkeypatch):
    calls, st, _ = _stage(monkeypatch, "unbalance", False, {"joint": 5.0, "own": 7.0})
    assert calls == [("own", False)]
    assert st.updated["unbalance"].params == {"hold": "own"}


def test_the_better_training_fit_is_kept_whichever_read_out_it_searched(monkeypatch):
    _, st, _ = _stage(monkeypatch, "lugre", True, {"joint": 9.0, "own": 7.0})
    assert st.updated["lugre"].params == {"hold": "own"}
    _, st, out = _stage(monkeypatch, "lugre", True, {"joint": 200.0, "own": 300.0})
    assert st.updated == {} and out == []


@pytest.mark.parametrize(("free", "want"), [(True, None), (False, Timing(0.75, True))])
def test_refit_globally_passes_no_timing_only_when_the_read_out_is_free(monkeypatch, free, want):
    """The global step gets timing None (identify chooses it, as `identify_held`
    documents) only with ``free_read_out``; the polish is on the data's stack."""
    seen = {}

    def identify_held(data, effects, timing, **options):
        seen["timing"] = timing
        seen["effects"] = [(e.name, dict(e.params)) for e in effects]
        return SimpleNamespace(vector=np.arange(20.0))

    def fit_candidates(train, x, names, fixed, starts, max_iter):
        seen["polish"] = (train, list(names), starts)
        return {names[0]: fit_double(names[0], starts[names[0]], 1.0)}

    monkeypatch.setattr(rounds, "identify_held", identify_held)
    monkeypatch.setattr(rounds, "fit_candidates", fit_candidates)
    data = SimpleNamespace(timing=Timing(0.75, True), train="the data's stack", max_iter=8)
    fit = SimpleNamespace(name="lugre", params={"accel_rad_s2": 1.0}, fixed=())
    held = {"accel_rad_s2": 3.0, "presliding_rad": 1e-3}
    rounds._refit_globally(data, fit, held, free_read_out=free)
    assert seen["timing"] == want
    assert seen["effects"] == [("lugre", held)]
    assert seen["polish"] == ("the data's stack", ["lugre"], {"lugre": held})


# Stop 61 (`rounds.GUESSES_HELD`; docs/diagnosis.md "Stop 61"): a leading
# cogging's global step is also held at each periodogram peak away from its
# local refit's period; the lowest training cost is kept.
def test_a_leading_cogging_is_also_held_at_its_other_periodogram_peaks(monkeypatch):
    peaks = [{"key": "peak1"}, {"key": "peak2"}]
    sse = {"own": 90.0, "peak1": 3.0, "peak2": 50.0}
    calls, st, _ = _stage(monkeypatch, "cogging", False, sse, peaks)
    assert calls == [("own", False), ("peak1", False), ("peak2", False)]
    assert st.updated["cogging"].params == {"hold": "peak1"}
    # The other torque effects are not held at their guesses.
    calls, _, _ = _stage(monkeypatch, "unbalance", False, sse, peaks)
    assert calls == [("own", False)]


def test_a_peak_within_one_percent_of_the_refits_period_is_not_held_again(monkeypatch):
    got = [{"period_rad": p} for p in (0.0388, 0.02165, 0.0341, 0.0218)]
    monkeypatch.setattr(rounds, "guesses_on", lambda train, base, name: got)
    st = RoundStateDouble({"cogging": fit_double("cogging", {"period_rad": 0.0216})})
    others = rounds._other_basins(SimpleNamespace(train=None), st, "cogging")
    assert [g["period_rad"] for g in others] == [0.0388, 0.0341]


# Stop 76 (`rounds.SCALED_HELD`; docs/diagnosis.md "Stop 76"): a leading
# LuGre's global step is also held at its joint estimate's bristle force
# scaled by each factor; the lowest training cost is kept.
def test_a_leading_lugre_keeps_the_scaled_hold_that_fits_the_training_runs_best(monkeypatch):
    assert "lugre" in rounds.SCALED_HELD
    best = _scaled_calls("lugre")[-1][0]
    calls, st, _ = _stage(monkeypatch, "lugre", True, {"joint": 9.0, "own": 7.0, best: 2.0})
    assert st.updated["lugre"].params == {"hold": best}
    # A scaled hold that fits worse than the joint estimate's is not kept.
    _, st, _ = _stage(monkeypatch, "lugre", True, {"joint": 5.0, "own": 7.0, best: 6.0})
    assert st.updated["lugre"].params == {"hold": "joint"}
    # Effects outside `SCALED_HELD` are held at the joint estimate only.
    calls, _, _ = _stage(monkeypatch, "unbalance", True, {"joint": 5.0})
    assert calls == [("joint", True)]


def test_the_scaled_holds_are_skipped_where_the_joint_hold_is_at_the_noise(monkeypatch):
    # Stop 78 (`rounds.SCALED_SKIP_RATIO`): the double's floor is 1 and its
    # rmse sqrt(sse), so the joint hold's sse decides on either side.
    at = rounds.SCALED_SKIP_RATIO**2
    calls, st, _ = _stage(monkeypatch, "lugre", True, {"joint": at * 0.999, "own": 7.0})
    assert calls == [("joint", True), ("own", False)]
    assert st.updated["lugre"].params == {"hold": "joint"}
    calls, _, _ = _stage(monkeypatch, "lugre", True, {"joint": at * 1.001, "own": 7.0})
    assert calls == [("joint", True)] + _scaled_calls("lugre") + [("own", False)]


def test_the_scaled_holds_stay_within_the_parameters_bounds():
    key, factors = rounds.SCALED_HELD["lugre"]
    lo, hi = rounds.effect_class("lugre").bounds[key]
    joint = {key: hi / min(factors) * 0.999, "presliding_rad": 2e-3}
    holds = rounds._scaled_joint("lugre", joint)
    assert len(holds) == len(factors)
    assert all(lo <= h[key] <= hi for h in holds)
    assert max(h[key] for h in holds) == hi
    # The other parameters stay at the joint estimate.
    assert all(h["presliding_rad"] == joint["presliding_rad"] for h in holds)
    assert rounds._scaled_joint("cogging", joint) == []
