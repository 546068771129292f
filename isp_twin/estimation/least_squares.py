"""The local solvers of the estimation engine: bounded least squares on a
simulation error.

`lm_steps` / `solve_many` / `levenberg_marquardt`: Levenberg-Marquardt with
batched residuals. The model is a recursive simulation whose cost is the
time loop, not the batch width, so every iteration evaluates all Jacobian
columns (forward differences) in one batched call and three damping trials
in a second one, and `solve_many` runs many problems in lockstep (diagnose:
every candidate effect's refit in one simulation). Scaled variables
(``x / scale``) keep the damping meaningful across parameters spanning ten
decades.

`trust_region`: scipy's trust-region reflective solver for one problem
with a long budget (identify's refinement, in log variables). Tried in its
place, `levenberg_marquardt` (same budget, tolerance and difference step)
gave the same fit on 8 of 10 clean dev axes and a worse one on dev 1001
(train RMS 1.82 noise floors for 1.07; held out 197 for 1.22): the trust
region's step control is worth its sequential steps there
(docs/identification.md, "One estimation engine").
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

__all__ = [
    "FitResult",
    "FitStatus",
    "Relative",
    "TrustRegionResult",
    "levenberg_marquardt",
    "lm_steps",
    "solve_many",
    "trust_region",
]


class FitStatus(Enum):
    CONVERGED = "converged"
    MAX_ITERATIONS = "max_iterations"
    NO_PROGRESS = "no_progress"


@dataclass(frozen=True)
class FitResult:
    """Outcome of `levenberg_marquardt`.

    Attributes:
        x: best parameters, (n,).
        residual: residuals at x, (M,).
        sse: sum of squared residuals at x.
        jacobian: d residual / d x at the last linearisation point, (M, n)
            (zero columns where the model could not be simulated beside x);
            the intervals come from it (`isp_twin.estimation.intervals`).
        status: why it stopped.
        sse_log: sse after each iteration.
    """

    x: np.ndarray
    residual: np.ndarray
    sse: float
    jacobian: np.ndarray
    status: FitStatus
    sse_log: tuple[float, ...]


@dataclass(frozen=True)
class Relative:
    """Points whose residuals `lm_steps` only compares among themselves, as
    it yields them with ``relative``: a Jacobian's finite-difference set
    (its linearisation point first, then one point per column) and the
    static scan's (the start first, then the scanned points). The evaluator
    may simulate them with a cheaper model (diagnose: fewer sub-steps,
    `isp_twin.estimation.simulation_error.JACOBIAN_SUBSTEPS`): the columns
    are then that model's slopes, the scan that model's ranking."""

    points: np.ndarray


def lm_steps(
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    max_iter: int = 8,
    rtol: float = 1e-3,
    rel_step: float = 1e-3,
    scan: Sequence[int] = (),
    scan_factors: Sequence[float] = (0.6, 0.7, 0.8, 0.9, 0.95, 1.05, 1.1, 1.2, 1.35, 1.5),
    relative: bool = False,
) -> Generator[np.ndarray | Relative, np.ndarray, FitResult]:
    """Levenberg-Marquardt as a generator: it yields the points it needs,
    shape (P, n), receives their residuals, shape (P, M), and returns the
    `FitResult`. `solve_many` drives several in lockstep, so one batched
    simulation serves every problem's iteration.

    Parameters listed in `scan` are first scanned one at a time over
    ``x0 * scan_factors`` (the best of each kept, then checked together):
    thresholds such as the breakaway torque change the cost in steps that a
    finite difference does not see.

    With `relative`, each iteration's columns and the scan are asked for as
    `Relative` (the evaluator's cheaper model); every step, and the scan's
    choice, is still accepted on the residuals of plain points, and the
    returned `FitResult.jacobian` (the intervals') is one more set of plain
    columns at the end point.
    """
    x = np.clip(np.asarray(x0, float), lower, upper)
    r = (yield x[None])[0]
    sse = float(r @ r)
    if len(scan):
        x, r, sse = yield from _scanned(x, r, sse, lower, upper, scan, scan_factors, relative)
    fit = yield from _iterations(x, r, sse, lower, upper, scale, max_iter, rtol, rel_step, relative)
    if relative and fit.x.size:
        jac = yield from _jacobian(fit.x, fit.residual, scale, upper, rel_step)
        fit = replace(fit, jacobian=jac)
    return fit


_Steps = Generator[np.ndarray, np.ndarray, tuple]


def _scanned(x, r, sse, lower, upper, scan, scan_factors, relative=False) -> _Steps:
    """`lm_steps`' one-at-a-time scan of the parameters in `scan`; (x, r, sse)
    after it. `relative`: the scanned points are compared with x simulated
    with them (`Relative`), the choice then checked on x's plain sse."""
    factors = np.asarray(scan_factors, float)
    pts = np.repeat(x[None], len(scan) * factors.size, axis=0)
    for j, i in enumerate(scan):
        pts[j * factors.size : (j + 1) * factors.size, i] = x[i] * factors
    pts = np.clip(pts, lower, upper)
    base = sse
    if relative:
        rs = yield Relative(np.vstack([x[None], pts]))
        base, rs = float(rs[0] @ rs[0]), rs[1:]
    else:
        rs = yield pts
    sses = np.einsum("ij,ij->i", rs, rs).reshape(len(scan), factors.size)
    sses = np.where(np.isfinite(sses), sses, np.inf)
    trial = x.copy()
    for j, i in enumerate(scan):
        k = int(np.argmin(sses[j]))
        if sses[j, k] < base:
            trial[i] = pts[j * factors.size + k, i]
    if np.any(trial != x):
        rt = (yield trial[None])[0]
        if float(rt @ rt) < sse:
            x, r, sse = trial, rt, float(rt @ rt)
    return x, r, sse


def _iterations(
    x, r, sse, lower, upper, scale, max_iter, rtol, rel_step, relative=False
) -> Generator[np.ndarray | Relative, np.ndarray, FitResult]:
    """`lm_steps`' damped Gauss-Newton iterations from x (three dampings tried per iteration)."""
    n = x.size
    lam = 1e-2
    log = []
    status = FitStatus.MAX_ITERATIONS
    jac = np.zeros((r.size, n))
    for _ in range(max_iter):
        if n == 0:
            status = FitStatus.CONVERGED
            break
        jac = yield from _jacobian(x, r, scale, upper, rel_step, relative)
        lams = lam * np.array([0.1, 1.0, 10.0])
        trials = _damped_steps(jac, r, x, scale, lower, upper, lams)
        rt = yield trials
        sses = np.einsum("ij,ij->i", rt, rt)
        sses = np.where(np.isfinite(sses), sses, np.inf)  # a diverged trial is no step
        best = int(np.argmin(sses))
        if sses[best] < sse:
            gain = (sse - sses[best]) / max(sse, 1e-300)
            x, r, sse = trials[best], rt[best], float(sses[best])
            lam = lams[best] / 3.0
            log.append(sse)
            if gain < rtol:
                status = FitStatus.CONVERGED
                break
        else:
            lam *= 100.0
            log.append(sse)
            if lam > 1e8:
                status = FitStatus.NO_PROGRESS
                break
    return FitResult(x, r, sse, jac, status, tuple(log))


def _jacobian(
    x, r, scale, upper, rel_step, relative: bool = False
) -> Generator[np.ndarray | Relative, np.ndarray, np.ndarray]:
    """Forward differences at x (one batched evaluation), (M, n); `relative`:
    from x's residuals simulated with the columns (`Relative`), not from r."""
    h = rel_step * scale
    step = np.where(x + h <= upper, h, -h)
    pts = x[None] + np.diag(step)
    if relative:
        rs = yield Relative(np.vstack([x[None], pts]))
        jac = ((rs[1:] - rs[0][None]) / step[:, None]).T
    else:
        jac = (((yield pts) - r[None]) / step[:, None]).T  # (M, n)
    # A finite-difference point the model cannot simulate (a candidate
    # that diverges there) gives no slope: that parameter stays put this
    # iteration and, if it never gets one, has no interval (a zero column).
    jac[:, ~np.all(np.isfinite(jac), axis=0)] = 0.0
    return jac


def _damped_steps(jac, r, x, scale, lower, upper, lams) -> np.ndarray:
    """The Levenberg-Marquardt steps from x for each damping in `lams`, clipped: (len(lams), n)."""
    n = x.size
    js = jac * scale  # scaled variables
    with np.errstate(over="ignore", invalid="ignore"):  # steep slopes: no interval later
        a = js.T @ js
        g = js.T @ r
    diag = np.diag(a).copy()
    diag[diag <= 0] = 1.0
    trials = []
    for lm in lams:
        try:
            dz = -np.linalg.solve(a + lm * np.diag(diag) + 1e-12 * np.eye(n), g)
        except np.linalg.LinAlgError:
            dz = -np.linalg.lstsq(a + lm * np.diag(diag), g, rcond=None)[0]
        trials.append(np.clip(x + dz * scale, lower, upper))
    return np.array(trials)


def solve_many(
    problems: Sequence[Generator],
    evaluate: Callable[[list[tuple[int, np.ndarray]]], list[np.ndarray]],
) -> list[FitResult]:
    """Run several `lm_steps` generators in lockstep.

    Args:
        problems: the generators.
        evaluate: [(problem index, points (P, n_i))] -> [residuals (P, M)],
            one call per round for all problems still running.
    """
    results: list[FitResult | None] = [None] * len(problems)
    pending = {i: next(g) for i, g in enumerate(problems)}
    while pending:
        keys = list(pending)
        outs = evaluate([(i, pending[i]) for i in keys])
        for i, out in zip(keys, outs):
            try:
                pending[i] = problems[i].send(out)
            except StopIteration as stop:
                results[i] = stop.value
                del pending[i]
    return results  # type: ignore[return-value]


def levenberg_marquardt(
    batch_residual: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    max_iter: int = 8,
    rtol: float = 1e-3,
    rel_step: float = 1e-3,
) -> FitResult:
    """Minimise the sum of squares of ``batch_residual`` within bounds.

    Args:
        batch_residual: X of shape (P, n) -> residuals of shape (P, M).
        x0: start, (n,), inside the bounds.
        lower, upper: bounds, (n,).
        scale: typical magnitude of each parameter, (n,) > 0.
        max_iter: iterations (each costs two batched evaluations).
        rtol: stop when an accepted step lowers the sse by less than this fraction.
        rel_step: forward-difference step in scaled units.
    """
    gen = lm_steps(x0, lower, upper, scale, max_iter, rtol, rel_step)
    return solve_many([gen], lambda reqs: [batch_residual(x) for _, x in reqs])[0]


@dataclass(frozen=True)
class TrustRegionResult:
    """Outcome of `trust_region`.

    Attributes:
        x: the end point, (n,).
        residual: residuals there, (M,).
        sse: their sum of squares.
        status: `FitStatus.MAX_ITERATIONS` when the budget ran out, else
            `FitStatus.CONVERGED` (a tolerance was met).
        message: the solver's reason to stop.
    """

    x: np.ndarray
    residual: np.ndarray
    sse: float
    status: FitStatus
    message: str


def trust_region(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    budget: int,
    ftol: float,
) -> TrustRegionResult:
    """Minimise the sum of squares of ``residual`` within bounds (scipy's
    trust-region reflective method, variables scaled by the Jacobian's columns).

    Args:
        residual: x (n,) -> residuals (M,).
        jacobian: x (n,) -> d residual / d x (M, n).
        x0: start, clipped into the bounds.
        lower, upper: bounds, (n,).
        budget: residual evaluations at most.
        ftol: stop when a step lowers the cost by less than this fraction.
    """
    from scipy.optimize import least_squares

    ls = least_squares(
        residual,
        np.clip(x0, lower, upper),
        jac=jacobian,
        bounds=(lower, upper),
        x_scale="jac",
        max_nfev=budget,
        method="trf",
        ftol=ftol,
    )
    status = FitStatus.MAX_ITERATIONS if ls.status == 0 else FitStatus.CONVERGED
    return TrustRegionResult(
        ls.x, ls.fun, float(2.0 * ls.cost), status, ls.message.rstrip(".")
    )  # fmt: skip
