"""Updates linear in the readings: over LOW_RANK_ROWS readings the UKF's and the
batched Kalman updates never form S (m x m) and give the direct solve's results to 1e-9; the
shipped scenarios stay on the direct path (their bits unchanged)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from beacon_sim.core.resources import scenario_dir, shipped_scenarios
from beacon_sim.core.scenario import load_scenario, parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.gaussian import measurements as gm
from beacon_sim.filters.gaussian import ukf as ukf_mod
from beacon_sim.filters.gaussian.measurements import SlotPacker, kalman, kalman_update, kalman_update_low_rank
from beacon_sim.hosting.loading import build_filter


def many_beacons(n: int, kind: str = "range_bearing", seed: int = 0):
    data = tomllib.loads((scenario_dir() / "default.toml").read_text())
    rng = np.random.default_rng(seed)
    data["world"]["beacons"] = [{"id": i + 1, "x": float(x), "y": float(y)} for i, (x, y) in
                                enumerate(zip(rng.uniform(0.5, 11.5, n), rng.uniform(0.5, 7.5, n),
                                              strict=True))]
    s = data["sensors"][0]
    s["kind"], s["max_range"], s["detection_prob"], s["period"] = kind, 50.0, 0.8, data["dt"]
    if kind == "bearing":
        s.pop("range_std", None)
    data["events"] = []
    return parse_scenario(data, "test", name=f"many_{n}")


def test_the_shipped_scenarios_stay_on_the_direct_path():
    for name in shipped_scenarios():
        sc = load_scenario(name)
        if any(s.kind not in gm.KINDS and s.kind != "range_finder" for s in sc.sensors):
            continue   # weighed by the kind's record, never packed (BatchableFilter.batch_blocker)
        assert SlotPacker(sc.world, sc.model_sensors).M <= gm.LOW_RANK_ROWS, name


def _run(spec, sc, params, steps):
    f = build_filter(spec, sc, 0, params=params)
    out = []
    for st in steps:
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        out.append(f.estimate())
    return f, out


@pytest.mark.parametrize("kind, params", [("range_bearing", {}), ("bearing", {}),
                                          ("range_bearing", {"gate_chi2": 9.21}),
                                          ("bearing", {"scaled": False, "kappa": 1.0})])
def test_ukf_low_rank_update_equals_the_direct_solve(monkeypatch, kind, params):
    sc = many_beacons(40, kind)
    steps = Simulation(sc, 1).run(4.0)
    assert max(sum(len(m) for m in st.measurements) for st in steps) * (2 if kind != "bearing" else 1) \
        > gm.LOW_RANK_ROWS
    _, fast = _run("ukf", sc, params, steps)
    monkeypatch.setattr(ukf_mod, "LOW_RANK_ROWS", 10**9)
    _, direct = _run("ukf", sc, params, steps)
    for (m1, c1), (m2, c2) in zip(fast, direct, strict=True):
        d = np.abs(m1 - m2)
        d[2] = min(d[2], 2 * np.pi - d[2])
        assert d.max() < 1e-9 and np.abs(c1 - c2).max() < 1e-9


@pytest.mark.parametrize("joseph", [True, False])
def test_kalman_update_low_rank_equals_the_direct_one(joseph):
    rng = np.random.default_rng(4)
    R, m = 5, 60
    A = rng.normal(size=(R, 3, 3))
    P = A @ A.swapaxes(-1, -2) * 0.1 + 1e-3 * np.eye(3)
    mean = rng.normal(size=(R, 3))
    H = rng.normal(size=(R, m, 3))
    H[:, ::7] = 0.0                    # empty slots: zero rows
    nu = rng.normal(size=(R, m)) * 0.05
    nu[:, ::7] = 0.0
    r = rng.uniform(1e-4, 1e-2, size=(R, m))
    got = kalman_update_low_rank(mean, P, H, nu, r, joseph, True)
    gm_rows = kalman.LOW_RANK_ROWS          # the update reads it from its own module
    try:
        kalman.LOW_RANK_ROWS = 10**9
        want = kalman_update(mean, P, H, nu, r, joseph, True)
    finally:
        kalman.LOW_RANK_ROWS = gm_rows
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def test_batched_filters_with_many_slots_equal_the_per_run_filters():
    """As tests/evaluation/test_batched_eval.py, on a map whose slots take the low-rank updates."""
    sc = many_beacons(30)
    seeds = [2, 3, 5]
    sims = [Simulation(sc, s) for s in seeds]
    packer = SlotPacker(sc.world, sc.model_sensors)
    assert packer.M > gm.LOW_RANK_ROWS
    specs = [("ekf", {}), ("ukf", {}), ("kf", {})]
    scalar = [[build_filter(spec, sc, s, params=p) for s in seeds] for spec, p in specs]
    batched = [fs[0].batched(len(seeds)) for fs in scalar]
    worst = 0.0
    for _ in range(60):
        steps = [sim.step() for sim in sims]
        v = np.array([s.control.v for s in steps])
        w = np.array([s.control.omega for s in steps])
        st = packer.pack([s.measurements for s in steps])
        for fs, fb in zip(scalar, batched, strict=True):
            fb.predict(v, w, sc.dt)
            if st is not None:
                fb.update(st)
            for i, (f, step) in enumerate(zip(fs, steps, strict=True)):
                f.predict(step.control, step.dt)
                f.update(step.measurements)
                m, c = f.estimate()
                dm = np.abs(fb.mean[i] - m)
                dm[2] = min(dm[2], 2 * np.pi - dm[2])
                worst = max(worst, dm.max(), np.abs(fb.cov[i] - c).max())
    assert worst < 1e-9


def test_the_evaluations_nis_is_linear_and_the_same_above_the_threshold(monkeypatch):
    from beacon_sim.evaluation import metrics

    sc = many_beacons(40)
    sensors = {s.name: s for s in sc.model_sensors}
    steps = [st for st in Simulation(sc, 3).run(2.0) if st.measurements]
    f = build_filter("ekf", sc, 0)
    means, covs, fast = [], [], []
    for st in steps:
        f.predict(st.control, st.dt)
        m, c = f.estimate()
        means.append(m)
        covs.append(c)
        fast.append(metrics.nis(st.measurements, sensors, m, c, sc.world))
        f.update(st.measurements)
    assert max(dof for _, dof in fast) > gm.LOW_RANK_ROWS
    batch_fast = metrics.nis_batch([st.measurements for st in steps], np.array(means), np.array(covs),
                                   sensors, sc.world)
    monkeypatch.setattr(metrics, "LOW_RANK_ROWS", 10**9)
    for st, m, c, (value, dof) in zip(steps, means, covs, fast, strict=True):
        want = metrics.nis(st.measurements, sensors, m, c, sc.world)
        assert dof == want[1] and value == pytest.approx(want[0], rel=1e-9)
    batch_direct = metrics.nis_batch([st.measurements for st in steps], np.array(means), np.array(covs),
                                     sensors, sc.world)
    assert batch_fast[1] == batch_direct[1] and batch_fast[0] == pytest.approx(batch_direct[0], rel=1e-9)
