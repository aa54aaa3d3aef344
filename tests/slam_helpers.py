"""Small SLAM scenarios and a run loop for the SLAM tests (tests/filters/test_ekf_slam*.py,
test_fastslam*.py, test_slam*.py) and benchmarks/bench_slam.py."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.clutter import ClutterSpec, hide_ids_all
from beacon_sim.core.scenario import Scenario, parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter


def ring_scenario(n_beacons: int = 6, duration: float = 20.0, *, map_: str = "unknown",
                  anchors: tuple[int, ...] = (), bearing_only: bool = False) -> Scenario:
    """A benign SLAM world: the robot drives a 3 m circle around the centre of a 12 m room,
    beacons on a 4.5 m ring around it, all in view (8 m range), good sensor, modest motion
    noise, the filters told the true noise."""
    beacons = [{"id": i + 1, "x": 6.0 + 4.5 * math.cos(2 * math.pi * i / n_beacons + 0.3),
                "y": 6.0 + 4.5 * math.sin(2 * math.pi * i / n_beacons + 0.3)} for i in range(n_beacons)]
    for b in beacons:
        if b["id"] in anchors:
            b["anchor"] = True
    sensor = {"name": "beacons", "kind": "bearing" if bearing_only else "range_bearing",
              "period": 0.1, "max_range": 8.0, "detection_prob": 1.0, "bearing_std": 0.02}
    if not bearing_only:
        sensor["range_std"] = 0.05
    data = {
        "name": "ring_slam", "dt": 0.1, "duration": duration, "seed": 1,
        "world": {"bounds": [0.0, 0.0, 12.0, 12.0], "beacons": beacons},
        "robot": {"initial_pose": [9.0, 6.0, math.pi / 2],
                  "motion_noise": {"v_std": 0.02, "v_frac": 0.05, "omega_std": 0.03, "omega_frac": 0.0,
                                   "pose_std": [0.0, 0.0, 0.0]}},
        "sensors": [sensor],
        "driver": {"kind": "circle", "radius": 3.0, "speed": 0.5},
        "initial_belief": {"std": [0.01, 0.01, 0.005]},
        "model": {"map": map_},
        "default_filters": ["ekf_slam"],
    }
    return parse_scenario(data, "ring_slam.toml")


def run(sc: Scenario, spec: str, seed: int, *, hide: bool = False, clutter: float = 0.0,
        params: dict | None = None, on_step=None):
    """Run one filter over the scenario; readings without IDs when ``hide``. Returns the
    filter, the final true pose and the path (estimates and truths, (T, 3))."""
    flt = build_filter(spec, sc, seed, params=params)
    sim = Simulation(sc, seed)
    rng = np.random.default_rng(seed + 1000)
    est, tru = [], []
    for _ in range(round(sc.duration / sc.dt)):
        st = sim.step()
        ms = st.measurements
        if hide:
            fired = [s for s in sc.sensors if s.name in {m.sensor for m in ms}]
            ms, _ = hide_ids_all(ms, fired, {s.name: ClutterSpec(clutter) for s in fired}, rng)
        flt.predict(st.control, st.dt)
        flt.update(ms)
        est.append(flt.estimate()[0])
        tru.append(st.true_pose)
        if on_step is not None:
            on_step(flt, st)
    return flt, st.true_pose, np.array(est), np.array(tru)


def true_beacons(sc: Scenario) -> dict[int, tuple[float, float]]:
    return {b.id: (b.x, b.y) for b in sc.world.beacons}


def lookalike_pairs(duration: float) -> Scenario:
    """Five pairs of look-alike beacons 0.4 m apart on a 4 m ring, range-bearing readings, a
    robot with a poor gyro (omega_std 0.15 rad/s) on a 3 m circle, no map given (the
    scenario of tests/filters/test_fastslam_jcbb.py and benchmarks/bench_slam.py --association)."""
    bs = []
    for i in range(5):
        a = 2 * math.pi * i / 5 + 0.3
        cx, cy = 6 + 4.0 * math.cos(a), 6 + 4.0 * math.sin(a)
        for s, bid in ((-1, 2 * i + 1), (1, 2 * i + 2)):
            bs.append({"id": bid, "x": cx + s * 0.2 * math.sin(a), "y": cy - s * 0.2 * math.cos(a)})
    return parse_scenario({
        "name": "lookalike_pairs", "dt": 0.1, "duration": duration, "seed": 1,
        "world": {"bounds": [0, 0, 12, 12], "beacons": bs},
        "robot": {"initial_pose": [9.0, 6.0, math.pi / 2],
                  "motion_noise": {"v_std": 0.05, "v_frac": 0.1, "omega_std": 0.15, "omega_frac": 0.0,
                                   "pose_std": [0.0, 0.0, 0.0]}},
        "sensors": [{"name": "beacons", "kind": "range_bearing", "period": 0.1, "max_range": 8.0,
                     "detection_prob": 0.9, "bearing_std": 0.02, "range_std": 0.1}],
        "driver": {"kind": "circle", "radius": 3.0, "speed": 0.5},
        "initial_belief": {"std": [0.01, 0.01, 0.005]},
        "model": {"map": "unknown"}}, "lookalike_pairs.toml")


def weighted_correct(flt, true_ids, xy: np.ndarray, ids: np.ndarray) -> tuple[float, int]:
    """FastSLAM's associations of one tick's readings scored against the truth: the sum over
    readings of the particle weight whose association is right (a beacon's reading given to
    the particle's landmark nearest that beacon, a clutter reading, ``UNKNOWN_ID``, given to
    none), and the number of readings. ``true_ids`` are the readings' true IDs, ``xy``/``ids``
    the beacons' positions [m] and IDs."""
    from beacon_sim.core.clutter import UNKNOWN_ID

    good, w = 0.0, flt.weights
    for true_id, tgt in zip(true_ids, flt.last_targets, strict=True):
        lm = flt.lm[np.arange(flt.n), np.maximum(tgt, 0)]
        nearest = ids[np.argmin(np.sum((lm[:, None, :] - xy[None]) ** 2, axis=2), axis=1)]
        ok = np.where(tgt >= 0, nearest == true_id, true_id == UNKNOWN_ID)
        good += float(w @ ok)
    return good, len(true_ids)
