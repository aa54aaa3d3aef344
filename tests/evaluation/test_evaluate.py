"""``beacon_sim.evaluate``: Monte Carlo runs as tidy per-tick and per-run tables, with seed
and scenario columns and units in every name; the numbers are those of single runs and of
eval's figures, and seaborn draws error bands from the per-tick frame with no reshaping."""

from __future__ import annotations

import numpy as np
import pytest

import beacon_sim as bs
from beacon_sim.core.angles import wrap
from beacon_sim.evaluation.mc_tables import RUN_COLUMNS, TICK_COLUMNS

RUNS, SECONDS = 3, 6.0


@pytest.fixture(scope="module")
def ev():
    return bs.evaluate("default", ["ekf", "dead_reckoning"], runs=RUNS, seed=5, duration=SECONDS)


def test_tables_are_tidy(ev):
    ticks, runs = ev.columns("ticks"), ev.columns("runs")
    assert tuple(ticks) == TICK_COLUMNS and tuple(runs) == RUN_COLUMNS
    T = round(SECONDS / ev.scenario.dt)
    assert {len(v) for v in ticks.values()} == {2 * RUNS * T}
    assert {len(v) for v in runs.values()} == {2 * RUNS}
    assert set(ticks["seed"]) == {5, 6, 7} and set(ticks["scenario"]) == {"default"}
    assert sorted(set(runs["filter"])) == ["dead_reckoning", "ekf"]
    units = ("_m", "_rad", "_s", "_m2", "_rad2", "_step")
    plain = {"scenario", "seed", "run", "filter", "tick", "nees", "anees", "in_model", "failed",
             "failed_tick", "ticks"}
    assert all(c.endswith(units) or c in plain for c in (*ticks, *runs))
    with pytest.raises(bs.UsageError, match="expected one of ticks, runs"):
        ev.columns("estimates")


def test_each_row_is_the_single_run_of_its_seed(ev):
    ticks = ev.columns("ticks")
    for seed in (5, 7):
        r = bs.run("default", ["ekf", "dead_reckoning"], seed=seed, duration=SECONDS)
        for name in ("ekf", "dead_reckoning"):
            rows = (ticks["seed"] == seed) & (ticks["filter"] == name)
            err = r.estimates[name] - r.truth[1:]
            err[:, 2] = wrap(err[:, 2])
            np.testing.assert_allclose(ticks["err_x_m"][rows], err[:, 0], atol=1e-9)
            np.testing.assert_allclose(ticks["err_theta_rad"][rows], err[:, 2], atol=1e-9)
            cov = r.covariances[name]
            np.testing.assert_allclose(ticks["sigma_y_m"][rows], np.sqrt(cov[:, 1, 1]), rtol=1e-9)
            nees = np.einsum("ti,tij,tj->t", err, np.linalg.inv(cov), err)
            np.testing.assert_allclose(ticks["nees"][rows], nees, rtol=1e-6)
            np.testing.assert_array_equal(ticks["time_s"][rows], r.time[1:])


def test_per_run_figures_follow_from_the_ticks(ev):
    ticks, runs = ev.columns("ticks"), ev.columns("runs")
    for i in range(len(runs["filter"])):
        rows = (ticks["seed"] == runs["seed"][i]) & (ticks["filter"] == runs["filter"][i]) & ticks["in_model"]
        e = np.column_stack([ticks["err_x_m"][rows], ticks["err_y_m"][rows]])
        assert runs["pos_rmse_m"][i] == pytest.approx(np.sqrt(np.mean(np.sum(e * e, axis=1))), rel=1e-12)
        assert runs["anees"][i] == pytest.approx(np.mean(ticks["nees"][rows]), rel=1e-12)
        assert runs["failed"][i] == "" and runs["failed_tick"][i] == -1
    # the PCRB is below the EKF's own sigma on average (no unbiased estimator beats it)
    ekf = ticks["filter"] == "ekf"
    assert np.mean(ticks["pcrb_sigma_x_m"][ekf]) <= np.mean(ticks["sigma_x_m"][ekf])


def test_seaborn_draws_bands_from_the_frame_as_it_is(ev):
    import matplotlib

    matplotlib.use("Agg")
    sns = pytest.importorskip("seaborn")  # a third-party plotting library, not the project
    import matplotlib.pyplot as plt

    df = ev.to_frame("ticks")
    ax = sns.lineplot(df, x="time_s", y="err_pos_m", hue="filter", errorbar=("pi", 90))
    assert len(ax.lines) >= 2 and len(ax.collections) == 2  # a mean line and a band per filter
    plt.close("all")
    frames = ev.to_pandas()
    assert set(frames) == {"ticks", "runs"} and len(frames["runs"]) == 2 * RUNS
