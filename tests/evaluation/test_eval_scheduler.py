"""``eval --scheduler``: the same runs on a Dask cluster as on local processes,
bit for bit, file filters hosted there too; and module filters (``pkg.mod:Class``) hosted
in a child process of their own by ``eval`` and ``check``."""

from __future__ import annotations

import json
import os
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.montecarlo import on_dask, run_monte_carlo, run_monte_carlo_isolated

ATTACKS = Path(__file__).parents[1] / "attacks"

#: A module filter that reports, through its covariance, whether it runs in the grader's
#: process (the pid the test passes in its parameters) and whether the simulation's objects
#: are reachable through ``gc`` there.
PROBE = textwrap.dedent("""
    import gc
    import os

    import numpy as np

    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


    class Probe(ExtendedKalmanFilter):
        def estimate(self):
            mean, cov = super().estimate()
            here = os.getpid() == int(os.environ.get("PROBE_GRADER_PID", "-1"))
            sims = any(type(o).__name__ == "Simulation" and type(o).__module__ ==
                       "beacon_sim.core.simulation" for o in gc.get_objects())
            return mean, cov + np.eye(3) * ((10.0 if here else 0.0) + (100.0 if sims else 0.0))
    """)


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as c, distributed.Client(c) as client:
        yield client


def _same(a, b) -> None:
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        assert ra.seed == rb.seed and np.array_equal(ra.truth, rb.truth)
        assert set(ra.filters) == set(rb.filters)
        for name in ra.filters:
            fa, fb = ra.filters[name], rb.filters[name]
            for attr in ("pos_err", "nees", "failed"):
                x, y = getattr(fa, attr, None), getattr(fb, attr, None)
                if isinstance(x, np.ndarray):
                    assert np.array_equal(x, y, equal_nan=True), (name, attr)
                else:
                    assert x == y, (name, attr)


def test_dask_runs_equal_local_runs_bit_for_bit(cluster):
    sc = load_scenario("default")
    for batch in (None, False):
        local = run_monte_carlo(sc, ["ekf", "pf"], 3, seed=5, duration=3.0, jobs=1, batch=batch)
        dask = run_monte_carlo(sc, ["ekf", "pf"], 3, seed=5, duration=3.0, batch=batch,
                               scheduler=cluster)
        _same(local, dask)
    # By address, as ``eval --scheduler tcp://...`` does (a client of its own, closed after).
    address = cluster.scheduler.address
    _same(run_monte_carlo(sc, ["ekf"], 2, seed=5, duration=3.0, jobs=1),
          run_monte_carlo(sc, ["ekf"], 2, seed=5, duration=3.0, scheduler=address))


def test_runs_grouped_into_dask_tasks_come_back_in_seed_order(cluster, monkeypatch):
    # Several runs a task on the per-run path; 5 runs on 2 workers at one task a
    # worker are groups of 3 and 2, and every run is the local one, in its place
    import beacon_sim.evaluation.montecarlo.sweep as mc

    monkeypatch.setattr(mc, "TASKS_PER_DASK_WORKER", 1)
    seen = []
    monkeypatch.setattr(mc, "on_dask", lambda s, fn, tasks, done, **kw: (
        seen.append([len(t) for t in tasks]), on_dask(s, fn, tasks, done, **kw)))
    sc = load_scenario("default")
    local = run_monte_carlo(sc, ["ekf"], 5, seed=2, duration=2.0, jobs=1, batch=False)
    dask = run_monte_carlo(sc, ["ekf"], 5, seed=2, duration=2.0, batch=False, scheduler=cluster)
    assert seen == [[3, 2]]
    assert [r.seed for r in dask] == [2, 3, 4, 5, 6] and [r.index for r in dask] == list(range(5))
    _same(local, dask)


def test_eval_cli_on_dask_prints_the_local_table(cluster, capsys):
    argv = ["eval", "default", "--runs", "2", "--duration", "3", "--filter", "ekf", "--filter",
            f"{ATTACKS / 'honest.py'}:MyEkf", "--sandbox", "process", "--json"]
    assert main([*argv, "--jobs", "1"]) == 0
    local = json.loads(capsys.readouterr().out)["filters"]
    assert main([*argv, "--scheduler", cluster.scheduler.address]) == 0
    dask = json.loads(capsys.readouterr().out)["filters"]
    for name in ("ekf", "MyEkf"):
        for key in ("pos_rmse_m", "heading_rmse_rad", "anees", "rmse_over_pcrb", "failed_runs"):
            assert local[name][key] == dask[name][key], (name, key)


def test_dask_hosts_a_file_filter_with_the_local_figures(cluster):
    specs = [f"{ATTACKS / 'honest.py'}:MyEkf", "ekf"]
    sc = load_scenario("default")
    local = run_monte_carlo_isolated(sc, specs, 2, seed=1, duration=3.0, jobs=1, sandbox="process")
    dask = run_monte_carlo_isolated(sc, specs, 2, seed=1, duration=3.0, sandbox="process",
                                    scheduler=cluster)
    _same(local, dask)
    assert all(r.filters["MyEkf"].failed is None for r in dask)


def test_a_lost_worker_is_one_cluster_error_not_a_traceback():
    import dask
    from dask.distributed import Client, LocalCluster

    from beacon_sim.evaluation.montecarlo import ClusterError, on_dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                         dashboard_address=":0") as c, Client(c) as client:
        got: list = []
        with pytest.raises(ClusterError, match=r"task 1 of 1 was lost \(KilledWorker"):
            on_dask(client, os._exit, [3], lambda i, r: got.append(r))
        assert got == []


def test_eval_cli_bad_scheduler_is_one_line_exit_2(capsys):
    assert main(["eval", "default", "--runs", "1", "--duration", "1", "--scheduler", "nowhere"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--scheduler nowhere" in err[0] and "Traceback" not in err[0]


@pytest.fixture
def probe_package(tmp_path, monkeypatch):
    pkg = tmp_path / "lib" / "probepkg"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "probe.py").write_text(PROBE)
    monkeypatch.syspath_prepend(str(tmp_path / "lib"))
    monkeypatch.setenv("PROBE_GRADER_PID", str(os.getpid()))

    def forget() -> None:  # an import by ``--sandbox none`` must not outlive its folder
        for name in [m for m in sys.modules if m == "probepkg" or m.startswith("probepkg.")]:
            del sys.modules[name]

    forget()
    yield "probepkg.probe:Probe"
    forget()


@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_eval_hosts_a_module_filter_in_a_child(capsys, probe_package, sandbox):
    from beacon_sim.hosting.containment import bwrap_problem

    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(bwrap_problem() or "")
    code = main(["eval", "default", "--runs", "2", "--duration", "2", "--json", "--filter",
                 probe_package, "--filter", "probe_ekf=ekf", "--sandbox", sandbox])
    assert code == 0
    got = json.loads(capsys.readouterr().out)["filters"]
    # In the grader's process (pid) or with the truth reachable its covariance would be
    # inflated by 10 or 100: the ANEES would collapse far below the ekf's.
    assert got["Probe"]["failed_runs"] == 0
    assert got["Probe"]["pos_rmse_m"] == got["probe_ekf"]["pos_rmse_m"]
    assert got["Probe"]["anees"] == pytest.approx(got["probe_ekf"]["anees"], rel=1e-9)


def test_eval_hosts_an_entry_point_filter_in_a_child(capsys, probe_package, tmp_path):
    """An installed package's entry point (group ``beacon_sim.filters``) is hosted as its
    module ``pkg.mod:Class`` is."""
    dist = tmp_path / "lib" / "probe_dist-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: probe-dist\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[beacon_sim.filters]\nprobe_ep = probepkg.probe:Probe\n")
    code = main(["eval", "default", "--runs", "1", "--duration", "2", "--json", "--filter",
                 "probe_ep", "--filter", "ekf", "--sandbox", "process"])
    assert code == 0
    got = json.loads(capsys.readouterr().out)["filters"]
    assert got["probe_ep"]["failed_runs"] == 0
    assert got["probe_ep"]["anees"] == pytest.approx(got["ekf"]["anees"], rel=1e-9)


def test_eval_in_process_would_be_seen_by_the_probe(capsys, probe_package):
    """The probe's own control: in the grader's process (``--sandbox none``) it is seen."""
    code = main(["eval", "default", "--runs", "1", "--duration", "2", "--json", "--filter",
                 probe_package, "--filter", "ekf", "--sandbox", "none"])
    assert code == 0
    got = json.loads(capsys.readouterr().out)["filters"]
    assert got["Probe"]["anees"] < 0.5 * got["ekf"]["anees"]


def test_check_hosts_a_module_filter_in_a_child(capsys, probe_package, tmp_path):
    """A module filter that raises where it can see the grader (its pid, or a Simulation
    through ``gc``) passes every check isolated, and fails "runs" in process (the control)."""
    strict = tmp_path / "lib" / "probepkg" / "strict.py"
    strict.write_text(PROBE.replace("return mean, cov + ",
                                    "if here or sims:\n            raise RuntimeError('seen')\n"
                                    "        return mean, cov + "))
    assert main(["check", "probepkg.strict:Probe", "--sandbox", "process"]) == 0
    out = capsys.readouterr().out
    assert "in a process of its own" in out and "13 of 13 checks passed" in out
    assert main(["check", "probepkg.strict:Probe", "--sandbox", "none"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  runs" in out and "RuntimeError" in out


def test_a_missing_module_is_one_line_exit_2(capsys):
    assert main(["eval", "default", "--runs", "1", "--duration", "1", "--filter",
                 "no_such_pkg_xyz.m:F"]) == 2
    assert "no_such_pkg_xyz" in capsys.readouterr().err


def test_the_lean_dask_settings_are_dasks_own_keys():
    # a key Dask does not know would be set silently and do nothing: each must be one of its
    # defaults (docs/performance.md)
    pytest.importorskip("dask.distributed")
    import dask

    from beacon_sim.evaluation.montecarlo import DASK_LEAN_CONFIG

    for key, value in DASK_LEAN_CONFIG.items():
        default = dask.config.get(key)  # KeyError if unknown
        assert type(default) is type(value) or isinstance(default, str), (key, default, value)
        with dask.config.set({key: value}):
            assert dask.config.get(key) == value


def _within(seconds, fn):
    """``fn()``'s exception (or None) and whether it returned within ``seconds``, run in a
    thread so that a hang fails the test instead of stalling it."""
    import threading

    got: list = []

    def call():
        try:
            fn()
            got.append(None)
        except BaseException as exc:  # handed to the test
            got.append(exc)

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(seconds)
    return (got[0] if got else None), not t.is_alive()


def test_no_worker_is_one_line_within_the_time_out(monkeypatch, capsys):
    """A scheduler with no worker: ``on_dask`` gives up after ``NO_WORKER_TIMEOUT_S`` with a
    one-line ClusterError, and ``eval --scheduler ADDRESS`` with one line and exit status 2,
    instead of waiting for ever (the bound is generous: only a hang can miss it)."""
    distributed = pytest.importorskip("dask.distributed")
    from beacon_sim.evaluation import cluster as cluster_module
    from beacon_sim.evaluation.montecarlo import ClusterError

    monkeypatch.setattr(cluster_module, "NO_WORKER_TIMEOUT_S", 1.0)
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as c, \
            distributed.Client(c) as client:
        exc, returned = _within(120.0, lambda: on_dask(client, abs, [1, 2], lambda i, r: None))
        assert returned, "on_dask still waits for a worker"
        assert isinstance(exc, ClusterError) and "\n" not in str(exc)
        assert str(exc).startswith("Dask: no worker at ") and "for 1 s" in str(exc)
        address = c.scheduler_address
        code: list = []
        exc, returned = _within(120.0, lambda: code.append(main(
            ["eval", "default", "--runs", "2", "--duration", "1", "--jobs", "1",
             "--scheduler", address])))
        assert returned and exc is None and code == [2]
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert len(err) == 1 and "no worker at" in err[0] and "Traceback" not in err[0]


def test_no_worker_left_mid_run_is_one_line_within_the_time_out(monkeypatch):
    """The last worker leaves with tasks pending (Dask would keep them for a worker that never
    comes): a one-line ClusterError, even with ``lost`` given (grading), within a generous bound."""
    import time as time_module

    distributed = pytest.importorskip("dask.distributed")
    from beacon_sim.evaluation import cluster as cluster_module
    from beacon_sim.evaluation.montecarlo import ClusterError

    monkeypatch.setattr(cluster_module, "NO_WORKER_TIMEOUT_S", 1.0)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as c, distributed.Client(c) as client:
        got: list = []

        def first_done(i, r):  # the first result in: the only worker goes away
            got.append(r)
            if len(got) == 1:
                c.scale(0)

        exc, returned = _within(120.0, lambda: on_dask(client, time_module.sleep, [0.0] + [0.5] * 20,
                                                       first_done, lost=lambda i, e: None))
        assert returned, "on_dask still waits for a worker"
        assert isinstance(exc, ClusterError) and "\n" not in str(exc) and "no worker at" in str(exc)
        assert len(got) < 21
