"""What a sweep found: J per design point and per knob, read back from the store.

J is Eq. 10's isolation of the sweep's axis [%] (lower is better). A design
point is one setting of the knobs; its J is averaged over its seeds (and
parameter draws when ``draw`` is not a knob of the table). Runs are streamed
from the store, so memory grows with the design points, not with the runs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from isp_twin.experiments.sweep.design import Sweep
from isp_twin.experiments.sweep.store import ResultStore

__all__ = [
    "PointSummary",
    "KnobSummary",
    "SweepSummary",
    "summarize",
    "format_summary",
    "plot_knobs",
]


@dataclass(frozen=True)
class PointSummary:
    """One design point over its seeds.

    Attributes:
        knobs: knob -> value.
        runs: stored runs of the point.
        failed: of those, failed (diverged or rejected).
        j_mean, j_min, j_max: J over the point's successful runs [%] (None: none).
    """

    knobs: Mapping[str, Any]
    runs: int
    failed: int
    j_mean: float | None
    j_min: float | None
    j_max: float | None

    def as_dict(self) -> dict:
        return {
            "knobs": dict(self.knobs),
            "runs": self.runs,
            "failed": self.failed,
            "j_mean_percent": self.j_mean,
            "j_min_percent": self.j_min,
            "j_max_percent": self.j_max,
        }


@dataclass(frozen=True)
class KnobSummary:
    """Mean J per value of one knob, over every other knob.

    Attributes:
        knob: the knob's key path (or ``label``, ``draw``).
        values: its values, in sorted order.
        j_mean: mean J of the successful runs at each value [%] (None: none).
        runs: stored runs at each value.
        failed: failed runs at each value.
    """

    knob: str
    values: tuple
    j_mean: tuple[float | None, ...]
    runs: tuple[int, ...]
    failed: tuple[int, ...]

    def as_dict(self) -> dict:
        return {
            "knob": self.knob,
            "values": list(self.values),
            "j_mean_percent": list(self.j_mean),
            "runs": list(self.runs),
            "failed": list(self.failed),
        }


@dataclass(frozen=True)
class SweepSummary:
    """A sweep's results.

    Attributes:
        name: the sweep.
        axis: the objective's inner axis.
        designed: runs in the design.
        stored: of those, runs in the store.
        failed: stored runs that failed.
        points: design points, best (lowest mean J) first, failed-only points last.
        knobs: one `KnobSummary` per knob.
    """

    name: str
    axis: str
    designed: int
    stored: int
    failed: int
    points: tuple[PointSummary, ...]
    knobs: tuple[KnobSummary, ...]

    def as_json(self) -> dict:
        """The JSON document of ``isp-twin sweep --json``."""
        return {
            "sweep": self.name,
            "axis": self.axis,
            "objective": f"{self.axis} isolation J (Eq. 10) [%], lower is better",
            "runs_designed": self.designed,
            "runs_stored": self.stored,
            "runs_failed": self.failed,
            "best": self.points[0].as_dict() if self.points else None,
            "points": [p.as_dict() for p in self.points],
            "knobs": [k.as_dict() for k in self.knobs],
        }


class _Acc:
    """Running count / sum / min / max of J."""

    __slots__ = ("runs", "failed", "n", "total", "lo", "hi")

    def __init__(self):
        self.runs = self.failed = self.n = 0
        self.total, self.lo, self.hi = 0.0, math.inf, -math.inf

    def add(self, j: float | None) -> None:
        self.runs += 1
        if j is None:
            self.failed += 1
            return
        self.n += 1
        self.total += j
        self.lo, self.hi = min(self.lo, j), max(self.hi, j)

    @property
    def mean(self) -> float | None:
        return self.total / self.n if self.n else None


def _sort_key(value: Any):
    return (0, value, "") if isinstance(value, (int, float)) else (1, 0, str(value))


def summarize(sweep: Sweep, store: ResultStore) -> SweepSummary:
    """Summarize the stored runs of `sweep`'s design (runs of other designs are ignored)."""
    knob_names = sweep.knob_names
    points: dict[str, tuple[dict, _Acc]] = {}
    per_knob: dict[str, dict[str, tuple[Any, _Acc]]] = {k: {} for k in knob_names}
    stored = failed = 0
    for row in store.runs([r.key for r in sweep.runs]):
        j = row.outcome.j_percent(sweep.axis) if row.outcome.status == "ok" else None
        stored += 1
        failed += row.outcome.status != "ok"
        shown = {k: row.knobs.get(k) for k in knob_names}
        pkey = json.dumps(shown, sort_keys=True)
        points.setdefault(pkey, (shown, _Acc()))[1].add(j)
        for k in knob_names:
            v = shown[k]
            per_knob[k].setdefault(json.dumps(v), (v, _Acc()))[1].add(j)
    summaries = [
        PointSummary(
            knobs,
            acc.runs,
            acc.failed,
            acc.mean,
            acc.lo if acc.n else None,
            acc.hi if acc.n else None,
        )
        for knobs, acc in points.values()
    ]
    summaries.sort(key=lambda p: (p.j_mean is None, p.j_mean if p.j_mean is not None else 0.0))
    knobs = []
    for k in knob_names:
        entries = sorted(per_knob[k].values(), key=lambda e: _sort_key(e[0]))
        knobs.append(
            KnobSummary(
                knob=k,
                values=tuple(v for v, _ in entries),
                j_mean=tuple(a.mean for _, a in entries),
                runs=tuple(a.runs for _, a in entries),
                failed=tuple(a.failed for _, a in entries),
            )
        )
    return SweepSummary(
        name=sweep.name,
        axis=sweep.axis,
        designed=len(sweep.runs),
        stored=stored,
        failed=failed,
        points=tuple(summaries),
        knobs=tuple(knobs),
    )


def _fmt(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def format_summary(s: SweepSummary, top: int = 10) -> str:
    """Plain-text tables: the best design points, then mean J per knob value."""
    lines = [
        f"sweep {s.name}: {s.stored}/{s.designed} runs stored, {s.failed} failed; "
        f"J = {s.axis} isolation (Eq. 10) [%], lower is better",
        "",
        f"best settings (of {len(s.points)} design points, mean J over seeds):",
    ]
    for rank, p in enumerate(s.points[:top], 1):
        setting = ", ".join(f"{k}={v}" for k, v in p.knobs.items()) or "(base scenario)"
        spread = f"  [{_fmt(p.j_min)} .. {_fmt(p.j_max)}]" if p.j_mean is not None else ""
        fail = f"  {p.failed}/{p.runs} failed" if p.failed else ""
        lines.append(f"{rank:4d}. J {_fmt(p.j_mean):>8}{spread}  {setting}{fail}")
    for k in s.knobs:
        lines += ["", f"J per {k.knob}:"]
        for v, j, n, f in zip(k.values, k.j_mean, k.runs, k.failed):
            fail = f", {f} failed" if f else ""
            lines.append(f"  {str(v):>14}  J {_fmt(j):>8}  ({n} runs{fail})")
    return "\n".join(lines)


def _safe_name(knob: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in knob)


def plot_knobs(s: SweepSummary, out_dir: str | Path) -> list[Path]:
    """One PNG per knob: each design point's mean J against the knob, and the knob's mean.

    Returns:
        The files written (``J_<knob>.png`` in `out_dir`), each written whole or not at all.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from isp_twin.output.files import staged_path

    out_dir = Path(out_dir)
    written = []
    for k in s.knobs:
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in k.values)
        position = {json.dumps(v): (v if numeric else i) for i, v in enumerate(k.values)}
        fig, ax = plt.subplots(figsize=(6.0, 4.0))
        xs, ys = [], []
        for p in s.points:
            if p.j_mean is not None:
                xs.append(position[json.dumps(p.knobs.get(k.knob))])
                ys.append(p.j_mean)
        ax.scatter(xs, ys, s=14, alpha=0.5, label="design points (mean over seeds)")
        pairs = [(position[json.dumps(v)], j) for v, j in zip(k.values, k.j_mean) if j is not None]
        if pairs:
            ax.plot(*zip(*pairs), "o-", color="C3", label="mean over the other knobs")
        if not numeric:
            ax.set_xticks(range(len(k.values)), [str(v) for v in k.values])
        ax.set_xlabel(k.knob)
        ax.set_ylabel(f"J {s.axis} [%]")
        ax.set_title(f"{s.name}: J against {k.knob}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out_dir / f"J_{_safe_name(k.knob)}.png"
        with staged_path(path) as tmp:
            fig.savefig(tmp, dpi=100, format="png")
        plt.close(fig)
        written.append(path)
    return written
