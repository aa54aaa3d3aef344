"""The distance kinds (core/range_kind.py, core/tdoa_kind.py, core/ceiling_beacons.py):
their maths against finite differences and Monte Carlo, the simulation's draws, the four
filters updating on them through the record's model, the Cramer-Rao bound (the figures of
docs/distance_beacons.md reproduced by the program's own bound) and hostile scenarios."""

from __future__ import annotations

import math
import textwrap
from dataclasses import replace

import numpy as np
import pytest

from beacon_sim import api
from beacon_sim.cli.main import main
from beacon_sim.core.ceiling_beacons import covered_mask
from beacon_sim.core.range_kind import RANGE
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.sensor_kinds import sensor_kind
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.tdoa_kind import TDOA, difference_cov
from beacon_sim.core.types import Beacon, Measurement
from beacon_sim.core.world import World
from beacon_sim.evaluation.pcrb import bound_rmse, measurement_information, pcrb

SQUARE = World((-2.0, -2.0, 6.0, 6.0), tuple(Beacon(i + 1, x, y) for i, (x, y) in
                                               enumerate([(0, 0), (1, 0), (0, 1), (1, 1)])))

SCENARIO = """
name = "dist"
dt = 0.1
duration = 20.0
seed = 3
default_filters = ["ekf"]

[world]
bounds = [-2.0, -2.0, 6.0, 6.0]
beacons = [
  { id = 1, x = 0.0, y = 0.0 },
  { id = 2, x = 1.0, y = 0.0 },
  { id = 3, x = 0.0, y = 1.0 },
  { id = 4, x = 1.0, y = 1.0 },
]

[robot]
initial_pose = [0.5, -0.5, 0.0]
motion_noise = { v_std = 0.05, v_frac = 0.3, omega_std = 0.3 }

[[sensors]]
name = "d"
kind = "KIND"
period = 0.2
beacon_height = 2.0
range_std = 0.02
EXTRA

[driver]
kind = "constant"
v = 0.25
omega = 0.25

[initial_belief]
std = [0.05, 0.05, 0.05]
"""


def write(tmp_path, kind="tdoa", extra="", beacons=None, name="dist.toml"):
    text = textwrap.dedent(SCENARIO).replace("KIND", kind).replace("EXTRA", extra)
    if beacons is not None:
        start = text.index("beacons = [")
        end = text.index("]\n\n[robot]")
        text = text[:start] + f"beacons = [{beacons}" + text[end:]
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def spec_of(kind, **kw):
    """A sensor of ``kind`` over the 1 m square, 3.45 m up, sigma 1 cm (the lesson's)."""
    sc_params = {"range": (("nlos_rate", 0.0), ("nlos_mean", 0.3), ("cone_half_angle", 0.5 * math.pi)),
                 "tdoa": (("reference_id", -1.0), ("naive_differences", 0.0),
                          ("cone_half_angle", 0.5 * math.pi))}[kind]
    params = tuple((k, kw.pop(k, v)) for k, v in sc_params)
    from beacon_sim.core.sensors import SensorNoise, SensorSpec
    return SensorSpec("d", kind, beacon_height=kw.pop("height", 3.45),
                      noise=SensorNoise(range_std=kw.pop("std", 0.01)), params=params, **kw)


def fd_jacobian(model, spec, m, pose, world, eps=1e-6):
    return np.column_stack([(model.expected(spec, m, (pose + eps * e)[None], world)[0]
                             - model.expected(spec, m, (pose - eps * e)[None], world)[0]) / (2 * eps)
                            for e in np.eye(3)])


@pytest.mark.parametrize("pose", [[0.3, 0.4, 0.2], [4.0, 4.0, -3.0], [-1.5, 2.2, 3.1], [0.5, 0.5, 0.0]])
@pytest.mark.parametrize("height", [0.0, 3.45])
def test_jacobians_match_finite_differences(pose, height):
    pose = np.array(pose)
    for kind, ids in ((RANGE, [1, 2, 3, 4]), (TDOA, [3, 1, 2, 4])):
        spec = spec_of(kind.name, height=height)
        m = Measurement("d", kind.name, np.zeros((len(ids) - (kind is TDOA), 1)), np.array(ids))
        H = kind.model.jacobian(spec, m, pose, SQUARE)
        assert H.shape == (len(m), 3)
        assert np.allclose(H, fd_jacobian(kind.model, spec, m, pose, SQUARE), atol=1e-7)


def test_tdoa_expected_is_the_difference_to_the_first_id():
    spec = spec_of("tdoa")
    m = Measurement("d", "tdoa", np.zeros((3, 1)), np.array([2, 1, 3, 4]))
    p = np.array([0.2, 0.7, 0.0])
    r = np.sqrt(np.sum((SQUARE.beacon_xy - p[:2]) ** 2, axis=1) + 3.45**2)
    assert np.allclose(TDOA.model.expected(spec, m, p[None], SQUARE)[0], r[[0, 2, 3]] - r[1])


def test_tdoa_draws_have_the_correlated_covariance_and_the_strongest_reference():
    spec = spec_of("tdoa", std=0.05)
    pose = np.array([0.9, 0.8, 0.0])            # nearest beacon: id 4 at (1, 1)
    rng = np.random.default_rng(11)
    zs = []
    for _ in range(6000):
        m = TDOA.draw(spec, pose, SQUARE, rng)
        assert m is not None and m.beacon_ids.tolist() == [4, 1, 2, 3]
        zs.append(m.z[:, 0] - TDOA.model.expected(spec, m, pose[None], SQUARE)[0])
    C = np.cov(np.array(zs).T)
    want = difference_cov(3, 0.05)
    assert np.allclose(C, want, atol=0.12 * 0.05**2), C / 0.05**2
    # the off-diagonal is half the variance: the reference's error is in every row
    assert 0.4 < C[0, 1] / C[0, 0] < 0.6


def test_a_named_reference_is_used_and_a_tick_without_it_gives_nothing():
    spec = spec_of("tdoa", reference_id=2.0, detection_prob=0.5)
    rng = np.random.default_rng(5)
    got = [TDOA.draw(spec, np.array([0.2, 0.2, 0.0]), SQUARE, rng) for _ in range(400)]
    seen = [m for m in got if m is not None]
    assert seen and all(m.beacon_ids[0] == 2 and len(m) >= 1 for m in seen)
    assert 0.3 < len(seen) / len(got) < 0.5       # P(ref heard and one more) = 0.5 * 0.875


def test_the_cone_and_the_walls_hide_beacons(tmp_path):
    spec = spec_of("range", cone_half_angle=math.atan(1.0 / 3.45))  # 1 m radius on the floor
    mask = covered_mask(spec, np.array([[0.0, 0.0, 0.0], [3.0, 3.0, 0.0]]), SQUARE)
    assert mask[0].tolist() == [True, True, True, False] and not mask[1].any()
    text = write(tmp_path, "range").read_text().replace(
        "[world]\n", "[world]\nwalls = { resolution = 0.05, segments = [[[0.25, -1.5], [0.25, 0.3]]] }\n")
    path = tmp_path / "walls.toml"
    path.write_text(text)
    sc = load_scenario(path)
    pose = np.array([0.0, -1.0, 0.0])   # left of the wall: beacons 2 and 4 (x = 1) behind it
    assert covered_mask(sc.sensors[0], pose[None], sc.world)[0].tolist() == [True, False, True, False]


def test_range_draws_and_nlos_outliers():
    spec = spec_of("range", std=0.02, nlos_rate=0.2, nlos_mean=0.5)
    pose = np.array([2.0, 0.5, 0.0])
    rng = np.random.default_rng(3)
    errs = []
    for _ in range(3000):
        m = RANGE.draw(spec, pose, SQUARE, rng)
        assert m.beacon_ids.tolist() == [1, 2, 3, 4]
        errs.append(m.z[:, 0] - RANGE.model.expected(spec, m, pose[None], SQUARE)[0])
    e = np.concatenate(errs)
    far = e > 5 * 0.02
    assert 0.15 < far.mean() < 0.18               # 0.2 exp(-0.1 / 0.5) = 0.164 longer than 0.1 m
    assert 0.55 < e[far].mean() < 0.65            # memoryless: 0.1 + 0.5
    neg = e[e < 0]                                # never a longer path: the Gaussian's half
    assert 0.019 < math.sqrt(np.mean(neg**2)) < 0.021 and 0.38 < neg.size / e.size < 0.43
    # the mixture likelihood prefers the truth to a pose 10 cm nearer every beacon
    ids = np.arange(1, 5)
    h = RANGE.model.expected(spec, Measurement("d", "range", np.zeros((4, 1)), ids), pose[None], SQUARE)[0]
    m = Measurement("d", "range", (h + np.array([0.0, 0.0, 0.0, 0.8]))[:, None], ids)
    ll = RANGE.model.loglik(spec, m, np.array([pose, pose + np.array([0.1, 0.0, 0.0])]), SQUARE)
    assert ll[0] > ll[1]


def test_simulation_is_bit_for_bit_and_filters_update_on_both_kinds(tmp_path):
    for kind in ("range", "tdoa"):
        sc = load_scenario(write(tmp_path, kind))
        a, b = Simulation(sc), Simulation(sc)
        for _ in range(100):
            a.step(), b.step()
        assert (a.truth_checksum, a.readings_checksum) == (b.truth_checksum, b.readings_checksum)
        names = ["ekf", "ukf", "pf", "histogram", "dead_reckoning"]
        run = api.run(sc, names, duration=20.0, params={"pf": {"n_particles": 2000}})
        met = run.metrics()["filters"]
        rmse = {n: met[n]["pos_rmse_m"] for n in names}
        assert all(rmse[n] is not None and math.isfinite(rmse[n]) for n in names), (kind, rmse)
        for n in ("ekf", "ukf", "pf"):
            assert rmse[n] < 0.25 * rmse["dead_reckoning"] and rmse[n] < 0.06, (kind, rmse)
        assert rmse["histogram"] < 0.5 * rmse["dead_reckoning"], (kind, rmse)
        assert met["ekf"]["anees"] < 6.0, (kind, met["ekf"]["anees"])


def xy_bound_cm(kind, point, **kw):
    spec = spec_of(kind, **kw)
    J = measurement_information(spec, np.array([[*point, 0.0]]), SQUARE.beacon_xy, SQUARE)[0]
    return 100.0 * math.sqrt(np.trace(np.linalg.inv(J[:2, :2])))


@pytest.mark.parametrize("point, tdoa, toa", [((0.5, 0.5), 4.98, 4.98), ((2.0, 0.5), 5.90, 4.01),
                                              ((4.0, 4.0), 19.15, 6.11)])
def test_the_bound_reproduces_the_lessons_figures(point, tdoa, toa):
    """1 m square, 3.45 m up, 1 cm: sqrt of the trace of the x-y block of the CRB."""
    assert xy_bound_cm("tdoa", point) == pytest.approx(tdoa, rel=0.01)
    assert xy_bound_cm("range", point) == pytest.approx(toa, rel=0.01)
    # whichever beacon is the reference, the same bound (the true covariance)
    for ref in (1, 2, 3, 4):
        assert xy_bound_cm("tdoa", point, reference_id=float(ref)) == pytest.approx(tdoa, rel=0.01)


def test_the_bound_equals_the_differences_information_and_averages_detections():
    spec = spec_of("tdoa", reference_id=3.0)
    pose = np.array([2.0, 0.5, 0.0])
    m = Measurement("d", "tdoa", np.zeros((3, 1)), np.array([3, 1, 2, 4]))
    H = TDOA.model.jacobian(spec, m, pose, SQUARE)
    want = H.T @ np.linalg.solve(TDOA.model.noise(spec, m), H)
    assert np.allclose(TDOA.model.information(spec, pose[None], SQUARE)[0], want)
    # detection 0.7: the average over the detected subsets, by brute force
    p = 0.7
    spec7 = replace(spec, detection_prob=p)
    brute = np.zeros((3, 3))
    for bits in range(16):
        sub = [i for i in range(4) if bits >> i & 1]
        if 2 in sub and len(sub) >= 2:            # the reference (id 3, index 2) and one more
            ids = np.array([3] + [i + 1 for i in sub if i != 2])
            mm = Measurement("d", "tdoa", np.zeros((len(ids) - 1, 1)), ids)
            Hs = TDOA.model.jacobian(spec7, mm, pose, SQUARE)
            brute += p ** len(sub) * (1 - p) ** (4 - len(sub)) * Hs.T @ np.linalg.solve(
                TDOA.model.noise(spec7, mm), Hs)
    assert np.allclose(TDOA.model.information(spec7, pose[None], SQUARE)[0], brute)


def naive_claim(ref, point):
    """What the naive update claims at ``point`` with reference ``ref``: its covariance and
    the true covariance of the same (naive-weighted) estimate."""
    spec = spec_of("tdoa", naive_differences=1.0)
    ids = np.array([ref] + [i for i in (1, 2, 3, 4) if i != ref])
    m = Measurement("d", "tdoa", np.zeros((3, 1)), ids)
    D = TDOA.model.jacobian(spec, m, np.array([*point, 0.0]), SQUARE)[:, :2]
    Rn = TDOA.model.noise(spec, m)
    assert np.allclose(Rn, 2e-4 * np.eye(3))
    Pn = np.linalg.inv(D.T @ np.linalg.solve(Rn, D))
    K = Pn @ D.T @ np.linalg.inv(Rn)
    return Pn, K @ difference_cov(3, 0.01) @ K.T


@pytest.mark.parametrize("ref, claim", [(1, 17.13), (4, 17.13), (2, 26.15), (3, 26.15)])
def test_the_naive_updates_claim_depends_on_the_reference(ref, claim):
    Pn, _ = naive_claim(ref, (4.0, 4.0))
    assert 100 * math.sqrt(np.trace(Pn)) == pytest.approx(claim, rel=0.01)


@pytest.mark.parametrize("point", [(0.5, 0.5), (2.0, 0.5), (4.0, 4.0)])
def test_the_naive_update_is_overconfident_on_one_axis_and_underconfident_on_the_other(point):
    """Analytic: the true covariance over the claimed one has eigenvalues 0.5 and about
    1.83 (the one-fix NEES 2.33 against 2); Monte Carlo: one linearised fix per draw."""
    Pn, Pt = naive_claim(1, point)
    ev = np.sort(np.linalg.eigvals(np.linalg.solve(Pn, Pt)).real)
    assert ev[0] == pytest.approx(0.5, rel=0.01) and 1.78 < ev[1] < 1.87
    if point == (4.0, 4.0):
        assert np.trace(np.linalg.solve(Pn, Pt)) == pytest.approx(2.33, rel=0.01)
    rng = np.random.default_rng(2)
    e = rng.standard_normal((20000, 4)) * 0.01
    dz = (e[:, 1:] - e[:, :1])                                   # differences against beacon 1
    spec = spec_of("tdoa")
    m = Measurement("d", "tdoa", np.zeros((3, 1)), np.array([1, 2, 3, 4]))
    D = TDOA.model.jacobian(spec, m, np.array([*point, 0.0]), SQUARE)[:, :2]
    err_naive = dz @ (Pn @ D.T / 2e-4).T
    nees_naive = np.einsum("ni,ij,nj->n", err_naive, np.linalg.inv(Pn), err_naive).mean()
    Pc = np.linalg.inv(D.T @ np.linalg.solve(difference_cov(3, 0.01), D))
    err_c = dz @ (Pc @ D.T @ np.linalg.inv(difference_cov(3, 0.01))).T
    nees_c = np.einsum("ni,ij,nj->n", err_c, np.linalg.inv(Pc), err_c).mean()
    assert nees_naive == pytest.approx(np.trace(np.linalg.solve(Pn, Pt)), rel=0.04)
    assert nees_c == pytest.approx(2.0, rel=0.04)


def test_the_pcrb_bounds_both_kinds(tmp_path):
    for kind in ("range", "tdoa"):
        sc = load_scenario(write(tmp_path, kind))
        errs, bounds = [], []
        for seed in range(6):
            run = api.run(sc, ["ekf"], seed=seed, duration=10.0)
            err = run.errors("ekf")
            errs.append(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2))
            P = pcrb(sc, run.truth[None], run.controls[None])
            bounds.append(bound_rmse(P)[0] ** 2)
            if seed == 0:
                blind = pcrb(replace(sc, sensors=()), run.truth[None], run.controls[None])
                assert bound_rmse(P)[0] < 0.5 * bound_rmse(blind)[0]
        ratio = math.sqrt(np.mean(errs) / np.mean(bounds))
        assert 0.9 <= ratio < 1.6, (kind, ratio)


def test_the_filters_may_be_told_the_naive_update(tmp_path):
    path = write(tmp_path, "tdoa", extra="", name="n.toml")
    path.write_text(path.read_text() + '\n[model.sensors.d]\nnaive_differences = 1\n')
    sc = load_scenario(path)
    assert sc.sensors[0].param("naive_differences") == 0.0
    assert sc.model_sensors[0].param("naive_differences") == 1.0
    m = Measurement("d", "tdoa", np.zeros((3, 1)), np.array([1, 2, 3, 4]))
    assert np.allclose(TDOA.model.noise(sc.model_sensors[0], m), 2 * 0.02**2 * np.eye(3))



def beacon_rows(*xy):
    return "".join(f"{{ id = {i + 1}, x = {x}, y = {y} }},\n  " for i, (x, y) in enumerate(xy)) + "\n"


HOSTILE = [
    ("tdoa", "", beacon_rows((0.0, 0.0), (0.0, 0.0), (1.0, 1.0)), "beacons 1 and 2 at one point"),
    ("range", "", beacon_rows((2.0, 2.0), (2.0, 2.0), (2.0, 2.0)), "at one point"),
    ("tdoa", "", "{ id = 1, x = 2.0, y = 2.0 },\n", "at least 2"),
    ("tdoa", "reference_id = 9", None, "reference_id = 9: expected -1 (the strongest) or the ID"),
    ("tdoa", "reference_id = 1\nmax_range = 2.0", beacon_rows((30.0, 0.0), (1.0, 0.0)),
     "reference_id = 1: expected a beacon the receiver can hear"),
    ("tdoa", "reference_id = 2.5", None, "reference_id = 2.5"),
    ("range", "outlier_rate = 0.1", None, "outlier_rate = 0.1: expected 0"),
    ("tdoa", "naive_differences = 0.5", None, "naive_differences = 0.5: expected 0 or 1"),
]


@pytest.mark.parametrize("kind, extra, beacons, words", HOSTILE)
def test_hostile_scenarios_give_one_clear_line(tmp_path, capsys, kind, extra, beacons, words):
    path = write(tmp_path, kind, extra, beacons)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    msg = str(err.value)
    assert words in msg and "dist.toml" in msg and "\n" not in msg, msg
    assert main(["run", str(path), "--duration", "1"]) == 2
    out = capsys.readouterr()
    assert "Traceback" not in out.err and words in out.err
    # the Python API and the Gym environment: the same one line
    from beacon_sim.gym import BeaconEnv
    for front in (lambda: api.run(str(path), ["ekf"], duration=1.0), lambda: BeaconEnv(str(path), ["ekf"])):
        with pytest.raises(ScenarioError) as err:
            front()
        assert words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("old, new, words", [("beacon_height = 2.0", "beacon_height = nan", "beacon_height"),
                                             ("range_std = 0.02", "range_std = 0.0", "range_std")])
def test_nan_heights_and_zero_noise_are_refused(tmp_path, capsys, old, new, words):
    path = write(tmp_path, "tdoa")
    path.write_text(path.read_text().replace(old, new))
    with pytest.raises(ScenarioError, match=words):
        load_scenario(path)
    assert main(["run", str(path), "--duration", "1"]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_the_records_say_what_each_kind_is():
    assert sensor_kind("range") is RANGE and sensor_kind("tdoa") is TDOA
    assert RANGE.carries_ids and not TDOA.carries_ids
    assert RANGE.columns == ("range_m",) and TDOA.columns == ("range_diff_m",)


@pytest.mark.parametrize("scenario, column", [("ruiz_ulps", "range_diff_m"), ("uwb_room", "range_m")])
def test_distance_readings_are_exported_to_npz_csv_and_mcap(tmp_path, scenario, column):
    from mcap.reader import make_reader

    from beacon_sim.io.export import load_export

    run = api.run(scenario, ["ekf"], duration=3.0)
    got = run.readings[column]
    assert np.isfinite(got).all() and len(got) > 20
    other = "range_m" if column == "range_diff_m" else "range_diff_m"
    assert np.isnan(run.readings[other]).all()
    for suffix in (".npz", ".csv"):
        run.export(tmp_path / f"run{suffix}")
        back = load_export(tmp_path / f"run{suffix}")["readings"]
        assert np.array_equal(back[column], got)
    if column == "range_diff_m":   # the reference a row of its own, difference 0; every row its beacon
        ids = run.readings["beacon_id"]
        assert (ids > 0).all() and np.sum(got == 0.0) == len(got) // 4
        m = Simulation(load_scenario(scenario)).step().measurements[0]   # the same first tick
        tick1 = run.readings["tick"] == 1
        assert ids[tick1].tolist() == m.beacon_ids.tolist()
        assert got[tick1].tolist() == [0.0, *m.z[:, 0].tolist()]
    (path,) = run.export(tmp_path / "run.mcap")
    with open(path, "rb") as f:
        topics = {ch.topic for _, ch, _ in make_reader(f).iter_messages()}
    assert "/readings" in topics
