"""A sensor kind is a record (core/sensor_kind.py, core/sensor_kinds.py): a toy kind
registered here, and nowhere else, is declared by a scenario, simulated bit for bit, filtered
by the EKF, UKF, particle and grid filters, exported to .npz / .csv / .mcap, shown in the
window's panel and bounded by the Cramer-Rao bound.

The toy is a range-only sensor whose readings of one tick share a noise component (like
the clock error of a UWB or TDOA system): R is a full matrix,
``R = s^2 ((1 - rho) I + rho 1 1^T)``, so the record's design is held to correlated readings.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import replace

import numpy as np
import pytest
from mcap.reader import make_reader

from beacon_sim import api
from beacon_sim.core import portable_math as pm
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.sensor_kind import KindParam, MeasurementModel, SensorKind
from beacon_sim.core.sensor_kinds import KINDS, sensor_kind
from beacon_sim.core.sensors import SensorSpec, visible_beacons
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.evaluation.pcrb import bound_rmse, measurement_information, pcrb
from beacon_sim.io.export import load_export

TOY = "toy_range"


def toy_draw(spec: SensorSpec, pose: np.ndarray, world: World,
             rng: np.random.Generator) -> Measurement | None:
    """Ranges [m] to the beacons in view, each with its own noise plus one shared by all the
    tick's rows; fixed-size draws and portable maths (the same bits on every machine)."""
    n = len(world.beacons)
    u = rng.random(n)
    e = rng.standard_normal(n + 1)
    idx = np.flatnonzero(visible_beacons(spec, pose, world) & (u < spec.detection_prob))
    if idx.size == 0:
        return None
    d = world.beacon_xy[idx] - pose[:2]
    s, rho = spec.param("toy_std"), spec.param("toy_rho")
    z = pm.hypot(d[:, 0], d[:, 1]) + s * (math.sqrt(1.0 - rho) * e[1:][idx] + math.sqrt(rho) * e[0])
    return Measurement(spec.name, TOY, z[:, None], world.beacon_ids[idx])


class ToyRangeModel(MeasurementModel):
    """h = distance to each beacon, H = [-dx/r, -dy/r, 0], R with a shared component."""

    angles = (False,)

    def expected(self, spec, m, poses, world):
        b = world.beacon_positions(m.beacon_ids)
        return np.hypot(b[None, :, 0] - poses[:, 0:1], b[None, :, 1] - poses[:, 1:2])

    def jacobian(self, spec, m, pose, world):
        d = world.beacon_positions(m.beacon_ids) - pose[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        return np.column_stack([-d[:, 0] / r, -d[:, 1] / r, np.zeros(len(r))])

    def noise(self, spec, m):
        k = len(m)
        s2, rho = spec.param("toy_std") ** 2, spec.param("toy_rho")
        return s2 * ((1.0 - rho) * np.eye(k) + rho * np.ones((k, k)))


RECORD = SensorKind(TOY, ("toy_range_m",), carries_ids=True, draw=toy_draw, model=ToyRangeModel(),
                    params=(KindParam("toy_std", 0.1, 1e-6, 10.0, "noise of one range [m]"),
                            KindParam("toy_rho", 0.5, 0.0, 0.95, "share of the noise all rows have")),
                    label="toy range")

SCENARIO = """
name = "toy"
dt = 0.05
duration = 20.0
seed = 7
default_filters = ["ekf"]

[world]
bounds = [0.0, 0.0, 8.0, 6.0]
beacons = [
  { id = 1, x = 1.0, y = 1.0 },
  { id = 2, x = 7.0, y = 1.0 },
  { id = 3, x = 7.0, y = 5.0 },
  { id = 4, x = 1.0, y = 5.0 },
]

[robot]
initial_pose = [2.0, 2.0, 0.0]
motion_noise = { v_std = 0.03, v_frac = 0.3, omega_std = 0.15, omega_frac = 0.1 }

[[sensors]]
name = "uwb"
kind = "toy_range"
period = 0.1
max_range = 6.0
toy_std = {std}
toy_rho = {rho}

[driver]
kind = "waypoints"
points = [[6.0, 2.0], [6.0, 4.5], [2.0, 4.5], [2.0, 2.0]]
speed = 0.4

[initial_belief]
std = [0.1, 0.1, 0.05]
"""


@pytest.fixture
def toy(monkeypatch):
    """The toy kind, registered for this test only (as a plugin would register it)."""
    monkeypatch.setitem(KINDS, TOY, RECORD)
    return RECORD


def write_scenario(tmp_path, std="0.08", rho="0.5"):
    path = tmp_path / "toy.toml"
    path.write_text(textwrap.dedent(SCENARIO).replace("{std}", std).replace("{rho}", rho), encoding="utf-8")
    return path


def test_a_scenario_declares_the_toy_kind_with_its_own_keys(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path))
    spec = sc.sensors[0]
    assert spec.kind == TOY and sensor_kind(TOY) is RECORD
    assert (spec.param("toy_std"), spec.param("toy_rho")) == (0.08, 0.5)
    with pytest.raises(ScenarioError) as err:
        load_scenario(write_scenario(tmp_path, rho="1.5"))
    msg = str(err.value)
    assert "toy.toml" in msg and "sensors[0].toy_rho" in msg and "0.95" in msg and "\n" not in msg


def test_without_its_record_the_kind_and_its_keys_are_refused(tmp_path):
    with pytest.raises(ScenarioError, match=r"toy\.toml: unknown key 'sensors\[0\]\.toy_std'"):
        load_scenario(write_scenario(tmp_path))
    path = write_scenario(tmp_path)
    path.write_text("\n".join(ln for ln in path.read_text().splitlines() if not ln.startswith("toy_")))
    with pytest.raises(ScenarioError, match=r"sensors\[0\]\.kind.*range_bearing"):
        load_scenario(path)


def test_the_toy_kind_is_simulated_bit_for_bit_with_its_correlation(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path, std="0.2", rho="0.6"))
    runs = []
    for _ in range(2):
        sim = Simulation(sc)
        rows = []
        for _ in range(1200):
            st = sim.step()
            rows += [(m, st.true_pose) for m in st.measurements]
        runs.append((sim.truth_checksum, sim.readings_checksum, rows))
    assert runs[0][:2] == runs[1][:2]
    rows = runs[0][2]
    assert len(rows) > 500 and all(m.kind == TOY and m.z.shape[1] == 1 for m, _ in rows)
    # the errors: mean 0, variance s^2, and the rows of one tick correlated by rho
    errs, pairs = [], []
    for m, pose in rows:
        e = m.z[:, 0] - np.hypot(*(sc.world.beacon_positions(m.beacon_ids) - pose[:2]).T)
        errs += e.tolist()
        if len(e) >= 2:
            pairs.append(e[:2])
    errs_a, pairs_a = np.array(errs), np.array(pairs)
    assert abs(errs_a.mean()) < 0.04 and 0.85 < errs_a.std() / 0.2 < 1.15
    rho = np.corrcoef(pairs_a.T)[0, 1]
    assert 0.45 < rho < 0.75, rho


def test_the_model_is_its_maths(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path))
    spec, world, model = sc.sensors[0], sc.world, RECORD.model
    m = Measurement("uwb", TOY, np.array([[1.7], [3.1], [4.4]]), np.array([1, 2, 4]))
    pose = np.array([2.3, 1.9, 0.4])
    H = model.jacobian(spec, m, pose, world)
    eps = 1e-6
    fd = np.column_stack([(model.expected(spec, m, (pose + eps * e)[None], world)[0]
                           - model.expected(spec, m, (pose - eps * e)[None], world)[0]) / (2 * eps)
                          for e in np.eye(3)])
    assert np.allclose(H, fd, atol=1e-7)
    R = model.noise(spec, m)
    assert R[0, 1] == pytest.approx(0.5 * 0.08**2) and np.all(np.linalg.eigvalsh(R) > 0)
    poses = pose + np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.0], [-1.0, 0.5, 1.0]])
    nu = m.z[:, 0] - model.expected(spec, m, poses, world)
    want = -0.5 * np.einsum("ni,ij,nj->n", nu, np.linalg.inv(R), nu)
    assert np.allclose(model.loglik(spec, m, poses, world), want)


def test_the_ekf_ukf_pf_and_grid_filter_use_the_toy_kind(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path))
    names = ["ekf", "ukf", "pf", "histogram", "dead_reckoning"]
    run = api.run(sc, names, duration=20.0, params={"pf": {"n_particles": 1000}})
    metrics = run.metrics()["filters"]
    rmse = {n: metrics[n]["pos_rmse_m"] for n in names}
    assert all(rmse[n] is not None and math.isfinite(rmse[n]) for n in names), rmse
    for n in ("ekf", "ukf", "pf"):
        assert rmse[n] < 0.2 * rmse["dead_reckoning"] and rmse[n] < 0.05, rmse
    # the grid: within its 0.2 m cells (a cell's centre is 0.08 m RMS from a uniform point)
    assert rmse["histogram"] < 0.5 * rmse["dead_reckoning"] and rmse["histogram"] < 0.13, rmse
    assert metrics["ekf"]["anees"] < 6.0   # an honest covariance with the full R


def test_the_toy_kind_is_exported_to_npz_csv_and_mcap(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path))
    run = api.run(sc, ["ekf"], duration=3.0)
    readings = run.readings
    got = readings["toy_range_m"]
    assert (readings["kind"] == TOY).all() and np.isfinite(got).all() and len(got) > 20
    assert np.isnan(readings["range_m"]).all()           # its own column, not another kind's
    for suffix in (".npz", ".csv"):
        run.export(tmp_path / f"run{suffix}")
        back = load_export(tmp_path / f"run{suffix}")["readings"]
        assert np.array_equal(back["toy_range_m"], got) and np.array_equal(back["beacon_id"],
                                                                           readings["beacon_id"])
    (path,) = run.export(tmp_path / "run.mcap")
    with open(path, "rb") as f:
        topics = [ch.topic for _, ch, _ in make_reader(f).iter_messages()]
    assert topics.count("/readings") >= 20   # a ray to the beacon of each reading


def test_the_panel_shows_the_toy_kind(toy, tmp_path, monkeypatch):
    import pygame

    from beacon_sim.app.main import App
    from beacon_sim.runs.live import Session

    app = App(Session(load_scenario(write_scenario(tmp_path)), ["ekf", "pf"], 3), (1000, 700), scripted=True)
    try:
        app.run(app.frames + 30)
        drawn: list[str] = []
        real = app.hud._blit

        def blit(surf, text, font, colour, at, bg=None):
            drawn.append(text)
            return real(surf, text, font, colour, at, bg)

        monkeypatch.setattr(app.hud, "_blit", blit)
        app.run(app.frames + 1)
        monkeypatch.setattr(app.hud, "_blit", real)
        line = next(t for t in drawn if t.startswith("toy range (uwb): "))
        n = sum(len(m) for m in app.session.readings() if m.kind == TOY)
        assert line == f"toy range (uwb): {n} reading{'s' if n != 1 else ''}"
        assert any(t.startswith("beacons in view") for t in drawn)
        pygame.image.save(app.screen, str(tmp_path / "toy_panel.png"))
    finally:
        app.close()


def test_the_pcrb_bounds_the_toy_kind(toy, tmp_path):
    sc = load_scenario(write_scenario(tmp_path))
    spec, world = sc.sensors[0], sc.world
    pose = np.array([[2.0, 2.0, 0.3]])
    ids = world.beacon_ids[visible_beacons(spec, pose[0], world)]
    m = Measurement("uwb", TOY, np.zeros((len(ids), 1)), ids)
    H = RECORD.model.jacobian(spec, m, pose[0], world)
    want = H.T @ np.linalg.solve(RECORD.model.noise(spec, m), H)
    assert np.allclose(measurement_information(spec, pose, world.beacon_xy, world)[0], want)
    # Monte Carlo: the EKF's squared error over seeds stays above the bound on those paths
    errs, bounds = [], []
    for seed in range(8):
        run = api.run(sc, ["ekf"], seed=seed, duration=10.0)
        err = run.errors("ekf")
        errs.append(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2))
        P = pcrb(sc, run.truth[None], run.controls[None])
        bounds.append(bound_rmse(P)[0] ** 2)
        if seed == 0:
            blind = pcrb(replace(sc, sensors=()), run.truth[None], run.controls[None])
            assert bound_rmse(P)[0] < 0.5 * bound_rmse(blind)[0]   # the readings inform
    assert math.sqrt(np.mean(errs)) >= 0.9 * math.sqrt(np.mean(bounds)), (errs, bounds)
