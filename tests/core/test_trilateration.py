"""Hyperbolic trilateration (core/trilateration.py) and the loose coupling's sensor kind
(core/tdoa_fix_kind.py): exact and noisy geometry, the fix's covariance against the bound,
ambiguous and degenerate layouts (a clear error, no crash), the filters on the fix."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim import api
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.sensor_kinds import sensor_kind
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.tdoa_fix_kind import TDOA_FIX
from beacon_sim.core.tdoa_kind import TDOA, difference_cov
from beacon_sim.core.trilateration import TrilaterationError, tdoa_hdop, trilaterate
from beacon_sim.core.types import Beacon
from beacon_sim.core.world import World

SQ = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
H = 3.45


def diffs(p, bxy=SQ, h=H, ref=0):
    r = np.sqrt(np.sum((np.asarray(p) - bxy) ** 2, axis=1) + h * h)
    return np.delete(r, ref) - r[ref]


@pytest.mark.parametrize("p", [(0.5, 0.5), (2.0, 0.5), (4.0, 4.0), (-3.0, 1.2), (0.1, 0.9)])
@pytest.mark.parametrize("h", [0.0, H])
def test_exact_geometry_gives_the_point(p, h):
    fix = trilaterate(diffs(p, h=h), SQ[0], SQ[1:], h, 0.01)
    assert np.allclose(fix.xy, p, atol=1e-8) and fix.cost < 1e-12


@pytest.mark.parametrize("p, bound_cm", [((0.5, 0.5), 4.98), ((2.0, 0.5), 5.90), ((4.0, 4.0), 19.15)])
def test_the_fix_covariance_is_the_bound_and_hdop_its_size(p, bound_cm):
    for ref in range(4):
        fix = trilaterate(diffs(p, ref=ref), SQ[ref], np.delete(SQ, ref, axis=0), H, 0.01)
        assert 100 * math.sqrt(np.trace(fix.cov)) == pytest.approx(bound_cm, rel=0.01)
        assert fix.hdop * 0.01 * 100 == pytest.approx(bound_cm, rel=0.01)
    assert tdoa_hdop(np.array([p]), SQ, H)[0] * 1.0 == pytest.approx(bound_cm, rel=0.01)


@pytest.mark.parametrize("p", [(0.5, 0.5), (2.0, 0.5)])
def test_noisy_fixes_are_unbiased_and_their_covariance_honest(p):
    rng = np.random.default_rng(8)
    s = 0.01
    r = np.sqrt(np.sum((np.asarray(p) - SQ) ** 2, axis=1) + H * H)
    errs, nees = [], []
    for _ in range(2000):
        t = r + s * rng.standard_normal(4)
        fix = trilaterate(t[1:] - t[0], SQ[0], SQ[1:], H, s)
        e = fix.xy - p
        errs.append(e)
        nees.append(e @ np.linalg.solve(fix.cov, e))
    errs = np.array(errs)
    assert np.all(np.abs(errs.mean(axis=0)) < 4 * errs.std(axis=0) / math.sqrt(len(errs)))
    assert np.mean(nees) == pytest.approx(2.0, rel=0.08)          # chi-square, 2 dof


def test_ambiguous_and_degenerate_layouts_give_a_clear_error():
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    cases = [
        (diffs((0.7, 1.5), line), line[0], line[1:], "ambiguous"),        # mirror in the line
        (diffs((0.7, 0.0), line), line[0], line[1:], "does not fix"),     # on the line
        (np.array([0.1]), SQ[0], SQ[1:2], "at least 2"),                  # one difference
        (np.zeros(3), SQ[0], np.zeros((3, 2)) + SQ[0], "one point"),     # all at one point
        (np.array([0.1, np.nan, 0.2]), SQ[0], SQ[1:], "finite"),
    ]
    for z, ref, others, words in cases:
        with pytest.raises(TrilaterationError, match=words) as err:
            trilaterate(z, ref, others, H, 0.01)
        assert "\n" not in str(err.value)


def spec(**kw):
    params = (("reference_id", kw.pop("reference_id", -1.0)), ("isotropic_fix", kw.pop("iso", 0.0)),
              ("cone_half_angle", 0.5 * math.pi))
    return SensorSpec("u", "tdoa_fix", beacon_height=H, noise=SensorNoise(range_std=0.01), params=params,
                      **kw)


WORLD = World((-5.0, -5.0, 6.0, 6.0), tuple(Beacon(i + 1, *xy) for i, xy in enumerate(SQ.tolist())))


def test_the_fix_kind_trilaterates_the_tdoa_kinds_draws():
    sp = spec()
    tdoa_spec = SensorSpec("u", "tdoa", beacon_height=H, noise=SensorNoise(range_std=0.01),
                           params=(("reference_id", -1.0), ("naive_differences", 0.0),
                                   ("cone_half_angle", 0.5 * math.pi)), min_beacons=3)
    pose = np.array([2.0, 0.5, 0.3])
    a, b = np.random.default_rng(4), np.random.default_rng(4)
    for _ in range(20):
        m = TDOA_FIX.draw(sp, pose, WORLD, a)
        t = TDOA.draw(tdoa_spec, pose, WORLD, b)
        bxy = WORLD.beacon_positions(t.beacon_ids)
        want = trilaterate(t.z[:, 0], bxy[0], bxy[1:], H, 0.01)
        assert np.array_equal(m.z[0], want.xy) and m.hdop == want.hdop
        assert m.beacon_ids.tolist() == t.beacon_ids.tolist()
    R = TDOA_FIX.model.noise_at(sp, m, WORLD)
    assert np.allclose(R, want.cov)
    iso = TDOA_FIX.model.noise_at(spec(iso=1.0), m, WORLD)
    assert np.allclose(iso, np.eye(2) * (0.01 * m.hdop) ** 2)


def test_the_fix_carries_the_differences_information():
    p = np.array([[2.0, 0.5, 0.0]])
    J = TDOA_FIX.model.information(spec(), p, WORLD)[0]
    D = TDOA.model.jacobian(spec(), type("M", (), {"beacon_ids": np.array([1, 2, 3, 4])})(), p[0], WORLD)
    want = D.T @ np.linalg.solve(difference_cov(3, 0.01), D)
    assert np.allclose(J, want)


def test_filters_take_the_loose_fix(tmp_path):
    text = load_scenario("ruiz_ulps").source
    src = open(text, encoding="utf-8").read().replace('kind = "tdoa"', 'kind = "tdoa_fix"')
    path = tmp_path / "loose.toml"
    path.write_text(src, encoding="utf-8")
    sc = load_scenario(path)
    assert sensor_kind(sc.sensors[0].kind) is TDOA_FIX
    run = api.run(sc, ["ekf", "ukf", "pf", "dead_reckoning"], duration=100.0)
    met = run.metrics()["filters"]
    for n in ("ekf", "ukf", "pf"):
        assert met[n]["pos_rmse_m"] < 0.5 * met["dead_reckoning"]["pos_rmse_m"], met
        assert met[n]["pos_rmse_m"] < 0.08 and math.isfinite(met[n]["anees"]), met
    # two beacons cannot fix x and y: refused at load
    two = src.replace("  { id = 3, x = 0.335, y = 3.558 },\n  { id = 4, x = -0.335, y = 3.558 },\n", "")
    path.write_text(two, encoding="utf-8")
    with pytest.raises(ScenarioError, match="at least 3 for a tdoa_fix"):
        load_scenario(path)
