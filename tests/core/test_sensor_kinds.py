"""The built-in sensor kinds' records (core/sensor_kinds.py): their widths are the
simulation's, their models are their maths (finite-difference Jacobians, the Gaussian
log-likelihood with R), and the registry refuses a name twice."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.sensor_kinds import BUILTIN, KINDS, names_beacons, register_kind, sensor_kind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import MEASUREMENT_DIMS, Measurement
from beacon_sim.io.tables import VALUE_COLUMNS, value_columns


def test_the_records_agree_with_the_simulations_readings():
    assert BUILTIN == tuple(MEASUREMENT_DIMS)
    for name, d in MEASUREMENT_DIMS.items():
        assert sensor_kind(name).dims == d
    # the built-in kinds add no column; the distance kinds one, the tdoa's differences
    assert value_columns() == (*VALUE_COLUMNS, "range_diff_m")
    assert [names_beacons(k) for k in BUILTIN] == [True, True, False, False, False]
    sim = Simulation(load_scenario("default"))
    seen = [m for _ in range(200) for m in sim.step().measurements]
    assert seen and all(m.z.shape[1] == sensor_kind(m.kind).dims for m in seen)


@pytest.mark.parametrize("kind", ["bearing", "range_bearing", "pose", "position"])
def test_each_built_in_model_is_its_maths(kind):
    world = load_scenario("default").world
    spec = SensorSpec("s", kind)
    model = KINDS[kind].model
    ids = np.array([1, 3, 5])
    k = len(ids) if KINDS[kind].carries_ids else 1
    d = KINDS[kind].dims
    rng = np.random.default_rng(4)
    m = Measurement("s", kind, rng.normal(size=(k, d)), ids, hdop=1.3)
    pose = np.array([3.1, 2.4, 0.7])
    eps = 1e-6
    fd = np.column_stack([(model.expected(spec, m, (pose + eps * e)[None], world)[0]
                           - model.expected(spec, m, (pose - eps * e)[None], world)[0]) / (2 * eps)
                          for e in np.eye(3)])
    assert np.allclose(model.jacobian(spec, m, pose, world), fd, atol=1e-6)
    poses = pose + rng.normal(scale=0.3, size=(5, 3))
    R = model.noise(spec, m)
    nu = model.residual(m, model.expected(spec, m, poses, world))
    assert np.all(np.abs(nu[:, model.angle_rows(m)]) <= np.pi)
    want = -0.5 * np.einsum("ni,ij,nj->n", nu, np.linalg.inv(R), nu)
    assert np.allclose(model.loglik(spec, m, poses, world), want)


def test_a_name_is_registered_once():
    with pytest.raises(ValueError, match="already registered"):
        register_kind(KINDS["bearing"])
    with pytest.raises(ValueError, match=r"unknown sensor kind .sonar.*range_finder"):
        sensor_kind("sonar")
