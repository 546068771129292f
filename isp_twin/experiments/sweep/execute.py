"""Running a sweep's runs: in this process, or on Dask distributed (local or remote cluster).

The parent process owns the results store: each finished run is written to
it (and committed) the moment its result arrives, so Ctrl-C, a killed worker
or a killed parent loses only the runs in flight. Runs already in the store
are skipped. On Dask a run on a worker that dies is resubmitted by the
scheduler elsewhere; the store's key makes each run land exactly once.

Local clusters are bounded by the work and the machine
(`worker_count`), and go down with the parent: Dask starts its worker
processes with a pipe to the parent and they exit when it closes.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from isp_twin.errors import IspTwinError
from isp_twin.experiments.sweep.design import RunSpec, scenario_of
from isp_twin.experiments.sweep.store import ResultStore, RunOutcome

__all__ = [
    "worker_count",
    "run_one",
    "run_batch",
    "Progress",
    "local_client",
    "dask_client",
    "execute",
]

#: Runs in flight per worker thread: enough to keep every worker busy between
#: results, few enough that the parent holds O(workers) futures, not O(runs).
IN_FLIGHT_PER_WORKER = 4


def worker_count(requested: int | None, pending: int, cores: int | None = None) -> int:
    """Worker processes for a local cluster: never more than the runs or the cores.

    Args:
        requested: the user's wish (None: all cores).
        pending: runs still to do.
        cores: usable cores (default: this process's CPU affinity).
    """
    if cores is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cores = max(1, cores or 1)
    want = cores if requested is None else max(1, int(requested))
    return max(1, min(want, cores, max(1, pending)))


@lru_cache(maxsize=8)
def _parameters(path: str, mtime_ns: int, draw_json: str | None):
    """The plant's and the NFC's parameter sets (cached per worker process and file version)."""
    import json

    from isp_twin.model.parameters import load_parameters
    from isp_twin.vocabulary import REGIMES

    nominal = load_parameters(path)
    if draw_json is None:
        return nominal, nominal
    plant = nominal
    for axis, regimes in json.loads(draw_json).items():
        ax = plant.axis(axis)
        new = list(ax.regimes)
        for regime, values in regimes.items():
            i = REGIMES.index(regime)
            new[i] = dataclasses.replace(new[i], **values)
        plant = plant.with_axis(axis, dataclasses.replace(ax, regimes=tuple(new)))
    return plant, nominal


def _mtime(path: str) -> int:
    try:
        return os.stat(path).st_mtime_ns
    except OSError:
        return 0  # load_parameters names the missing file


def run_one(spec: RunSpec) -> RunOutcome:
    """Run one spec (in any process) and return its outcome.

    A run that diverges, or whose inputs the twin rejects, is an outcome
    (status ``failed`` with the one-line reason), not an exception: in a gain
    sweep an unstable setting is a result.
    """
    import json

    from isp_twin.experiments.closed_loop import ClosedLoop

    start = time.perf_counter()
    try:
        draw = json.dumps(spec.parameter_draw, sort_keys=True) if spec.parameter_draw else None
        plant, nominal = _parameters(spec.parameters, _mtime(spec.parameters), draw)
        scenario = scenario_of(spec)
        # The NFC compensates with the scenario's nfc_parameters; 'plant' is the
        # parameter file's nominal set, which a drawn plant departs from.
        nfc = nominal if scenario.nfc_parameters == "plant" else None
        loop = ClosedLoop(scenario, params=plant, seed=spec.seed, nfc_params=nfc)
        loop.run()
        metrics = dict(loop.metrics())
        status, error = "ok", None
    except IspTwinError as exc:
        metrics, status, error = {}, "failed", str(exc)
    return RunOutcome(
        key=spec.key,
        status=status,
        metrics=metrics,
        error=error,
        elapsed_s=time.perf_counter() - start,
        worker=f"{os.uname().nodename}:{os.getpid()}",
    )


def run_batch(specs: Sequence[RunSpec]) -> list[RunOutcome]:
    """Run several specs back to back in one process (one Dask task of a ``--batch`` sweep).

    Each run is `run_one` of its spec, so its numbers are those of a run on
    its own. The closed loop runs compiled (`isp_twin.experiments.closed_loop_kernel`),
    so there is no per-sample Python left that stepping the runs in lockstep
    could share; what a batch saves is per task: the scheduler round trip and
    the transfer of one spec and one outcome.
    """
    return [run_one(spec) for spec in specs]


@dataclass(frozen=True)
class Progress:
    """Where a sweep stands, after each stored run.

    Attributes:
        done: runs finished in this call.
        total: runs to do in this call (the design minus what the store had).
        skipped: runs found in the store and not redone.
        failed: finished runs with status ``failed`` so far.
        elapsed_s: wall time since the first submission [s].
        outcome: the run just stored.
    """

    done: int
    total: int
    skipped: int
    failed: int
    elapsed_s: float
    outcome: RunOutcome

    @property
    def eta_s(self) -> float:
        """Time left at the mean rate so far [s]."""
        return self.elapsed_s / self.done * (self.total - self.done) if self.done else math.inf


def local_client(n_workers: int):
    """A LocalCluster of `n_workers` single-threaded processes and its client."""
    import dask
    from distributed import Client, LocalCluster

    # The scheduler lives in this process: short logs keep its memory flat
    # over many tasks (Dask's defaults keep 10 000 entries per log).
    logs = {"distributed.admin.log-length": 1000, "distributed.admin.low-level-log-length": 200}
    try:
        with dask.config.set(logs):
            cluster = LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # no fixed port: several sweeps may run at once
                silence_logs=logging.ERROR,
                # numpy's BLAS must not start threads of its own in each worker
                env={"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"},
            )
    except (OSError, RuntimeError, TimeoutError) as exc:
        raise IspTwinError(
            f"cannot start a local Dask cluster of {n_workers} workers: {exc}"
        ) from None
    return Client(cluster), cluster


def execute(
    runs: Sequence[RunSpec],
    store: ResultStore,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    in_process: bool = False,
    client: Any = None,
    on_progress: Callable[[Progress], None] | None = None,
    name: str = "",
    batch: int = 1,
) -> tuple[int, int]:
    """Run every spec not yet in `store`, storing each result as it arrives.

    Args:
        runs: the design.
        store: the results store (written by this process only).
        workers: local worker processes (None: all cores); bounded by
            `worker_count`.
        scheduler: address of a running Dask scheduler (``tcp://host:8786``)
            to use instead of a local cluster.
        in_process: run here, one after the other (no Dask).
        client: an existing `distributed.Client` to use (tests, notebooks).
        on_progress: called after each stored run.
        name: the sweep's name, stored with each run.
        batch: runs per Dask task (`run_batch`); the runs of a batch are
            stored when the batch returns, and a batch on a worker that dies
            is redone whole.

    Returns:
        (runs done now, runs skipped because the store had them).
    """
    pending = _pending(runs, store.finished_keys())
    skipped = len(runs) - len(pending)
    if batch < 1:
        raise IspTwinError(f"batch must be >= 1 runs per task, got {batch}")
    if not pending:
        return 0, skipped
    tracker = _Tracker(len(pending), skipped, on_progress)
    if in_process:
        for spec in pending:
            outcome = run_one(spec)
            store.put(spec, outcome, name)
            tracker.stored(outcome)
        return tracker.done, skipped
    own = None
    if client is None:
        own = dask_client(scheduler, workers, len(pending))
        client = own[0]
    try:
        _run_on_dask(client, pending, store, tracker, name, batch)
    finally:
        if own is not None:
            own[0].close()
            if own[1] is not None:
                own[1].close()
    return tracker.done, skipped


def _pending(runs: Sequence[RunSpec], finished: set[str]) -> list[RunSpec]:
    """The runs not in the store yet, each key once, in design order."""
    pending: list[RunSpec] = []
    seen = set()
    for spec in runs:
        if spec.key in finished or spec.key in seen:
            continue
        seen.add(spec.key)
        pending.append(spec)
    return pending


def dask_client(scheduler: str | None, workers: int | None, n_pending: int) -> tuple[Any, Any]:
    """(client, local cluster or None): the scheduler at `scheduler`, else a local cluster
    of `worker_count` workers; close both when done.

    Raises:
        IspTwinError: the scheduler does not answer.
    """
    if scheduler is not None:
        from distributed import Client

        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise IspTwinError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        return client, None
    return local_client(worker_count(workers, n_pending))


class _Tracker:
    def __init__(self, total: int, skipped: int, on_progress):
        self.total, self.skipped, self.on_progress = total, skipped, on_progress
        self.done = self.failed = 0
        self.start = time.perf_counter()

    def stored(self, outcome: RunOutcome) -> None:
        self.done += 1
        self.failed += outcome.status != "ok"
        if self.on_progress is not None:
            self.on_progress(
                Progress(
                    self.done,
                    self.total,
                    self.skipped,
                    self.failed,
                    time.perf_counter() - self.start,
                    outcome,
                )
            )


def _run_on_dask(
    client,
    pending: Sequence[RunSpec],
    store: ResultStore,
    tracker: _Tracker,
    name: str,
    batch: int = 1,
) -> None:
    from distributed import as_completed

    threads = sum(client.nthreads().values()) or 1
    window = max(2, IN_FLIGHT_PER_WORKER * threads)
    chunks = (list(pending[i : i + batch]) for i in range(0, len(pending), batch))
    by_key: dict[str, RunSpec] = {}

    def submit(chunk: list[RunSpec]):
        for spec in chunk:
            by_key[spec.key] = spec
        # pure=False: the run keys are the identity, the store dedupes
        if batch == 1:
            return client.submit(run_one, chunk[0], key=f"run-{chunk[0].key}", pure=False)
        return client.submit(run_batch, chunk, key=f"runs-{chunk[0].key}-{len(chunk)}", pure=False)

    stream = as_completed([submit(c) for _, c in zip(range(window), chunks)])
    try:
        for future in stream:
            result = future.result()
            for outcome in [result] if batch == 1 else result:
                store.put(by_key.pop(outcome.key), outcome, name)
                tracker.stored(outcome)
            future.release()
            nxt = next(chunks, None)
            if nxt is not None:
                stream.add(submit(nxt))
    except BaseException:
        for f in list(stream.futures):
            f.cancel()
        raise
