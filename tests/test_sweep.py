"""Design sweeps: the file's checks, run identity, the store, Dask execution and the command."""

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

from isp_twin.cli import main
from isp_twin.errors import DataError
from isp_twin.experiments.sweep.design import draw_parameters, load_sweep, parse_sweep
from isp_twin.experiments.sweep.execute import execute, run_one, worker_count
from isp_twin.experiments.sweep.store import ResultStore
from isp_twin.experiments.sweep.summary import summarize

# A short closed loop (yaw 0.5 Hz, metrics over the last 0.4 s): ~50 ms a run.
SHORT = {
    "name": "short",
    "duration_s": 2.4,
    "turntable": {"table_yaw": {"rate_amplitude_deg_s": 3.141592653589793, "freq_hz": 0.5}},
    "controller": {"inner_az": {"nfc": {"enabled": True}}},
}


@pytest.fixture()
def files(tmp_path):
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(SHORT))

    def write(sweep: dict, name: str = "sw.yaml"):
        path = tmp_path / name
        path.write_text(yaml.safe_dump({"scenario": "short.yaml", **sweep}, sort_keys=False))
        return path

    return write


GRID = {
    "seeds": {"first": 1, "count": 2},
    "grid": {
        "controller.inner_az.nfc.gamma": [0.9, 0.98],
        "controller.inner_az.pi_nfc.kp_digit_per_count": {"from": 2.0, "to": 4.0, "num": 3},
    },
}


# ---------------------------------------------------------------- the design


def test_the_design_is_every_combination_and_each_run_has_its_own_key(files):
    sweep = load_sweep(
        files(
            {
                **GRID,
                "cases": [{"label": "slow", "gyro.bandwidth_hz": 100.0}, {"label": "fast"}],
                "random": {
                    "count": 3,
                    "seed": 1,
                    "knobs": {"follower.kd_digit_per_deg_s": {"low": 10.0, "high": 30.0}},
                },
            }
        )
    )
    assert len(sweep.runs) == 2 * (2 * 3) * 3 * 2
    assert len({r.key for r in sweep.runs}) == len(sweep.runs)
    assert sweep.knob_names == (
        "label",
        "controller.inner_az.nfc.gamma",
        "controller.inner_az.pi_nfc.kp_digit_per_count",
        "follower.kd_digit_per_deg_s",
    )
    kps = sorted({r.knobs["controller.inner_az.pi_nfc.kp_digit_per_count"] for r in sweep.runs})
    assert kps == [2.0, 3.0, 4.0]
    slow = [r for r in sweep.runs if r.knobs["label"] == "slow"]
    assert all(r.scenario_raw["gyro"]["bandwidth_hz"] == 100.0 for r in slow)
    kd = [r.scenario_raw["follower"]["kd_digit_per_deg_s"] for r in sweep.runs]
    assert all(10.0 <= v <= 30.0 for v in kd) and len(set(kd)) == 3


def test_a_sweep_without_a_name_is_named_after_its_file(files):
    assert load_sweep(files(GRID, "many_seeds.yaml")).name == "many_seeds"
    assert load_sweep(files({**GRID, "name": "gains"})).name == "gains"


def test_a_runs_key_depends_on_its_inputs_not_on_its_place_in_the_design(files):
    a = load_sweep(files(GRID, "a.yaml"))
    b = load_sweep(files({**GRID, "seeds": [2, 1]}, "b.yaml"))
    assert {r.key for r in a.runs} == {r.key for r in b.runs}
    c = load_sweep(files({**GRID, "seeds": [3]}, "c.yaml"))
    assert not {r.key for r in c.runs} & {r.key for r in a.runs}
    again = load_sweep(files(GRID, "a.yaml"))
    assert [r.key for r in again.runs] == [r.key for r in a.runs]


BAD = [
    ({"grdi": {}}, r"sw\.yaml: grdi: unknown key \(did you mean 'grid'\?\)"),
    (
        {"grid": {"controller.inner_az.nfc.gama": [0.9]}},
        r"grid\.controller\.inner_az\.nfc\.gama: unknown scenario key 'gama'.*did you mean 'gamma'",
    ),
    (
        {"grid": {"controller.inner_az.nfc.gamma": []}},
        r"grid\.controller\.inner_az\.nfc\.gamma: empty list",
    ),
    (
        {"grid": {"duration_s": {"from": 1.0, "to": 3.0, "num": 0}}},
        r"grid\.duration_s\.num: empty range",
    ),
    (
        {"grid": {"controller.inner_az.nfc.gamma": [0.9, 1.5]}},
        r"grid\.controller\.inner_az\.nfc\.gamma\[1\]: 1\.5 out of range; must be > 0 and <= 1",
    ),
    (
        {"random": {"count": 2, "knobs": {"gyro.noise_deg_s": {"low": 0.1, "high": 0.1}}}},
        r"random\.knobs\.gyro\.noise_deg_s: empty range",
    ),
    ({"seeds": {"first": 1, "count": 0}}, r"seeds\.count: 0 out of range"),
    ({"uncertainty": {"draws": 2, "sed": 1}}, r"uncertainty\.sed: unknown key"),
    ({"axis": "inner_za"}, r"axis: 'inner_za' is not allowed \(did you mean 'inner_az'\?\)"),
    (
        {"cases": [{"label": "x", "controller.inner_az": 1}]},
        r"cases\[0\]\.controller\.inner_az: 'controller\.inner_az' is a section",
    ),
    (
        {"grid": {"gyro.noise_deg_s": [0.01]}, "cases": [{"gyro.noise_deg_s": 0.02}]},
        r"sw\.yaml: 'gyro\.noise_deg_s' is set by both grid and cases",
    ),
    # valid knobs alone, a run the scenario loader refuses (the metrics window is empty)
    ({"grid": {"duration_s": [1.5]}}, r"the run with duration_s=1\.5: .*leaves nothing"),
]


def test_a_broken_parameter_file_to_draw_from_is_named_with_its_line(files, tmp_path, capsys):
    # Line 3 holds the error (a second ": " in a plain scalar).
    (tmp_path / "broken.yaml").write_text("name: broken\nsample_time_s: 0.001\nunits: a: b\n")
    path = files({"parameters": "broken.yaml", "uncertainty": {"draws": 2}})
    store = tmp_path / "store.sqlite"
    assert main(["sweep", str(path), "--store", str(store), "--in-process"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "sw.yaml: uncertainty: " in err and "broken.yaml: line 3 not valid YAML" in err, err
    assert not store.exists()


@pytest.mark.parametrize(("sweep", "message"), BAD)
def test_a_bad_sweep_file_is_one_line_naming_the_key_with_exit_2_before_any_run(
    files, tmp_path, capsys, sweep, message
):
    path = files(sweep)
    store = tmp_path / "store.sqlite"
    assert main(["sweep", str(path), "--store", str(store), "--in-process"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("isp-twin sweep: error: ")
    assert __import__("re").search(message, err), err
    assert not store.exists()  # no run started, no store made


def test_a_batch_below_one_run_is_a_one_line_error_before_any_run(files, tmp_path, capsys):
    store = tmp_path / "store.sqlite"
    assert main(["sweep", str(files(GRID)), "--store", str(store), "--batch", "0"]) == 2
    err = capsys.readouterr().err
    assert err == "isp-twin sweep: error: --batch must be >= 1, got 0\n"
    assert not store.exists()


def test_parameter_draws_scatter_with_the_ci95_and_repeat_with_their_seed():
    params = {
        "axes": {
            "x": {"R+": {"Ts": {"value": 5.0, "ci95": 0.2}, "a": {"value": 0.9, "ci95": 0.01}}}
        }
    }
    ts = np.array([draw_parameters(params, 3, d)["x"]["R+"]["Ts"] for d in range(4000)])
    # the ci95 is the half-width of a normal 95 % interval: sigma = ci95 / 1.96
    assert ts.mean() == pytest.approx(5.0, abs=4 * 0.2 / 1.96 / np.sqrt(4000))
    assert ts.std(ddof=1) == pytest.approx(0.2 / 1.96, rel=0.05)
    assert np.mean(np.abs(ts - 5.0) <= 0.2) == pytest.approx(0.95, abs=0.015)
    assert draw_parameters(params, 3, 7) == draw_parameters(params, 3, 7)
    assert draw_parameters(params, 3, 7) != draw_parameters(params, 4, 7)


def test_a_drawn_plant_differs_from_the_nfc_model_which_keeps_the_nominal_values(files):
    sweep = load_sweep(files({"uncertainty": {"draws": 2, "seed": 5}}))
    assert [r.knobs["draw"] for r in sweep.runs] == [0, 1]
    assert sweep.runs[0].parameter_draw != sweep.runs[1].parameter_draw
    nominal = run_one(parse_sweep({"scenario": str(files({}).parent / "short.yaml")}).runs[0])
    drawn = [run_one(r) for r in sweep.runs]
    js = [o.j_percent("inner_az") for o in drawn]
    assert all(o.status == "ok" for o in drawn)
    assert js[0] != js[1] and nominal.j_percent("inner_az") not in js


# ---------------------------------------------------------------- the store


def test_the_store_keeps_each_run_once_and_survives_reopening(files, tmp_path):
    sweep = load_sweep(files({"seeds": [1, 2, 3]}))
    path = tmp_path / "s.sqlite"
    with ResultStore(path) as store:
        outcome = run_one(sweep.runs[0])
        assert store.put(sweep.runs[0], outcome)
        assert not store.put(sweep.runs[0], outcome)
    with ResultStore(path) as store:
        assert store.finished_keys() == {sweep.runs[0].key}
        assert store.outcomes([sweep.runs[0].key])[sweep.runs[0].key] == outcome
        assert execute(sweep.runs, store, in_process=True) == (2, 1)
        assert execute(sweep.runs, store, in_process=True) == (0, 3)
        assert store.count() == 3
    row = sqlite3.connect(path).execute("SELECT inputs FROM runs WHERE seed=2").fetchone()
    assert json.loads(row[0])["scenario"]["duration_s"] == 2.4  # self-describing rows


def test_a_file_that_is_not_a_store_is_a_one_line_error(tmp_path):
    bad = tmp_path / "x.sqlite"
    bad.write_text("not a database at all, just text " * 100)
    with pytest.raises(DataError, match=r"x\.sqlite: not an isp-twin results store"):
        ResultStore(bad)


def test_ctrl_c_keeps_every_finished_run_and_the_rerun_does_only_the_rest(files, tmp_path):
    sweep = load_sweep(files({"seeds": [1, 2, 3, 4]}))
    path = tmp_path / "s.sqlite"

    def stop_after_two(p):
        if p.done == 2:
            raise KeyboardInterrupt

    with ResultStore(path) as store, pytest.raises(KeyboardInterrupt):
        execute(sweep.runs, store, in_process=True, on_progress=stop_after_two)
    with ResultStore(path) as store:
        assert store.count() == 2
        assert execute(sweep.runs, store, in_process=True) == (2, 2)


def test_a_diverging_setting_is_a_failed_run_not_a_crash(files):
    sweep = load_sweep(
        files({"grid": {"controller.inner_az.pi_nfc.kp_digit_per_count": [3.0, 1000.0]}})
    )
    with ResultStore(":memory:") as store:
        execute(sweep.runs, store, in_process=True)
        summary = summarize(sweep, store)
    assert summary.failed == 1 and summary.stored == 2
    best, worst = summary.points
    assert best.knobs["controller.inner_az.pi_nfc.kp_digit_per_count"] == 3.0
    assert worst.j_mean is None and worst.failed == 1


# ---------------------------------------------------------------- Dask


def test_worker_count_is_bounded_by_the_runs_and_the_cores():
    assert worker_count(100000, 4, cores=2) == 2
    assert worker_count(100000, 1, cores=8) == 1
    assert worker_count(None, 1000, cores=8) == 8
    assert worker_count(3, 1000, cores=8) == 3
    assert worker_count(0, 0, cores=8) == 1


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as lc,
        Client(lc) as client,
    ):
        yield client


def _stored(store, sweep):
    return {
        k: (o.status, o.metrics) for k, o in store.outcomes([r.key for r in sweep.runs]).items()
    }


def test_in_process_one_worker_two_workers_and_batches_give_identical_numbers(files, cluster):
    sweep = load_sweep(
        files({**GRID, "grid": {"controller.inner_az.nfc.gamma": [0.9, 0.95, 0.98]}})
    )
    results = []
    with ResultStore(":memory:") as store:
        execute(sweep.runs, store, in_process=True)
        results.append(_stored(store, sweep))
    with ResultStore(":memory:") as store:
        execute(sweep.runs, store, workers=1)  # its own local cluster of one worker
        results.append(_stored(store, sweep))
    with ResultStore(":memory:") as store:
        execute(sweep.runs, store, client=cluster)
        results.append(_stored(store, sweep))
    # batches of 4 on 2 workers: one full batch, one short; each run lands once
    with ResultStore(":memory:") as store:
        done, _ = execute(sweep.runs, store, client=cluster, batch=4)
        results.append(_stored(store, sweep))
        assert done == len(list(store.runs())) == 6
    assert len(results[0]) == len(sweep.runs) == 6
    assert results[0] == results[1] == results[2] == results[3]
    # the seeds and gammas differ, so the numbers do
    assert len({json.dumps(m, sort_keys=True) for _, m in results[0].values()}) == 6


@pytest.mark.parametrize("batch", [1, 3])
def test_a_worker_killed_mid_sweep_has_its_runs_redone_and_each_run_is_stored_once(
    files, cluster, batch
):
    sweep = load_sweep(files({"seeds": {"first": 10, "count": 12}}))
    pids = cluster.run(os.getpid)
    killed = []

    def kill_one(p):
        if not killed:
            victim = next(pid for pid in pids.values() if not p.outcome.worker.endswith(f":{pid}"))
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    with ResultStore(":memory:") as store:
        done, skipped = execute(
            sweep.runs, store, client=cluster, on_progress=kill_one, batch=batch
        )
        rows = list(store.runs())
        stored = _stored(store, sweep)
    assert killed and (done, skipped) == (12, 0)
    assert sorted(r.outcome.key for r in rows) == sorted(r.key for r in sweep.runs)
    assert all(r.outcome.status == "ok" for r in rows)
    with ResultStore(":memory:") as store:  # redone runs give the same numbers
        execute(sweep.runs[:3], store, in_process=True)
        assert _stored(store, sweep) == {k: stored[k] for k in (r.key for r in sweep.runs[:3])}
    cluster.wait_for_workers(2, timeout=30)  # the nanny restarts the killed worker


def _rows(store) -> int:
    """Rows in a store another process is creating (0 before its table exists)."""
    if not store.exists():
        return 0
    try:
        with sqlite3.connect(store, timeout=5) as db:
            return db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    except sqlite3.OperationalError:
        return 0


SCRIPT = """
import sys
from isp_twin.cli import main
if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
"""


def test_a_killed_sweep_takes_its_local_workers_down_and_keeps_its_finished_runs(files, tmp_path):
    import psutil

    path = files({"seeds": {"first": 1, "count": 60}})
    store = tmp_path / "s.sqlite"
    script = tmp_path / "cli.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen(
        [
            sys.executable,
            str(script),
            "sweep",
            str(path),
            "--store",
            str(store),
            "--workers",
            "2",
            "--no-plots",
        ],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.time() + 60
        while time.time() < deadline and proc.poll() is None:
            if _rows(store):
                break
            time.sleep(0.2)
        children = psutil.Process(proc.pid).children(recursive=True)
        assert len(children) >= 2
    finally:
        proc.kill()
        proc.wait()
    gone, alive = psutil.wait_procs(children, timeout=20)
    assert not alive
    assert 1 <= _rows(store) < 60


# ---------------------------------------------------------------- the command


def test_the_sweep_command_prints_the_best_setting_writes_plots_and_json(files, tmp_path, capsys):
    path = files(GRID)
    store, out, plots = tmp_path / "s.sqlite", tmp_path / "s.json", tmp_path / "plots"
    args = ["sweep", str(path), "--store", str(store), "--json", str(out), "--plots", str(plots)]
    assert main(args + ["--in-process"]) == 0
    captured = capsys.readouterr()
    printed = captured.out
    # not a terminal: plain progress lines with an ETA, the last one complete
    progress = captured.err.splitlines()
    assert progress[-1].startswith("sweep: 12/12 runs done") and "ETA" in progress[0]
    doc = json.loads(out.read_text())
    assert doc["runs_designed"] == doc["runs_stored"] == 12
    # the best point is the lowest mean J over its seeds, recomputed from the store here
    by_point = {}
    for row in ResultStore(store).runs():
        key = json.dumps(row.knobs, sort_keys=True)
        by_point.setdefault(key, []).append(row.outcome.j_percent("inner_az"))
    best = min(by_point, key=lambda k: np.mean(by_point[k]))
    assert doc["best"]["knobs"] == json.loads(best)
    assert doc["best"]["j_mean_percent"] == pytest.approx(np.mean(by_point[best]), rel=1e-12)
    knob = next(k for k in doc["knobs"] if k["knob"] == "controller.inner_az.nfc.gamma")
    assert knob["values"] == [0.9, 0.98] and knob["runs"] == [6, 6]
    assert sorted(p.name for p in plots.iterdir()) == [
        "J_controller.inner_az.nfc.gamma.png",
        "J_controller.inner_az.pi_nfc.kp_digit_per_count.png",
    ]
    assert "best settings" in printed and "J per controller.inner_az.nfc.gamma" in printed
    # a second call finds everything in the store
    assert main(args + ["--no-plots"]) == 0
    assert "12 already in" in capsys.readouterr().out


def test_campaign_with_absurd_jobs_starts_no_more_workers_than_runs_and_cores(monkeypatch, capsys):
    import isp_twin.experiments.sweep.execute as ex

    started = []
    real = ex.local_client

    def spy(n):
        started.append(n)
        return real(n)

    monkeypatch.setattr(ex, "local_client", spy)
    assert main(["campaign", "tracking_0_5Hz", "-n", "1", "--jobs", "100000"]) == 0
    assert started and started[0] <= min(2, len(os.sched_getaffinity(0)))
    assert "NFC reduces the average J" in capsys.readouterr().out


def test_the_shipped_example_sweep_is_valid():
    from isp_twin.resources import resource_root

    sweep = load_sweep(resource_root() / "scenarios" / "sweeps" / "nfc_gamma_kp.yaml")
    assert len(sweep.runs) == 3 * 3 * 3 * 5
    assert sweep.knob_names[-1] == "draw"


def test_a_sweep_runs_on_an_existing_scheduler_by_its_address(files, cluster):
    sweep = load_sweep(files({"seeds": [1, 2]}))
    address = cluster.scheduler.address
    with ResultStore(":memory:") as store:
        assert execute(sweep.runs, store, scheduler=address) == (2, 0)
        workers = {o.worker for o in store.outcomes([r.key for r in sweep.runs]).values()}
    assert workers and all(w.split(":")[1] != str(os.getpid()) for w in workers)
    assert cluster.scheduler_info()["workers"]  # our client closed, the cluster lives on


def test_runs_with_identical_inputs_are_one_run(files):
    # 40 draws of an integer knob with 3 values must repeat; each setting runs once
    sweep = load_sweep(
        files(
            {
                "random": {
                    "count": 40,
                    "seed": 2,
                    "knobs": {"gyro.sample_every": {"low": 1, "high": 3}},
                }
            }
        )
    )
    assert sorted(r.knobs["gyro.sample_every"] for r in sweep.runs) == [1, 2, 3]
    assert [r.index for r in sweep.runs] == [0, 1, 2]
