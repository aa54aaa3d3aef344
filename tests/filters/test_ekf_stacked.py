"""The EKF's stacked update on arrays (many readings in a tick) against its row-by-row update
on floats: the same posterior to rounding, the same readings dropped by the gate, and the
gate's closed form on floats deciding as the matrix form does, at the threshold too."""

import math
import zlib

import numpy as np
import pytest
from gaussian_helpers import NOISE, SENSORS, bearing, belief, pose_fix, position_fix, range_bearing

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.filters.gaussian.ekf import STACKED_ROWS, ExtendedKalmanFilter

N_BEACONS = 400
BRG2 = SensorSpec("brg2", "bearing", noise=SensorNoise(bearing_std=0.2))


def world(seed):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-9.0, 9.0, (N_BEACONS, 2))
    return World((-10.0, -10.0, 10.0, 10.0), tuple(Beacon(i + 1, x, y) for i, (x, y) in enumerate(xy)))


def ekf(seed, **params):
    ctx = FilterContext("test", world(seed), 0.1, NOISE, (*SENSORS, BRG2), dict(params),
                        np.random.default_rng(0))
    return ExtendedKalmanFilter(ctx)


def random_belief(rng):
    A = rng.normal(0.0, 1.0, (3, 3)) * np.array([0.3, 0.3, 0.1])[:, None]
    cov = A @ A.T + np.diag([1e-3, 1e-3, 1e-4])
    return GaussianBelief(np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi)]),
                          cov)


def readings(rng, f, k, kind, sensor, outliers=0.2):
    """k readings of beacons seen from a pose near the belief's mean, a share of them 1-3 rad
    (bearing) or metres (range) off."""
    ids = rng.choice(np.arange(1, N_BEACONS + 1), size=k, replace=False)
    pose = f.mean + rng.normal(0.0, 0.05, 3)
    xy = f.models.xy[ids - 1]
    z = mm.range_bearing(pose, xy) if kind == "range_bearing" else mm.bearing(pose, xy)[:, None]
    z = z + rng.normal(0.0, 0.05, z.shape)
    bad = rng.random(k) < outliers
    z[bad, -1] = wrap(z[bad, -1] + rng.uniform(1.0, 3.0, int(bad.sum())))
    if kind == "range_bearing":
        z[bad, 0] += rng.uniform(1.0, 3.0, int(bad.sum()))
        return range_bearing(z, ids, sensor)
    return bearing(z[:, 0], ids, sensor)


def tick(rng, f, case):
    if case == "bearing":
        return [readings(rng, f, int(rng.integers(21, 300)), "bearing", "brg")]
    if case == "range_bearing":
        return [readings(rng, f, int(rng.integers(21, 300)), "range_bearing", "rb")]
    # several sensors and kinds in one tick, fixes between them
    m = f.mean
    return [readings(rng, f, int(rng.integers(5, 40)), "bearing", "brg"),
            pose_fix(m + rng.normal(0.0, 0.1, 3)),
            readings(rng, f, int(rng.integers(5, 40)), "range_bearing", "rb"),
            position_fix(m[:2] + rng.normal(0.0, 0.05, 2)),
            readings(rng, f, int(rng.integers(5, 40)), "bearing", "brg2")]


def assert_same_update(a, b):
    (ma, Pa), (mb, Pb) = a.estimate(), b.estimate()
    assert abs(wrap(ma[2] - mb[2])) <= 1e-9 and np.allclose(ma[:2], mb[:2], rtol=0, atol=1e-9)
    scale = np.sqrt(np.outer(np.diag(Pb), np.diag(Pb)))
    assert np.all(np.abs(Pa - Pb) <= 1e-9 * scale + 1e-15)
    assert a.rejected == b.rejected


@pytest.mark.parametrize("case", ["bearing", "range_bearing", "mixed"])
@pytest.mark.parametrize("params", [{"gate_chi2": 0.0}, {"gate_chi2": 9.21}, {"gate_chi2": 3.0},
                                    {"gate_chi2": 9.21, "joseph": False}])
def test_stacked_update_equals_the_row_by_row_update(case, params):
    rng = np.random.default_rng(zlib.crc32(repr((case, params)).encode()))
    for seed in range(8):
        a, b = ekf(seed, **params), ekf(seed, **params)
        start = random_belief(rng)
        a.reset(start)
        b.reset(start)
        for _ in range(3):  # a few ticks: the posterior of one is the prior of the next
            ms = tick(rng, a, case)
            assert a.update_stacked(ms)
            b.update_rows(ms)
            assert_same_update(a, b)
        if params["gate_chi2"] > 0.0:
            assert a.rejected > 0  # the outliers were there to be dropped


def test_update_takes_the_stacked_form_only_above_the_row_limit():
    rng = np.random.default_rng(5)
    for k in (STACKED_ROWS // 2, STACKED_ROWS // 2 + 1):   # range-bearing: 2 rows a reading
        f, rows, stacked = ekf(1), ekf(1), ekf(1)
        start = random_belief(rng)
        for x in (f, rows, stacked):
            x.reset(start)
        ms = [readings(rng, f, k, "range_bearing", "rb")]
        f.update(ms)
        rows.update_rows(ms)
        stacked.update_stacked(ms)
        want = rows if 2 * k <= STACKED_ROWS else stacked
        for got, ref in zip(f.estimate(), want.estimate(), strict=True):
            assert np.array_equal(got, ref)  # bit for bit the form it says


def test_the_gates_closed_form_decides_as_the_matrix_form_at_the_threshold():
    rng = np.random.default_rng(7)
    f = ekf(2, gate_chi2=9.21)
    checked = 0
    for _ in range(300):
        f.reset(random_belief(rng))
        kind = "bearing" if rng.random() < 0.5 else "range_bearing"
        m = readings(rng, f, 1, kind, "brg" if kind == "bearing" else "rb", outliers=0.5)
        g = f.linearise([m])[0]
        H = np.array([r[:3] for r in g])
        nu = np.array([r[3] for r in g])
        S = H @ f.cov @ H.T + np.diag([r[4] for r in g])
        d = float(nu @ np.linalg.solve(S, nu))
        for gate in (d, math.nextafter(d, 0.0), math.nextafter(d, math.inf), d * (1 + 1e-10),
                     d * (1 - 1e-10), 9.21):
            f.gate = gate
            assert f._passes_gate(g) == f._passes_gate_matrix(g)
            checked += 1
        # the stacked form drops the same readings at these gates
        for gate in (d, math.nextafter(d, 0.0)):
            a, b = ekf(2), ekf(2)
            for x in (a, b):
                x.reset(GaussianBelief(f.mean, f.cov))
                x.gate = gate
            a.update_stacked([m])
            b.update_rows([m])
            assert a.rejected == b.rejected
    assert checked == 1800


def test_a_beacon_at_the_robot_leaves_the_row_form_to_fail_as_before():
    f = ekf(3)
    f.reset(belief([0.0, 0.0, 0.0], (0.1, 0.1, 0.1)))
    xy = f.models.xy
    f.reset(belief([xy[0, 0], xy[0, 1], 0.0], (0.1, 0.1, 0.1)))
    ids = np.arange(1, 31)
    m = Measurement("brg", "bearing", np.zeros((30, 1)), ids)
    assert not f.update_stacked([m])
    with pytest.raises(ZeroDivisionError):
        f.update([m])
