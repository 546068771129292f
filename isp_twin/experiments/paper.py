"""The paper's measured and simulated results, as data (Cong et al., Sect. 3.2 and 4).

Isolation J (Eq. 10) in percent. Each table keeps the paper's source note;
the averages are recomputed from the runs in the tests, not trusted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "TABLE4_FREQS_HZ",
    "TABLE4_AMPLITUDES_DEG_S",
    "TABLE4_ACTUAL",
    "TABLE4_MODEL",
    "CampaignTable",
    "TABLE5",
    "TABLE6",
    "relative_reduction",
    "PaperCell",
    "PAPER_CELLS",
]

#: Table 4 columns: frequencies [Hz] and rate amplitudes [deg/s] (pi/2, pi, 2*pi).
TABLE4_FREQS_HZ: tuple[float, ...] = (1.0 / 6.0, 0.5)
TABLE4_AMPLITUDES_DEG_S: tuple[float, ...] = (math.pi / 2, math.pi, 2 * math.pi)

#: Table 4, row J_actual [%]: the real ISP, PI control; keyed (freq_hz, amplitude_deg_s).
TABLE4_ACTUAL: dict[tuple[float, float], float] = dict(
    zip(
        [(f, a) for f in TABLE4_FREQS_HZ for a in TABLE4_AMPLITUDES_DEG_S],
        (29.89, 22.56, 14.28, 28.24, 21.37, 11.78),
    )
)
#: Table 4, row J_model [%]: the paper's own simulation (Eq. 6 + PI).
TABLE4_MODEL: dict[tuple[float, float], float] = dict(
    zip(
        [(f, a) for f in TABLE4_FREQS_HZ for a in TABLE4_AMPLITUDES_DEG_S],
        (29.93, 24.34, 12.85, 29.91, 22.48, 10.44),
    )
)


@dataclass(frozen=True)
class CampaignTable:
    """Ten runs of PI and of PI+NFC (Tables 5 and 6) and the figures quoted with them.

    Attributes:
        source: where in the paper.
        pi, pi_nfc: J of each run [%], as printed (row-major).
        pi_average, pi_nfc_average: the printed averages [%].
        pi_variance, pi_nfc_variance: the printed "square error" (sample
            variance of J as a fraction, ddof = 1).
        relative_reduction_percent: the printed improvement of the average.
        pi_max_abs_error_deg_s, pi_nfc_max_abs_error_deg_s: maximum |error| [deg/s].
        pi_rms_error_deg_s, pi_nfc_rms_error_deg_s: "mean square value of error" [deg/s].
    """

    source: str
    pi: tuple[float, ...]
    pi_nfc: tuple[float, ...]
    pi_average: float
    pi_nfc_average: float
    pi_variance: float
    pi_nfc_variance: float
    relative_reduction_percent: float
    pi_max_abs_error_deg_s: float
    pi_nfc_max_abs_error_deg_s: float
    pi_rms_error_deg_s: float
    pi_nfc_rms_error_deg_s: float


TABLE5 = CampaignTable(
    source="Table 5 and Sect. 4.1 (tracking, 0.5 Hz, pi deg/s, inner azimuth)",
    pi=(18.54, 20.84, 19.01, 20.46, 18.68, 18.74, 21.11, 19.12, 18.27, 19.93),
    pi_nfc=(12.40, 12.72, 12.28, 12.21, 13.04, 11.65, 11.43, 12.49, 11.94, 12.75),
    pi_average=19.47,
    pi_nfc_average=12.29,
    pi_variance=1.0616e-4,
    pi_nfc_variance=2.5437e-5,
    relative_reduction_percent=36.88,
    pi_max_abs_error_deg_s=0.5796,
    pi_nfc_max_abs_error_deg_s=0.3657,
    pi_rms_error_deg_s=0.2422,
    pi_nfc_rms_error_deg_s=0.1077,
)

TABLE6 = CampaignTable(
    source="Table 6 and Sect. 4.2 (isolation, 1/6 Hz, pi deg/s, 3 turntable axes)",
    pi=(22.90, 21.28, 23.48, 21.29, 22.23, 22.32, 24.46, 25.01, 24.07, 23.02),
    pi_nfc=(12.87, 14.15, 13.35, 13.56, 13.39, 14.18, 13.89, 12.14, 12.81, 13.63),
    pi_average=23.01,
    pi_nfc_average=13.40,
    # Printed 4.1229E-5; the ten printed runs give 4.1207E-5 (a rounding slip).
    pi_variance=1.6105e-4,
    pi_nfc_variance=4.1229e-5,
    relative_reduction_percent=41.76,
    pi_max_abs_error_deg_s=0.7559,
    pi_nfc_max_abs_error_deg_s=0.4192,
    pi_rms_error_deg_s=0.2059,
    pi_nfc_rms_error_deg_s=0.0811,
)


def relative_reduction(before: float, after: float) -> float:
    """Improvement of the average in percent of the original, as the paper computes it."""
    return 100.0 * (before - after) / before


@dataclass(frozen=True)
class PaperCell:
    """One figure of Tables 4-6 that the twin reproduces with one scenario and controller.

    Attributes:
        name: the cell's name, used by rig files and `isp-twin calibrate`.
        scenario: the shipped scenario that runs it.
        nfc: True for the PI+NFC controller, False for PI.
        paper_percent: the paper's J [%] (Table 4: J_actual; Tables 5, 6: the average).
        source: where in the paper.
    """

    name: str
    scenario: str
    nfc: bool
    paper_percent: float
    source: str


def _table4_cells() -> list[PaperCell]:
    cells = []
    for (f, a), value in TABLE4_ACTUAL.items():
        ftag = "1_6Hz" if f < 0.3 else "0_5Hz"
        atag = {math.pi / 2: "half_pi", math.pi: "pi", 2 * math.pi: "2pi"}[a]
        name = f"table4_{ftag}_{atag}"
        fname = "1/6" if f < 0.3 else "0.5"
        cells.append(PaperCell(name, name, False, value, f"Table 4, {fname} Hz, {a:.3f} deg/s, PI"))
    return cells


#: Every paper cell by name: the six Table 4 cells (PI), then Tables 5 and 6 (PI, PI+NFC).
PAPER_CELLS: dict[str, PaperCell] = {
    c.name: c
    for c in _table4_cells()
    + [
        PaperCell("table5_pi", "tracking_0_5Hz", False, TABLE5.pi_average, "Table 5, PI"),
        PaperCell(
            "table5_pi_nfc", "tracking_0_5Hz", True, TABLE5.pi_nfc_average, "Table 5, PI+NFC"
        ),
        PaperCell("table6_pi", "turbulence_1_6Hz", False, TABLE6.pi_average, "Table 6, PI"),
        PaperCell(
            "table6_pi_nfc", "turbulence_1_6Hz", True, TABLE6.pi_nfc_average, "Table 6, PI+NFC"
        ),
    ]
}
