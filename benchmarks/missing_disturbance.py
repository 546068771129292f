"""Issue 10, item 4: which disturbance does the twin lack? One thing changed at a time.

For each candidate the three 1/6 Hz cells of Table 4 (PI, the shipped
`table4_1_6Hz_*` scenarios; the pi cell is also Table 6's PI run) are run on
a few seeds and printed with: J per cell, the peak and RMS of omega_1 in the
pi cell (paper, Table 6 PI: 0.756 / 0.206 deg/s), the RMS of the gyro reading
there (what a rig records), and the exponent p of peak |omega_1| ~ A^p over
the three amplitudes (paper: 0.47, from J x A = 0.47, 0.71, 0.90 deg/s; the
shipped twin: about 0). With ``--nfc`` the pi cell is also run with PI+NFC
(Table 6's reduction, paper 41.8 %).

Candidates (issue 10): dynamic cross-coupling through the gimbals' inertia
products, base-motion-induced unbalance (centre-of-mass offsets, the ISP
above the turntable's centre), cable torque, gyro noise and bandwidth, and
follower lag (soft followers, heavier outer-gimbal friction). MJCF variants
are written to a temporary folder and loaded in place of the shipped model.

    nice python benchmarks/missing_disturbance.py [--seeds 2] [--jobs 2] [--nfc] [--only LABEL ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.experiments.paper import TABLE4_ACTUAL, TABLE6, relative_reduction
from isp_twin.experiments.scenario import load_scenario, parse_scenario, scenario_to_raw
from isp_twin.model.parameters import EffectSpec, ParameterSet, load_parameters
from isp_twin.resources import model_path
from isp_twin.units import DEG

CELLS = {
    math.pi / 2: "table4_1_6Hz_half_pi",
    math.pi: "table4_1_6Hz_pi",
    2 * math.pi: "table4_1_6Hz_2pi",
}
GIMBAL_BODIES = ("outer_az", "outer_el", "inner_el", "inner_az")


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One thing changed: scenario keys, a parameter edit, or an MJCF edit."""

    label: str
    scenario: tuple[tuple[str, object], ...] = ()
    params: str = ""  # name of a parameter edit in `edit_params`
    mjcf: str = ""  # name of an MJCF edit in `edit_mjcf`


def _quat_xy(deg_x: float, deg_y: float) -> str:
    """Quaternion (w x y z) of a rotation by deg_x about x, then deg_y about y."""
    hx, hy = math.radians(deg_x) / 2, math.radians(deg_y) / 2
    qx = np.array([math.cos(hx), math.sin(hx), 0, 0])
    qy = np.array([math.cos(hy), 0, math.sin(hy), 0])
    w1, x1, y1, z1 = qy
    w2, x2, y2, z2 = qx
    q = (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )
    return " ".join(f"{v:.9f}" for v in q)


def edit_mjcf(text: str, kind: str) -> str:
    """The shipped MJCF with one physical change (see the candidates' labels)."""
    if kind.startswith("tilt"):
        # principal axes of every gimbal tilted off its joint frame: inertia
        # products of (I1 - I2) sin(2 theta) / 2 (a payload's optics, a yoke's
        # motor on one side); MuJoCo then couples the carrier's angular
        # acceleration into each gimbal axis
        deg = float(kind[4:])
        for body in GIMBAL_BODIES:
            text = re.sub(
                rf'(<body name="{body}"[^>]*>\s*<inertial pos="0 0 0")',
                rf'\1 quat="{_quat_xy(deg, deg)}"',
                text,
            )
        return text
    if kind.startswith("offset"):
        # centre of mass of every gimbal off its axes by `mm` in x, y and z:
        # gravity torque as the carrier tilts, d'Alembert torque as it accelerates
        mm = float(kind[6:]) / 1000.0
        for body in GIMBAL_BODIES:
            text = re.sub(
                rf'(<body name="{body}"[^>]*>\s*<inertial) pos="0 0 0"',
                rf'\1 pos="{mm} {mm} {mm}"',
                text,
            )
        return text
    if kind.startswith("raised"):
        # the ISP mounted `cm` above the turntable's centre of rotation, plus
        # 2 mm offsets: the carrier's rotation then also accelerates the gimbal centre
        cm = float(kind[6:]) / 100.0
        text = edit_mjcf(text, "offset2")
        return text.replace(
            '<body name="outer_az" pos="0 0 0">', f'<body name="outer_az" pos="0 0 {cm}">'
        )
    raise ValueError(kind)


def edit_params(params: ParameterSet, kind: str) -> ParameterSet:
    """The Table 2 set with one effect or friction change."""
    if not kind:
        return params
    if kind.startswith("cable"):
        # a cable bundle across the inner azimuth bearing: spring of
        # stiffness k [N m/rad] / J, written as rate-form acceleration
        k = float(kind[5:])
        spec = EffectSpec("cable_spring", {"stiffness_1_s2": k, "offset_rad_s2": 0.0})
        ax = params.axis("inner_az")
        return params.with_axis("inner_az", dataclasses.replace(ax, effects=(spec,)))
    if kind.startswith("outerfric"):
        # the outer gimbals' friction (an assumption of the parameter file) scaled
        f = float(kind[9:])
        for name in ("outer_az", "outer_el"):
            ax = params.axis(name)
            regs = tuple(dataclasses.replace(r, Ts=r.Ts * f, Tc=r.Tc * f) for r in ax.regimes)
            params = params.with_axis(name, dataclasses.replace(ax, regimes=regs))
        return params
    if kind.startswith("outercog"):
        # torque ripple of the outer torque motors (cogging), period 2 deg: the
        # outer gimbals turn through the whole carrier swing, so its frequency
        # and the ripple it passes to the inner bearings grow with the amplitude
        amp, period_deg = (float(x) for x in kind[8:].split("_"))
        spec = EffectSpec(
            "cogging",
            {"amplitude_rad_s2": amp, "period_rad": math.radians(period_deg), "phase_rad": 0.0},
        )
        for name in ("outer_az", "outer_el"):
            params = params.with_axis(name, dataclasses.replace(params.axis(name), effects=(spec,)))
        return params
    raise ValueError(kind)


CANDIDATES = [
    Candidate("shipped"),
    Candidate("inertia products: principal axes tilted 10 deg", mjcf="tilt10"),
    Candidate("inertia products: principal axes tilted 30 deg", mjcf="tilt30"),
    Candidate("unbalance: CoM offset 2 mm (x, y, z)", mjcf="offset2"),
    Candidate("unbalance: CoM offset 10 mm", mjcf="offset10"),
    Candidate("unbalance 2 mm + ISP 30 cm above table centre", mjcf="raised30"),
    Candidate("cable spring inner_az 200 1/s^2", params="cable200"),
    Candidate("cable spring inner_az 2000 1/s^2", params="cable2000"),
    Candidate("gyro noise 0.05 deg/s", scenario=(("gyro.noise_deg_s", 0.05),)),
    Candidate("gyro noise 0.1 deg/s", scenario=(("gyro.noise_deg_s", 0.1),)),
    Candidate("gyro bandwidth 50 Hz", scenario=(("gyro.bandwidth_hz", 50.0),)),
    Candidate(
        "follower soft: kp 500, ki 0, kd 20",
        scenario=(("follower.kp_digit_per_deg", 500.0), ("follower.ki_digit_per_deg", 0.0)),
    ),
    Candidate(
        "follower kd 5 (less rate damping)", scenario=(("follower.kd_digit_per_deg_s", 5.0),)
    ),
    Candidate("outer-gimbal friction x2", params="outerfric2"),
    Candidate("outer-gimbal friction x4", params="outerfric4"),
    Candidate("outer-motor cogging 5 rad/s^2, 2 deg", params="outercog5_2"),
    Candidate("outer-motor cogging 20 rad/s^2, 2 deg", params="outercog20_2"),
]
#: The ripple's amplitude x period, scanned with ``--scan-ripple``.
RIPPLE_SCAN = [
    Candidate(f"outer-motor cogging {a:g} rad/s^2, {p:g} deg", params=f"outercog{a:g}_{p:g}")
    for a in (2.0, 5.0, 10.0)
    for p in (0.5, 1.0, 2.0, 5.0)
]
#: A follower without integral or damping (docs/calibration.md: J x A grows as
#: in the paper) alone and with outer ripple, with ``--combine``.
_LOOSE = (
    ("follower.kp_digit_per_deg", 1000.0),
    ("follower.ki_digit_per_deg", 0.0),
    ("follower.kd_digit_per_deg_s", 0.0),
)
COMBINED = [Candidate("follower 1000, 0, 0", scenario=_LOOSE)] + [
    Candidate(f"follower 1000, 0, 0 + cogging {a:g}, {p:g} deg", _LOOSE, f"outercog{a:g}_{p:g}")
    for a in (2.0, 5.0)
    for p in (1.0, 2.0)
]


def _set(raw: dict, path: str, value) -> None:
    node = raw
    *head, last = path.split(".")
    for part in head:
        node = node.setdefault(part, {})
    node[last] = value


def _job(job):
    cand, name, nfc, seed, xml = job
    import isp_twin.model.twin as twin_module
    from isp_twin.experiments.closed_loop import ClosedLoop

    if xml is not None:
        twin_module.default_model_path = lambda: Path(xml)
    else:
        twin_module.default_model_path = model_path
    base = load_scenario(name).with_nfc(nfc)
    raw = scenario_to_raw(base)
    for path, value in cand.scenario:
        _set(raw, path, value)
    scenario = parse_scenario(raw, base.source)
    params = edit_params(load_parameters(scenario.parameters_path), cand.params)
    loop = ClosedLoop(scenario, params=params, seed=seed)
    loop.run()
    res = loop.result()
    m = res.metrics["inner_az"]
    keep = res.t >= scenario.skip_s
    gyro = res.signals["inner_az/gyro"][keep]
    return (
        m["isolation_percent"],
        m["max_abs_error_deg_s"],
        m["rms_error_deg_s"],
        float(np.sqrt(np.mean(gyro**2)) / DEG),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--nfc", action="store_true", help="also the pi cell with PI+NFC")
    ap.add_argument("--only", nargs="*", default=None, help="labels starting with these words")
    ap.add_argument("--scan-ripple", action="store_true", help="the outer ripple grid instead")
    ap.add_argument("--combine", action="store_true", help="loose follower (+ ripple) instead")
    args = ap.parse_args()
    cands = RIPPLE_SCAN if args.scan_ripple else COMBINED if args.combine else CANDIDATES
    if args.only:
        cands = [c for c in cands if any(c.label.startswith(w) for w in args.only)]
    tmp = Path(tempfile.mkdtemp(prefix="isp_md_"))
    shipped = model_path().read_text()
    xmls = {}
    for c in cands:
        if c.mjcf:
            p = tmp / f"{c.mjcf}.xml"
            p.write_text(edit_mjcf(shipped, c.mjcf))
            xmls[c.mjcf] = str(p)
    jobs = []
    for c in cands:
        for name in CELLS.values():
            for s in range(1, args.seeds + 1):
                jobs.append((c, name, False, s, xmls.get(c.mjcf)))
        if args.nfc:
            for s in range(1, args.seeds + 1):
                jobs.append((c, "table4_1_6Hz_pi", True, s, xmls.get(c.mjcf)))
    start = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        out = list(pool.map(_job, jobs))
    wall = time.perf_counter() - start
    per = len(CELLS) * args.seeds + (args.seeds if args.nfc else 0)
    amps = np.array(list(CELLS))
    head = (
        f"{'candidate':<48} {'J pi/2':>7} {'J pi':>6} {'J 2pi':>6} {'p':>6} "
        f"{'max(pi)':>8} {'rms(pi)':>8} {'gyro rms':>8}"
    )
    if args.nfc:
        head += f" {'J NFC':>6} {'red %':>6}"
    print(head)
    paper_peaks = np.array([TABLE4_ACTUAL[(1 / 6, a)] * a / 100 for a in amps])
    p_paper = np.polyfit(np.log(amps), np.log(paper_peaks), 1)[0]
    print(
        f"{'paper (Table 4 actual; Table 6 PI)':<48} "
        + " ".join(f"{TABLE4_ACTUAL[(1 / 6, a)]:6.2f}" for a in amps)
        + f" {p_paper:6.2f} {TABLE6.pi_max_abs_error_deg_s:8.3f} {TABLE6.pi_rms_error_deg_s:8.3f}"
        + f" {'':>8}"
        + (
            f" {TABLE6.pi_nfc_average:6.2f} "
            f"{relative_reduction(TABLE6.pi_average, TABLE6.pi_nfc_average):6.1f}"
            if args.nfc
            else ""
        )
    )
    for i, c in enumerate(cands):
        rows = out[i * per : (i + 1) * per]
        cells = np.array(rows[: len(CELLS) * args.seeds]).reshape(len(CELLS), args.seeds, 4)
        mean = cells.mean(axis=1)
        peaks = mean[:, 1]
        p = np.polyfit(np.log(amps), np.log(peaks), 1)[0]
        line = (
            f"{c.label:<48} "
            + " ".join(f"{j:6.2f}" for j in mean[:, 0])
            + f" {p:6.2f} {mean[1, 1]:8.3f} {mean[1, 2]:8.3f} {mean[1, 3]:8.3f}"
        )
        if args.nfc:
            jn = float(np.mean([r[0] for r in rows[len(CELLS) * args.seeds :]]))
            line += f" {jn:6.2f} {relative_reduction(mean[1, 0], jn):6.1f}"
        print(line, flush=True)
    print(f"\n{len(jobs)} runs in {wall:.0f} s ({args.jobs} workers, {args.seeds} seeds)")


if __name__ == "__main__":
    main()
