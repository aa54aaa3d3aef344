"""eval reduces each run as it ends (summary.Evaluation) with the figures the stacked
arrays give, bit for bit: checked here against the formulas on the stacked runs, whatever
order the runs end in; the parked per-step values (evaluation/spill.py) come back whole
with or without a temporary file; the bootstrap drawn in blocks is the one drawn at once."""

from __future__ import annotations

import io
import random

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation import intervals
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.montecarlo.sweep import batch_size
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.evaluation.spill import SpilledColumns
from beacon_sim.evaluation.summary import Evaluation, Thresholds, evaluate, model_mask


@pytest.fixture(scope="module")
def kidnap_runs():
    sc = load_scenario("krejsa_bearing_only")   # a kidnap at 30 s: steps left out of the bound
    return sc, run_monte_carlo(sc, ["ekf", "dead_reckoning"], 9, seed=11, duration=40, jobs=1,
                               progress=False)


def test_streamed_figures_are_the_stacked_formulas_bit_for_bit(kidnap_runs):
    sc, runs = kidnap_runs
    ev = Evaluation(sc)
    shuffled = list(runs)
    random.Random(3).shuffle(shuffled)
    for r in shuffled:   # in the order they end, not in seed order
        ev.add_any(r)
    meta, curves = ev.result()
    truths = np.stack([r.truth for r in runs])
    kid = np.stack([r.kidnapped for r in runs])
    P = pcrb(sc, truths, np.stack([r.controls for r in runs]), kid)
    keep = model_mask(sc, kid)
    assert 0 < keep.sum() < keep.size
    assert meta["pcrb"]["pos_rmse_m"] == float(np.sqrt(np.mean((P[..., 0, 0] + P[..., 1, 1])[keep])))
    assert meta["pcrb"]["steps_used"] == float(keep.mean())
    assert np.array_equal(curves["pcrb_pos_t"], np.sqrt(np.mean(P[..., 0, 0] + P[..., 1, 1], axis=0)))
    for name, row in meta["filters"].items():
        err = np.stack([r.filters[name].err for r in runs])
        nees = np.stack([r.filters[name].nees for r in runs])
        pos2 = err[..., 0] ** 2 + err[..., 1] ** 2
        mse = np.nanmean(err**2, axis=(0, 1))
        assert [row["mse_x"], row["mse_y"], row["mse_theta"]] == [float(v) for v in mse]
        assert row["anees"] == float(np.nanmean(nees))
        assert row["pos_rmse_modelled_m"] == float(np.sqrt(np.nanmean(pos2[keep])))
        assert np.array_equal(curves["filters"][name]["nees_t"], np.nanmean(nees, axis=0))
        assert np.array_equal(curves["filters"][name]["rmse_t"], np.sqrt(np.nanmean(pos2, axis=0)))
        assert [p["seed"] for p in row["per_run"]] == [r.seed for r in runs]
    assert meta["run_checksums"] == [r.truth_checksum for r in runs]


def test_a_list_and_a_stream_give_the_same_document(kidnap_runs):
    sc, runs = kidnap_runs
    ev = Evaluation(sc, Thresholds())
    for r in reversed(runs):
        ev.add_any(r)
    assert repr(ev.result()[0]) == repr(evaluate(sc, runs)[0])


def test_runs_not_kept_are_each_handed_over_once_in_batches():
    sc = load_scenario("default")
    n = batch_size(round(2.0 / sc.dt)) + 3   # two batches
    seen = []
    out = run_monte_carlo(sc, ["ekf"], n, seed=4, duration=2.0, jobs=1, progress=False,
                          on_run=lambda r: seen.append(r.index), keep_runs=False)
    assert out == [] and sorted(seen) == list(range(n))


def test_spilled_columns_come_back_whole_with_or_without_a_temporary_file(monkeypatch):
    rng = np.random.default_rng(5)
    parts = [rng.standard_normal(k) for k in (3, 0, 17, 1)]
    cols = SpilledColumns()
    for p in parts:
        cols.append("a", p)
    assert np.array_equal(cols.read("a"), np.concatenate(parts)) and cols.size("a") == 21

    class FullDisk(io.BytesIO):   # takes one write, then the disk is full
        writes = 0

        def write(self, b):
            FullDisk.writes += 1
            if FullDisk.writes > 1:
                super().write(bytes(b)[:5])   # a partial write before the error
                raise OSError(28, "No space left on device")
            return super().write(b)

    monkeypatch.setattr("beacon_sim.evaluation.spill.tempfile.TemporaryFile", lambda **_: FullDisk())
    full = SpilledColumns()
    for p in parts:
        full.append("a", p)
    assert np.array_equal(full.read("a"), np.concatenate(parts))
    cols.close()
    full.close()


@pytest.mark.parametrize("n", [2, 7, 150])
def test_the_bootstrap_in_blocks_is_the_bootstrap_drawn_at_once(n):
    rng = np.random.default_rng(n)
    num, den = rng.exponential(size=n), rng.exponential(size=n) + 0.1
    idx = np.random.default_rng(intervals.SEED).integers(0, n, size=(intervals.REPLICATES, n))
    v = num[idx].sum(axis=1) / den[idx].sum(axis=1)
    a = (1 - intervals.LEVEL) / 2
    want = [float(np.percentile(v, 100 * a, method="lower")),
            float(np.percentile(v, 100 * (1 - a), method="higher"))]
    assert intervals.ratio_of_sums(num, den) == want
