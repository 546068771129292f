"""Long logs: identify and diagnose refuse data over --max-samples before any
work, in one line naming the limit, and write nothing (issue 8, item 7)."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.cli import main


def _csv(path, n):
    t = np.arange(n) * 1e-3
    u = 500 * np.cos(2 * np.pi * 0.5 * t)
    rows = np.column_stack([t, u, np.sin(t), np.zeros(n)])
    np.savetxt(path, rows, delimiter=",", header="t,u,omega,theta", comments="", fmt="%.9g")
    return path


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_data_over_the_sample_limit_is_refused_before_any_work(command, tmp_path, capsys):
    a = _csv(tmp_path / "a.csv", 300)
    b = _csv(tmp_path / "b.csv", 400)
    out = tmp_path / "p.yaml"
    argv = [command, str(a), str(b), "--out", str(out), "--max-samples", "500"]
    if command == "diagnose":
        argv += ["--params", _table2()]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "700 samples" in err[0] and "limit of 500" in err[0] and "--max-samples" in err[0]
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.csv"]


def _table2() -> str:
    from isp_twin.resources import default_parameters_path

    return str(default_parameters_path())
