"""The results store of sweeps: one SQLite file, one row per run, keyed by the run's input hash.

Only the parent process of a sweep writes it, one committed row per finished
run (WAL journal), so an interrupted sweep keeps every run it finished and a
re-run skips them. The row holds the run's inputs (JSON) so the file is
self-describing: the scenario, parameter file and draw, seed and knobs of
every number in it.

Table ``runs``: key (SHA-256 of the inputs, primary key), sweep, idx, seed,
knobs (JSON), inputs (JSON), status (``ok`` or ``failed``), metrics (JSON,
`isp_twin.experiments.metrics.run_metrics`), error (one line, failed runs), elapsed_s,
worker (host:pid), finished_utc.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from isp_twin.errors import DataError

__all__ = ["RunOutcome", "StoredRun", "ResultStore", "SCHEMA_VERSION"]

SCHEMA_VERSION = 1

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS runs (
    key TEXT PRIMARY KEY,
    sweep TEXT NOT NULL,
    idx INTEGER NOT NULL,
    seed INTEGER NOT NULL,
    knobs TEXT NOT NULL,
    inputs TEXT NOT NULL,
    status TEXT NOT NULL,
    metrics TEXT NOT NULL,
    error TEXT,
    elapsed_s REAL NOT NULL,
    worker TEXT NOT NULL,
    finished_utc TEXT NOT NULL
);
"""


@dataclass(frozen=True)
class RunOutcome:
    """What a worker sends back for one run.

    Attributes:
        key: the run's key.
        status: ``ok`` or ``failed``.
        metrics: axis -> {isolation_percent, max_abs_error_deg_s, rms_error_deg_s}.
        error: the one-line reason of a failed run.
        elapsed_s: wall time of the run [s].
        worker: host:pid that ran it.
    """

    key: str
    status: str
    metrics: Mapping[str, Any] = field(default_factory=dict)
    error: str | None = None
    elapsed_s: float = 0.0
    worker: str = ""

    def j_percent(self, axis: str) -> float | None:
        """J of Eq. 10 on `axis` [%], or None (failed run, or no carrier motion on it)."""
        m = self.metrics.get(axis)
        return None if m is None else m.get("isolation_percent")


@dataclass(frozen=True)
class StoredRun:
    """One row of the store: the outcome, with the run's knobs and seed."""

    outcome: RunOutcome
    index: int
    seed: int
    knobs: Mapping[str, Any]


class ResultStore:
    """An open results store (a path, or ``:memory:`` for a throw-away one).

    Raises:
        DataError: the file exists but is not an isp-twin results store.
    """

    def __init__(self, path: str | Path):
        self.path = str(path)
        if self.path != ":memory:":
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        try:
            self._db = sqlite3.connect(self.path, isolation_level=None)
            if self.path != ":memory:":
                self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.executescript(_SCHEMA)
            row = self._db.execute("SELECT value FROM meta WHERE name='schema'").fetchone()
            if row is None:
                self._db.execute("INSERT INTO meta VALUES ('schema', ?)", (str(SCHEMA_VERSION),))
            elif row[0] != str(SCHEMA_VERSION):
                raise DataError(
                    f"{self.path}: results store schema {row[0]}, this isp-twin reads "
                    f"{SCHEMA_VERSION}; use another --store"
                )
            self._db.execute("SELECT key, status, metrics FROM runs LIMIT 1").fetchall()
        except sqlite3.DatabaseError as exc:
            raise DataError(f"{self.path}: not an isp-twin results store ({exc})") from None

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def finished_keys(self) -> set[str]:
        """Keys of every stored run."""
        return {k for (k,) in self._db.execute("SELECT key FROM runs")}

    def put(self, spec, outcome: RunOutcome, sweep: str = "") -> bool:
        """Store one finished run (committed at once); False if it was already there."""
        cur = self._db.execute(
            "INSERT OR IGNORE INTO runs VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
            (
                outcome.key,
                sweep,
                spec.index,
                spec.seed,
                json.dumps(spec.knobs, sort_keys=True),
                json.dumps(spec.inputs(), sort_keys=True),
                outcome.status,
                json.dumps(outcome.metrics, sort_keys=True),
                outcome.error,
                outcome.elapsed_s,
                outcome.worker,
                datetime.now(UTC).isoformat(timespec="seconds"),
            ),
        )
        return cur.rowcount == 1

    def count(self) -> int:
        """Rows in the store."""
        return self._db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]

    def runs(self, keys: Iterable[str] | None = None) -> Iterator[StoredRun]:
        """The stored runs (all, or those of `keys`), streamed row by row."""
        if keys is None:
            rows = self._db.execute(
                "SELECT key, status, metrics, error, elapsed_s, worker, idx, seed, knobs "
                "FROM runs ORDER BY idx"
            )
            yield from (_stored(r) for r in rows)
            return
        keys = list(keys)
        for i in range(0, len(keys), 500):  # SQLite's host-parameter limit
            chunk = keys[i : i + 500]
            rows = self._db.execute(
                "SELECT key, status, metrics, error, elapsed_s, worker, idx, seed, knobs "
                f"FROM runs WHERE key IN ({','.join('?' * len(chunk))})",
                chunk,
            ).fetchall()
            yield from (_stored(r) for r in rows)

    def outcomes(self, keys: Sequence[str]) -> dict[str, RunOutcome]:
        """Stored outcomes of `keys`, by key (missing keys left out)."""
        return {r.outcome.key: r.outcome for r in self.runs(keys)}


def _stored(row) -> StoredRun:
    key, status, metrics, error, elapsed, worker, idx, seed, knobs = row
    return StoredRun(
        outcome=RunOutcome(key, status, json.loads(metrics), error, elapsed, worker),
        index=idx,
        seed=seed,
        knobs=json.loads(knobs),
    )
