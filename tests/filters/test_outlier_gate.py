"""Outliers in simulation: when a scenario declares them, the EKF and UKF gate
by default (the chi-square 99 % point for the readings' degrees of freedom, kept in the
filters' parameters), the batched forms gate as the per-run ones, and the particle
filter's mixture and lost test allow for them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.summary import Thresholds, evaluate
from beacon_sim.filters.gaussian import ukf
from beacon_sim.filters.gaussian.measurements import SlotPacker, nis
from beacon_sim.hosting.loading import build_filter


def with_outliers(name: str, rate: float):
    sc = load_scenario(name)
    return replace(sc, sensors=tuple(replace(s, outlier_rate=rate) for s in sc.sensors),
                   model_sensors=tuple(replace(s, outlier_rate=rate) for s in sc.model_sensors))


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_gate_default_follows_the_declared_outliers(name):
    clean = build_filter(name, load_scenario("default"), 0)
    assert clean.params["gate_chi2"] == 0.0 and clean.gate == 0.0
    noisy = build_filter(name, with_outliers("default", 0.2), 0)
    want = chi2_quantile(0.99, 2)                     # range-bearing: 2 dof, 9.21
    assert noisy.params["gate_chi2"] == pytest.approx(want) and noisy.gate == pytest.approx(want)
    assert abs(want - 9.21) < 0.01
    # a given value (a --set, a recording's parameters) is kept, 0 included
    off = build_filter(name, with_outliers("default", 0.2), 0, params={"gate_chi2": 0.0})
    assert off.gate == 0.0 and off.params["gate_chi2"] == 0.0
    bearing = with_outliers("krejsa_bearing_only", 0.1)
    assert build_filter(name, bearing, 0).gate == pytest.approx(chi2_quantile(0.99, 1))


@pytest.mark.parametrize("name, cls", [("ekf", "gaussian.ekf:ExtendedKalmanFilter"),
                                       ("ukf", "gaussian.ukf:UnscentedKalmanFilter")])
def test_a_subclass_that_declares_its_own_gate_keeps_it(name, cls, tmp_path):
    """A student's subclass with ``defaults = {'gate_chi2': 12.0}`` keeps that gate, with and
    without declared outliers: the automatic gate fills in only when nobody chose one (it
    used to overwrite the class's choice, so every such student was graded gate-less)."""
    module, klass = cls.split(":")
    f = tmp_path / "tuned.py"
    f.write_text(f"from beacon_sim.filters.{module} import {klass}\n\n\n"
                 f"class Tuned({klass}):\n"
                 f"    defaults = {{**{klass}.defaults, 'gate_chi2': 12.0}}\n")
    for sc, auto_gate in ((load_scenario("default"), 0.0),
                          (with_outliers("default", 0.2), chi2_quantile(0.99, 2))):
        assert build_filter(name, sc, 0).gate == pytest.approx(auto_gate)
        flt = build_filter(f"{f}:Tuned", sc, 0)
        assert flt.gate == 12.0 and flt.params["gate_chi2"] == 12.0


def test_filters_near_the_bound_with_declared_outliers():
    # 20 % of the readings replaced by random ones and the filters told so: without the
    # gate the EKF reached 8.75x the bound (ANEES 906) and the PF 12.7x; now near 1, but for
    # the PF's rare hard run: on the keyed filter streams one of these three runs
    # ends at 0.38 m (the others 0.08 m), 2.2x the bound pooled; seeds 43-54 (12 more runs)
    # gave 0.77-1.26x. So the PF's bound here is 2.5x, still five times below the ungated 12.7x.
    sc = with_outliers("default", 0.2)
    runs = run_monte_carlo(sc, ["ekf", "pf"], 3, seed=40, duration=60.0, jobs=1)
    meta, _ = evaluate(sc, runs, Thresholds())
    ekf, pf = meta["filters"]["ekf"], meta["filters"]["pf"]
    assert ekf["rmse_over_pcrb"] <= 1.3, ekf["rmse_over_pcrb"]
    assert pf["rmse_over_pcrb"] <= 2.5, pf["rmse_over_pcrb"]
    assert ekf["anees"] < 6 and pf["anees"] < 6


@pytest.mark.parametrize("scenario, rate", [("default", 0.2), ("krejsa_bearing_only", 0.15),
                                            ("ulps_circle", 0.1)])
@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_batched_gate_equals_the_per_run_gate(name, scenario, rate):
    """The batched EKF and UKF gate as their per-run forms do: every step's mean and
    covariance to 1e-9, the same readings dropped, and (the EKF's own NIS) the NIS of all
    readings (gated or not)."""
    worst, rejected, batched_rejected = _step_batched_and_per_run(name, scenario, rate)
    assert worst < 1e-9
    assert rejected == batched_rejected
    assert sum(rejected) > 0                            # the gate did reject outliers


def test_batched_ukf_gate_on_the_low_rank_update(monkeypatch):
    """The batched UKF's gate on its update linear in the readings (over LOW_RANK_ROWS
    slots; lowered here so `default`'s 14 slots take that path) equals the per-run UKF."""
    monkeypatch.setattr(ukf, "LOW_RANK_ROWS", 4)
    worst, rejected, batched_rejected = _step_batched_and_per_run("ukf", "default", 0.2)
    assert worst < 1e-9
    assert rejected == batched_rejected and sum(rejected) > 0


def _step_batched_and_per_run(name, scenario, rate):
    """Runs seeds 4 and 9 of ``scenario`` with outliers for 20 s through the per-run filter
    and its batched form side by side; returns the largest difference of a mean or
    covariance entry over every step, and the readings each dropped (per run)."""
    sc = with_outliers(scenario, rate)
    seeds = [4, 9]
    sims = [Simulation(sc, s) for s in seeds]
    packer = SlotPacker(sc.world, sc.model_sensors)
    scalar = [build_filter(name, sc, s) for s in seeds]
    assert scalar[0].gate > 0 and scalar[0].batch_blocker is None
    fb = scalar[0].batched(len(seeds))
    assert fb.gate == scalar[0].gate
    worst = 0.0
    for _ in range(round(20.0 / sc.dt)):
        steps = [sim.step() for sim in sims]
        v = np.array([s.control.v for s in steps])
        w = np.array([s.control.omega for s in steps])
        st = packer.pack([s.measurements for s in steps])
        fb.predict(v, w, sc.dt)
        for f, step in zip(scalar, steps, strict=True):
            f.predict(step.control, step.dt)
        if st is not None:
            want_nis = nis(fb.mean, fb.cov, st)
            fb.update(st)
            if fb.own_nis:
                assert fb.last_nis == pytest.approx(want_nis, rel=1e-12)
        for i, (f, step) in enumerate(zip(scalar, steps, strict=True)):
            f.update(step.measurements)
            m, c = f.estimate()
            dm = np.abs(fb.mean[i] - m)
            dm[2] = min(dm[2], 2 * np.pi - dm[2])
            worst = max(worst, dm.max(), np.abs(fb.cov[i] - c).max())
    return worst, [f.rejected for f in scalar], fb.rejected.tolist()
