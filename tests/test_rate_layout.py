"""The rate-parameter vector's layout: named once, agreeing with RateParams and Table 2.

And a guard: the vector's arithmetic (``reshape(4, 5)``, ``% 5``, ``[:20]``,
``STATIC_INDICES = (2, 7, 12, 17)``, ...) is written only in
`isp_twin.model.rate_layout`; files on a commented allow-list are converted later,
and the list can only shrink.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from isp_twin.model.parameters import RATE_LAYOUT, RateParams
from isp_twin.model.rate_layout import CandidateLayout, RateLayout
from isp_twin.units import DEG
from isp_twin.vocabulary import REGIMES

ROOT = Path(__file__).resolve().parents[1]

# Table 2 of the paper (inner azimuth), per regime: a, b, Ke, Ts, Tc, alpha
# (the paper's units: b in (deg/s)/tu per sample, alpha in 1/(deg/s)).
TABLE2 = {
    "R+": (0.851, 0.491, 0.00863, 5.563, 3.176, 0.427),
    "R-": (0.889, 0.152, 0.0114, 7.117, 4.016, 0.263),
    "L+": (0.893, 0.557, 0.0119, 2.743, 1.950, 0.774),
    "L-": (0.896, 0.281, 0.0186, 4.254, 3.569, 0.166),
}


def _distinct_rate_params(shape: tuple[int, ...] = ()) -> RateParams:
    """Every entry a different number, so a misplaced one cannot pass."""
    n = len(RATE_LAYOUT.fields)
    values = np.arange(np.prod(shape, dtype=int) * 4 * n, dtype=float).reshape(*shape, n, 4)
    return RateParams(*(values[..., i, :] + 0.5 for i in range(n)))


def test_the_layout_is_the_vocabulary_regimes_times_rate_params_fields():
    assert RATE_LAYOUT.regimes == REGIMES
    assert RATE_LAYOUT.fields == ("pole", "gain", "static", "coulomb", "alpha")
    assert RATE_LAYOUT.size == len(REGIMES) * len(RATE_LAYOUT.fields)


def test_every_entry_of_to_vector_sits_at_its_named_index():
    rp = _distinct_rate_params()
    x = rp.to_vector()
    assert x.shape == (RATE_LAYOUT.size,)
    for r, regime in enumerate(REGIMES):
        for f in RATE_LAYOUT.fields:
            assert x[RATE_LAYOUT.index(regime, f)] == getattr(rp, f)[r]
            assert x[RATE_LAYOUT.index(r, f)] == getattr(rp, f)[r]
        block = x[RATE_LAYOUT.regime_slice(regime)]
        assert list(block) == [getattr(rp, f)[r] for f in RATE_LAYOUT.fields]
    np.testing.assert_array_equal(x[list(RATE_LAYOUT.static_indices)], rp.static)
    for f in RATE_LAYOUT.fields:
        np.testing.assert_array_equal(RATE_LAYOUT.column(x, f), getattr(rp, f))


def test_indices_cover_the_vector_once():
    every = [RATE_LAYOUT.index(r, f) for r in REGIMES for f in RATE_LAYOUT.fields]
    assert sorted(every) == list(range(RATE_LAYOUT.size))
    assert RATE_LAYOUT.labels() == [f"{r}.{f}" for r in REGIMES for f in RATE_LAYOUT.fields]
    assert RATE_LAYOUT.labels()[RATE_LAYOUT.index("L-", "static")] == "L-.static"


@pytest.mark.parametrize("batch", [(), (3,), (2, 3)])
def test_table_view_and_back_round_trip_for_batches(batch):
    rp = _distinct_rate_params(batch)
    x = rp.to_vector()
    assert x.shape == (*batch, RATE_LAYOUT.size)
    table = RATE_LAYOUT.as_table(x)
    assert table.shape == (*batch, len(REGIMES), len(RATE_LAYOUT.fields))
    assert np.shares_memory(table, x)
    for i, f in enumerate(RATE_LAYOUT.fields):
        np.testing.assert_array_equal(table[..., i], getattr(rp, f))
    np.testing.assert_array_equal(RATE_LAYOUT.from_table(table), x)
    back = RateParams.from_vector(x)
    for f in RATE_LAYOUT.fields:
        np.testing.assert_array_equal(getattr(back, f), getattr(rp, f))


def test_a_vector_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match="last axis must be 20"):
        RATE_LAYOUT.as_table(np.zeros(19))
    with pytest.raises(ValueError, match="last axes"):
        RATE_LAYOUT.from_table(np.zeros((5, 4)))
    with pytest.raises(ValueError, match="distinct"):
        RateLayout(("R+", "R+"), ("pole",))


def test_table2_fields_land_where_the_layout_names_them(paper_params):
    """Each regime's Table 2 numbers, converted by hand, sit at that regime's indices."""
    x = paper_params.axis("inner_az").rate_params().to_vector()
    for regime, (a, b, ke, ts, tc, alpha) in TABLE2.items():
        expected = {
            "pole": a,
            "gain": b * ke * DEG,
            "static": b * ts * DEG,
            "coulomb": b * tc * DEG,
            "alpha": alpha / DEG,
        }
        for f, v in expected.items():
            assert x[RATE_LAYOUT.index(regime, f)] == pytest.approx(v, rel=1e-12), (regime, f)
    # The breakaway levels the diagnosis scans first are Table 2's b*Ts.
    np.testing.assert_allclose(
        x[list(RATE_LAYOUT.static_indices)],
        [TABLE2[r][1] * TABLE2[r][3] * DEG for r in REGIMES],
        rtol=1e-12,
    )


def test_identifications_own_field_list_agrees_until_it_is_converted():
    from isp_twin.identification.fit import RATE_FIELDS

    assert RATE_FIELDS == RATE_LAYOUT.fields


def test_a_regime_mask_selects_exactly_those_regimes_entries():
    visited = np.array([True, False, False, True])
    mask = RATE_LAYOUT.regime_mask(visited)
    for r, regime in enumerate(REGIMES):
        assert mask[RATE_LAYOUT.regime_slice(regime)].tolist() == [visited[r]] * len(
            RATE_LAYOUT.fields
        )
    with pytest.raises(ValueError, match="regime mask"):
        RATE_LAYOUT.regime_mask([True, False])


def test_per_field_repeats_a_row_in_every_regime():
    x = RATE_LAYOUT.per_field({f: float(i) for i, f in enumerate(RATE_LAYOUT.fields)})
    for r in REGIMES:
        for i, f in enumerate(RATE_LAYOUT.fields):
            assert x[RATE_LAYOUT.index(r, f)] == i


def test_a_candidate_vector_splits_into_rate_and_named_effect_parameters():
    vec = CandidateLayout(RATE_LAYOUT, ("amplitude_rad_s2", "period_rad"))
    rate = _distinct_rate_params((3,)).to_vector()
    effect = np.array([[-1.0, -2.0], [-3.0, -4.0], [-5.0, -6.0]])
    x = np.concatenate([rate, effect], axis=1)
    assert vec.size == x.shape[1] == RATE_LAYOUT.size + 2
    got_rate, got_effect = vec.split(x)
    np.testing.assert_array_equal(got_rate, rate)
    np.testing.assert_array_equal(got_effect["amplitude_rad_s2"], effect[:, 0])
    np.testing.assert_array_equal(got_effect["period_rad"], effect[:, 1])
    assert x[0, vec.effect_index("period_rad")] == -2.0
    np.testing.assert_array_equal(x[:, vec.effect_slice], effect)
    baseline = CandidateLayout(RATE_LAYOUT)
    assert baseline.size == RATE_LAYOUT.size and baseline.effect_values(rate) == {}


# --------------------------------------------------------------------------
# Guard: the vector's arithmetic is written only by the layout module.

#: Files allowed to keep literal layout arithmetic, each with why. The list
#: only shrinks: an entry that no longer has any fails
#: `test_the_layout_literal_allow_list_only_shrinks`.
LAYOUT_LITERALS_ALLOWED: set[str] = set()
#: Not scanned: the independent reference simulator shares no code with the
#: model on purpose (docs/reference_simulator.md); this module defines the layout.
NOT_SCANNED = ("isp_twin/reference/", "isp_twin/model/rate_layout.py")

#: The layout's numbers written out: 4 regimes x 5 fields = 20 entries.
LAYOUT_LITERAL = re.compile(
    r"reshape\(.*\b4, ?5\)"  # reshape(4, 5), reshape(*s, 4, 5)
    r"|reshape\(-1, ?5\)"
    r"|[%/] ?5\b(?!\.)"  # regime or field from a flat index
    r"|(?<![\w.])5 ?\* ?\w+ ?\+|\w+ ?\* ?5 ?\+"  # regime * 5 + field
    r"|(?<!:):20\]|\[20:|\b20 ?\+ ?\w"  # the rate part of a candidate vector
    r"|np\.(full|zeros|ones|empty)\(\(?20,"
    r"|\([A-Za-z_]\w*, 20\)"  # (n, 20) arrays
    r"|np\.repeat\(\w+, ?5\)"  # a per-regime mask spread over the fields
    r"|\(2, 7, 12, 17\)|STATIC_INDICES ?="
)


def layout_literals(rel: str, source: str) -> list[str]:
    """``file:line: text`` of every layout literal in code (comments and docstrings skipped)."""
    found, in_doc = [], False
    for lineno, line in enumerate(source.splitlines(), 1):
        code = line.split("#", 1)[0]
        quotes = code.count('"""') + code.count("'''")
        if in_doc or quotes:
            in_doc = in_doc ^ (quotes % 2 == 1)
            continue
        if LAYOUT_LITERAL.search(code):
            found.append(f"{rel}:{lineno}: {line.strip()}")
    return found


def scanned_files() -> list[str]:
    rels = [
        p.relative_to(ROOT).as_posix()
        for folder in ("isp_twin", "benchmarks", "tests")
        for p in sorted((ROOT / folder).rglob("*.py"))
    ]
    return [r for r in rels if not r.startswith(NOT_SCANNED) and r != "tests/test_rate_layout.py"]


def test_the_rate_vector_layout_is_written_only_in_the_layout_module():
    found = []
    for rel in scanned_files():
        if rel not in LAYOUT_LITERALS_ALLOWED:
            found += layout_literals(rel, (ROOT / rel).read_text())
    assert not found, "use isp_twin.model.parameters.RATE_LAYOUT:\n" + "\n".join(found)


def test_the_layout_literal_allow_list_only_shrinks():
    stale = [r for r in LAYOUT_LITERALS_ALLOWED if not layout_literals(r, (ROOT / r).read_text())]
    assert not stale, "no layout literals left; strike from LAYOUT_LITERALS_ALLOWED: " + str(stale)


@pytest.mark.parametrize(
    "line",
    [
        "x = v.reshape(4, 5)",
        "t = np.asarray(x).reshape(*np.shape(x)[:-1], 4, 5)",
        "STATIC_INDICES = (2, 7, 12, 17)",
        "k = r * 5 + i",
        "k = 5 * regime + i",
        "regime = k // 5",
        "field = k % 5",
        "rate = x[:, :20]",
        "eff = x[:, 20 + j]",
        "ci = np.full(20, np.nan)",
        "xs = rng.standard_normal((n_sets, 20))",
        "free = np.repeat(visited, 5)",
    ],
)
def test_a_planted_layout_literal_is_caught(line):
    assert layout_literals("isp_twin/experiments/metrics.py", f"def f(x):\n    {line}\n")


@pytest.mark.parametrize(
    "source",
    [
        "angle_lsb = 2 * np.pi / 2**20\n",
        "t = run.t[::20]\n",
        "u = np.zeros(20)\n",
        "y = 2.0 * fn(2 * np.pi * 0.5 * t + 1.0)\n",
        "spans = ((10, 11), (11, 20))\n",
        "x = v.reshape(4, 6)\n",
        "# rate[:20] in a comment\n",
        'def f():\n    """Shape (P, 20), x[:20]."""\n',
        "y = t / 5.0\n",
        "win = 20\n",
    ],
)
def test_other_numbers_pass(source):
    assert layout_literals("isp_twin/experiments/metrics.py", source) == []
