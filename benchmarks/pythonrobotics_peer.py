"""What ``bench_pythonrobotics_slam.py`` shares between its EKF-SLAM and FastSLAM parts:
finding and importing PythonRobotics (never copying it), the peer's problem as a beacon-sim
scenario, running a built-in filter on the peer's readings, and the tables with per-seed
ratios and their bootstrap interval.

Readings everywhere here are the peer's, one array per tick of rows (range [m], bearing
[rad], landmark index); truths are (T, 3) poses (x, y [m], heading [rad]) in the world frame.
"""

from __future__ import annotations

import ast
import contextlib
import importlib
import io
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import parse_scenario
from beacon_sim.core.types import Control, Measurement
from beacon_sim.evaluation.slam_metrics import gospa
from beacon_sim.hosting.loading import build_filter

ROOT = Path(__file__).resolve().parents[1]
PEER_VARIABLE = "BEACON_SIM_PYTHONROBOTICS"
#: Bootstrap replicates and generator seed of the per-seed ratio's median interval.
REPLICATES, BOOT_SEED = 10_000, 12345


def find_peer() -> Path | None:
    """The PythonRobotics folder (holding ``SLAM/`` and ``utils/``), or None."""
    given = os.environ.get(PEER_VARIABLE)
    for p in ([Path(given)] if given else []) + [ROOT.parent / "shared" / "peers" / "pythonrobotics",
                                                  ROOT.parent.parent / "shared" / "peers" / "pythonrobotics"]:
        if (p / "SLAM" / "EKFSLAM" / "ekf_slam.py").is_file():
            return p
    return None


def load_module(folder: Path, sub: str, name: str):
    """The peer's module ``folder/SLAM/sub/name.py``, imported as it is, animation off."""
    for p in (str(folder), str(folder / "SLAM" / sub)):
        if p not in sys.path:
            sys.path.insert(0, p)
    with contextlib.redirect_stdout(io.StringIO()):
        mod = importlib.import_module(name)
    mod.show_animation = False
    return mod


def main_landmarks(module) -> np.ndarray:
    """The landmark array that the peer's ``main()`` builds (``RFID``/``rfid = np.array(...)``),
    read from its source (so no coordinate of the peer is written down here), (N, 2) [m]."""
    tree = ast.parse(Path(module.__file__).read_text())
    main = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "main")
    for node in ast.walk(main):
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and node.targets[0].id.lower() == "rfid"
                and isinstance(node.value, ast.Call)):
            return np.array(ast.literal_eval(node.value.args[0]), dtype=float)
    raise LookupError(f"{module.__file__}: no RFID array in main()")


def random_landmarks(n: int, seed: int) -> np.ndarray:
    """``n`` landmarks drawn uniformly in a 40 m square around the peer's circle (a
    generator of this script, seeded by the run's seed), (n, 2) [m]."""
    rng = np.random.default_rng(10_000 + seed)
    return rng.uniform((-20.0, -10.0), (20.0, 30.0), size=(n, 2))


def scenario(name: str, lms: np.ndarray, dt: float, duration: float, max_range: float,
             v_std: float, omega_std: float, range_std: float, bearing_std: float):
    """The peer's problem as a beacon-sim scenario: what a built-in filter is told (the
    true noise; the map unknown; the start at the origin, known to 1 mm)."""
    return parse_scenario({
        "name": name, "dt": dt, "duration": duration, "seed": 0,
        "world": {"bounds": [-40.0, -30.0, 40.0, 50.0],
                  "beacons": [{"id": i + 1, "x": float(x), "y": float(y)} for i, (x, y) in enumerate(lms)]},
        "robot": {"initial_pose": [0.0, 0.0, 0.0],
                  "motion_noise": {"v_std": v_std, "omega_std": omega_std}},
        "sensors": [{"name": "beacons", "kind": "range_bearing", "period": dt, "max_range": max_range,
                     "detection_prob": 1.0, "range_std": range_std, "bearing_std": bearing_std}],
        "driver": {"kind": "constant", "v": 1.0, "omega": 0.1},
        "initial_belief": {"std": [1e-3, 1e-3, 1e-3]},
        "model": {"map": "unknown"},
    }, f"{name}.toml")


def nees(err: np.ndarray, cov: np.ndarray) -> float:
    try:
        return float(err @ np.linalg.solve(cov, err))
    except np.linalg.LinAlgError:
        return math.inf


def pose_error(mean: np.ndarray, truth: np.ndarray) -> np.ndarray:
    e = np.asarray(mean, dtype=float)[:3] - truth
    e[2] = wrap(e[2])
    return e


def run_ours(spec: str, sc, seed: int, truths, odo, readings, dt: float, ids: bool,
             params: dict | None = None) -> dict:
    """A built-in SLAM filter on the peer's odometry and readings, with the readings'
    landmark IDs or without them; CPU time around the filter calls only."""
    f = build_filter(spec, sc, seed, params=params or {})
    sq, ns, cpu = 0.0, 0.0, 0.0
    errs = np.zeros((len(truths), 3))
    for k in range(len(truths)):
        z = readings[k]
        beacon_ids = z[:, 2].astype(int) + 1 if ids else np.full(len(z), -1, dtype=int)
        m = [Measurement("beacons", "range_bearing", np.ascontiguousarray(z[:, :2]), beacon_ids)]
        t0 = time.process_time()
        f.predict(Control(float(odo[k, 0]), float(odo[k, 1])), dt)
        f.update(m)
        mean, cov = f.estimate()
        cpu += time.process_time() - t0
        e = pose_error(mean, truths[k])
        errs[k] = e
        sq += e[0] ** 2 + e[1] ** 2
        ns += nees(e, cov)
    return {"rmse": math.sqrt(sq / len(truths)), "nees": ns / len(truths), "errs": errs,
            "map": f.landmarks().means, "us": 1e6 * cpu / len(truths)}


def aligned_rmse(truths: np.ndarray, errs: np.ndarray) -> tuple[float, float]:
    """Position RMSE after the rigid motion (rotation and shift) that best fits the estimated
    path onto the true one, and that rotation [rad]: the error left once the frame the
    filter's map and path share is taken out (a SLAM filter's frame is fixed only by its
    first ticks)."""
    true_xy = truths[:, :2]
    est_xy = true_xy + errs[:, :2]
    a, b = est_xy - est_xy.mean(axis=0), true_xy - true_xy.mean(axis=0)
    rot = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(rot), math.sin(rot)
    fitted = a @ np.array([[c, s], [-s, c]])
    return math.sqrt(float(np.mean(np.sum((fitted - b) ** 2, axis=1)))), rot


def interleaved(names: tuple[str, ...], seeds: range, make: Callable[[int], dict],
                run: Callable[[str, dict, int], dict],
                on_seed: Callable[[int, dict[str, dict], dict[str, list[dict]]], None] | None = None
                ) -> dict[str, list[dict]]:
    """Every filter of ``names`` on every seed's problem (``make(seed)``: a dict with the
    truths and the landmarks ``lms``), in the order of ``names`` on even seeds and reversed
    on odd ones, so a change of load hits all alike; each result gets the map GOSPA and the
    aligned path error (:func:`aligned_rmse`); ``on_seed(seed, its results, all so far)``
    after each seed."""
    rows: dict[str, list[dict]] = {k: [] for k in names}
    for i, seed in enumerate(seeds):
        prob = make(seed)
        done: dict[str, dict] = {}
        for name in (names if i % 2 == 0 else tuple(reversed(names))):
            r = run(name, prob, seed)
            r["gospa"] = gospa(r["map"], prob["lms"]).value
            r["aligned"], r["frame_rot"] = aligned_rmse(prob["truths"], r["errs"])
            r["seed"] = seed
            rows[name].append(r)
            done[name] = r
        if on_seed is not None:
            on_seed(seed, done, rows)
    return rows


def median_interval(values) -> tuple[float, float, float]:
    """Median of ``values`` and its 95 % percentile-bootstrap interval."""
    a = np.asarray(values, dtype=float)
    if a.size < 2:
        return float(np.median(a)), math.nan, math.nan
    rng = np.random.default_rng(BOOT_SEED)
    meds = np.median(a[rng.integers(0, a.size, size=(REPLICATES, a.size))], axis=1)
    return float(np.median(a)), float(np.percentile(meds, 2.5)), float(np.percentile(meds, 97.5))


def print_table(title: str, names: tuple[str, ...], rows: dict[str, list[dict]], peer: str) -> None:
    """Means over seeds (RMSE, aligned RMSE, GOSPA), medians (NEES, CPU per tick), the cost
    ratio to the peer, and per seed the ratio of each filter's position RMSE to the peer's."""
    print(f"\n{title}")
    print(f"{'filter':<24}{'pos RMSE [m]':>14}{'aligned [m]':>13}{'map GOSPA [m]':>15}{'med. NEES':>11}"
          f"{'us/tick':>10}{'cost ratio':>12}{'RMSE ratio, median [95 %]':>34}{'worse':>8}")
    peer_us = statistics.median(r["us"] for r in rows[peer])
    for name in names:
        rs = rows[name]
        us = statistics.median(r["us"] for r in rs)
        ratios = [a["rmse"] / b["rmse"] for a, b in zip(rs, rows[peer], strict=True)]
        med, lo, hi = median_interval(ratios)
        worse = sum(x > 1.0 for x in ratios)
        nees_med = statistics.median(r["nees"] for r in rs)
        print(f"{name:<24}{statistics.mean(r['rmse'] for r in rs):>14.3f}"
              f"{statistics.mean(r['aligned'] for r in rs):>13.3f}"
              f"{statistics.mean(r['gospa'] for r in rs):>15.3f}"
              f"{nees_med:>11.3g}{us:>10.0f}{us / peer_us:>11.2f}x"
              + (f"{'-':>34}{'-':>8}" if name == peer else
                 f"{f'{med:.2f} [{lo:.2f}, {hi:.2f}]':>34}{f'{worse}/{len(rs)}':>8}"))
