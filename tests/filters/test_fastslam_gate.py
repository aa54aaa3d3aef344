"""FastSLAM 2.0's outlier gate on readings with IDs (``gate_chi2``): a reading off
by pi is dropped for all particles when none can explain it (the pose, the map and the
linearised covariance's EKF-SLAM recursion do not move; ungated, they do); a reading some
particles explain is used by all, as without the gate."""

from __future__ import annotations

import math

import numpy as np
from slam_helpers import ring_scenario

from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import GaussianBelief
from beacon_sim.filters.registry import MRCLAM_GATE_CHI2
from beacon_sim.filters.slam.fastslam import (
    GATED,
    FastSLAM2,
    predictive_distance,
    proposal_step,
    without_rows,
)
from beacon_sim.hosting.loading import build_filter

POSE = np.array([9.0, 6.0, math.pi / 2])
LANDMARK = np.array([6.0, 8.0])


def _truth_reading(pose: np.ndarray = POSE) -> np.ndarray:
    d = LANDMARK - pose[:2]
    return np.array([math.hypot(*d), float(wrap(math.atan2(d[1], d[0]) - pose[2]))])


def _reading(z: np.ndarray) -> list[Measurement]:
    return [Measurement("beacons", "range_bearing", z[None, :], np.array([1]))]


#: Forward at 0.5 m/s for 0.1 s (along +y, the heading): the proposals get the motion noise.
DRIVE = Control(0.5, 0.0)
STEP = np.array([0.0, 0.05, 0.0])


def _mapped(gate: float) -> FastSLAM2:
    """One landmark, a tight prior at POSE, ten ticks driving with the landmark seen from the
    true pose each tick (no noise added), then the eleventh tick's prediction: the true pose
    is then POSE + 11 STEP."""
    f = build_filter("fastslam", ring_scenario(1), 3, params={"n_particles": 50, "gate_chi2": gate})
    assert isinstance(f, FastSLAM2)
    f.reset(GaussianBelief(POSE.copy(), np.diag([1e-4, 1e-4, 2.5e-5])))
    for t in range(1, 11):
        f.predict(DRIVE, 0.1)
        f.update(_reading(_truth_reading(POSE + t * STEP)))
    f.predict(DRIVE, 0.1)
    return f


def test_a_reading_off_by_pi_moves_neither_pose_nor_map_with_the_gate_and_both_without():
    flipped = _truth_reading(POSE + 11 * STEP)
    flipped[1] = wrap(flipped[1] + math.pi)
    moved = {}
    for gate in (MRCLAM_GATE_CHI2, 0.0):
        f = _mapped(gate)
        before_pose, before_map = f.estimate()[0], f.landmarks().means[0].copy()
        assert f.companion is not None
        before_P = f.companion.ekf.P.copy()
        logw = f.logw.copy()
        f.update(_reading(flipped))
        pose, _ = f.estimate()
        turn = abs(float(wrap(pose[2] - before_pose[2])))
        moved[gate] = (float(np.hypot(*(pose[:2] - before_pose[:2]))) + turn,
                       float(np.hypot(*(f.landmarks().means[0] - before_map))))
        if gate:
            assert f.rejected == 1 and np.all(f.last_targets[0] == GATED)
            assert np.array_equal(f.logw, logw - np.max(logw))      # no weight changed
            assert np.array_equal(f.companion.ekf.P, before_P)  # its EKF dropped it too
        else:
            assert f.rejected == 0
            assert np.trace(f.companion.ekf.P) < np.trace(before_P)
    on, off = moved[MRCLAM_GATE_CHI2], moved[0.0]
    assert on[0] < 0.01 and on[1] < 0.01, on             # only the motion noise's sample
    assert off[0] > 0.05 and off[1] > 0.1, off           # the flipped reading drags both
    assert off[0] + off[1] > 10 * (on[0] + on[1])


def test_a_reading_some_particles_explain_is_used_by_all_as_without_the_gate():
    """Outliers are the reading's, decided by the set: half the particles put 0.5 m off
    reject a true reading, the other half explain it, so all fold it in ungated."""
    gate = MRCLAM_GATE_CHI2
    f = _mapped(gate)
    f.params["ess_threshold"] = 0.0               # no resampling: the weights stay readable
    assert f.prop_mu is not None and f.prop_cov is not None
    far = np.arange(f.n) % 2 == 1                  # half the particles 0.5 m off to the side
    f.prop_mu[far, 0] += 0.5
    mu, Sig = f.prop_mu.copy(), f.prop_cov.copy()
    f.logw[:] = 0.0
    slot = int(np.argmax(f.lid[0] == 1))
    lm, lc = f.lm[:, slot].copy(), f.lc[:, slot].copy()
    z = _truth_reading(POSE + 11 * STEP) + np.array([0.03, 0.0])   # 3 cm long: the maps move
    R = f.noise["beacons"]
    d2, _ = predictive_distance("range_bearing", z, R, mu, Sig, lm, lc)
    assert np.all(d2[far] > gate) and np.all(d2[~far] <= gate)
    loglik = proposal_step("range_bearing", z, R, mu, Sig, lm, lc)[2]
    f.update(_reading(z))
    assert f.rejected == 0 and np.all(f.last_targets[0] == slot)
    assert np.allclose(f.logw, loglik - loglik.max())             # the full likelihood
    assert loglik[far].max() < loglik[~far].min() - 10            # which sinks the far ones
    assert not np.any(np.all(f.lm[:, slot] == lm, axis=1))        # every map updated


def test_without_rows_takes_out_exactly_the_numbered_readings():
    ms = [Measurement("gps", "position", np.array([[1.0, 2.0]]), np.array([], dtype=int)),
          Measurement("a", "range_bearing", np.array([[1.0, 0.1], [2.0, 0.2]]), np.array([4, 5])),
          Measurement("b", "bearing", np.array([[0.3], [0.4]]), np.array([6, 7]))]
    out = without_rows(ms, [1, 2])
    assert out[0] is ms[0]
    assert out[1].beacon_ids.tolist() == [4] and out[1].z.tolist() == [[1.0, 0.1]]
    assert out[2].beacon_ids.tolist() == [7] and out[2].z.tolist() == [[0.4]]
    assert without_rows(ms, []) == ms
