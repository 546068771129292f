"""The paper's Tables 4-6 as data, and the twin's regression against them.

Tolerances (the issue's targets): Table 4 0.5 Hz cells within +-3 points of
the paper's measured J; PI -> PI+NFC relative reduction within +-10 points of
the paper's (36.9 % tracking, 41.8 % isolation); J falls as the amplitude
grows. The calibration cell (1/6 Hz, pi deg/s) is checked at +-3 points.
Short runs and few seeds here; `benchmarks/paper_tables.py` runs ten seeds.
"""

import math

import pytest

from isp_twin.campaign import TABLE4_SCENARIOS, run_campaign
from isp_twin.closed_loop import run_scenario
from isp_twin.metrics import campaign_stats
from isp_twin.paper import TABLE4_ACTUAL, TABLE5, TABLE6, relative_reduction
from isp_twin.scenario import load_scenario


@pytest.mark.parametrize("table", [TABLE5, TABLE6], ids=["table5", "table6"])
def test_printed_averages_and_variances_follow_from_the_printed_runs(table):
    for runs, avg, var in (
        (table.pi, table.pi_average, table.pi_variance),
        (table.pi_nfc, table.pi_nfc_average, table.pi_nfc_variance),
    ):
        s = campaign_stats(runs)
        assert s.average == pytest.approx(avg, abs=0.006)
        # Table 6's PI+NFC variance is printed as 4.1229E-5 for 4.1207E-5
        assert s.variance == pytest.approx(var, rel=1e-3)
    reduction = relative_reduction(table.pi_average, table.pi_nfc_average)
    assert reduction == pytest.approx(table.relative_reduction_percent, abs=0.01)


def test_table5_best_worst_and_ranges_quoted_in_the_text():
    pi, nfc = campaign_stats(TABLE5.pi), campaign_stats(TABLE5.pi_nfc)
    assert (pi.best, pi.worst, nfc.best, nfc.worst) == (18.27, 21.11, 11.43, 13.04)
    assert pi.range == pytest.approx(2.84) and nfc.range == pytest.approx(1.61)


def twin_j(name: str, seed: int = 1) -> float:
    scenario = load_scenario(name).with_nfc(False)
    return run_scenario(scenario, seed=seed).metrics["inner_az"]["isolation_percent"]


@pytest.fixture(scope="module")
def table4_twin():
    return {cell: twin_j(name) for cell, name in TABLE4_SCENARIOS.items()}


@pytest.mark.parametrize("amp", [math.pi / 2, math.pi, 2 * math.pi], ids=["pi/2", "pi", "2pi"])
def test_table4_half_hertz_cells_within_3_points_of_the_measured_system(table4_twin, amp):
    cell = (0.5, amp)
    assert table4_twin[cell] == pytest.approx(TABLE4_ACTUAL[cell], abs=3.0)


def test_table4_calibration_cell_is_matched(table4_twin):
    cell = (1 / 6, math.pi)
    assert table4_twin[cell] == pytest.approx(TABLE4_ACTUAL[cell], abs=3.0)


@pytest.mark.parametrize("freq", [1 / 6, 0.5], ids=["1/6Hz", "0.5Hz"])
def test_smaller_amplitude_gives_worse_isolation(table4_twin, freq):
    j = [table4_twin[(freq, a)] for a in (math.pi / 2, math.pi, 2 * math.pi)]
    assert j[0] > j[1] > j[2]


@pytest.mark.parametrize("name, table", [("tracking_0_5Hz", TABLE5), ("turbulence_1_6Hz", TABLE6)])
def test_nfc_reduces_average_j_like_the_paper(name, table):
    result = run_campaign(load_scenario(name), n_runs=2, first_seed=1)
    paper = relative_reduction(table.pi_average, table.pi_nfc_average)
    assert result.relative_reduction_percent == pytest.approx(paper, abs=10.0)
    for variant in ("PI", "PI+NFC"):
        assert result.variants[variant].stats.best <= result.variants[variant].stats.worst
    # Tables 5 and 6 also print RMS errors: NFC lowers them (0.242 -> 0.108,
    # 0.206 -> 0.081 deg/s). A loop that trades a lower peak for an oscillation
    # (docs/calibration.md, "What else was tried") fails here.
    rms = {v: sum(r.rms_error_deg_s) / len(r.rms_error_deg_s) for v, r in result.variants.items()}
    assert rms["PI+NFC"] < rms["PI"]


def _campaign_like(table):
    from isp_twin.campaign import CampaignResult, VariantResult

    def variant(runs):
        return VariantResult(campaign_stats(runs), (0.5,) * len(runs), (0.1,) * len(runs))

    return CampaignResult(
        "x",
        "p.yaml",
        "inner_az",
        tuple(range(10)),
        {"PI": variant(table.pi), "PI+NFC": variant(table.pi_nfc)},
    )


def test_report_says_met_when_the_twin_equals_the_paper_and_not_met_otherwise():
    from isp_twin.campaign import Comparison, comparison_markdown
    from isp_twin.paper import TABLE4_ACTUAL

    same = {cell: campaign_stats([j, j]) for cell, j in TABLE4_ACTUAL.items()}
    text = comparison_markdown(Comparison(same, _campaign_like(TABLE5), _campaign_like(TABLE6), 2))
    assert "NOT met" not in text and text.count("within +-3 points: met") == 3
    assert "- Every target is met." in text
    off = dict(same)
    off[(0.5, math.pi)] = campaign_stats([TABLE4_ACTUAL[(0.5, math.pi)] + 3.5] * 2)
    text = comparison_markdown(Comparison(off, _campaign_like(TABLE5), _campaign_like(TABLE6), 2))
    assert "within +-3 points: **NOT met**" in text
    assert "validation target missed by +3.5 points" in text
