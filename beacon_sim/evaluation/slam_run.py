"""A headless run's SLAM figures (docs/slam.md, "In `run`"): for each single-robot filter
with ``landmarks()`` that was not switched off, the path's ATE [m], the final map's GOSPA
[m] against the beacons the filters were not given, and the final joint NEES (landmarks
without IDs paired with beacons by GOSPA's assignment).

It lives here, not in ``runs/headless.py``, because the metrics are the evaluation layer's
(``evaluation/slam_metrics.py``) and the layers forbid ``runs`` to import them; ``run``
merges the figures into each filter's row of ``RunResult.as_json()``. ``beacon-sim mrclam --slam``
scores a real-data run the same way against the surveyed landmarks (:func:`mrclam_slam_figures`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation.slam_metrics import ate, gospa, joint_nees
from beacon_sim.runs.headless import RunResult
from beacon_sim.runs.mrclam import MrclamRun

#: GOSPA's cut-off [m]: a landmark farther than this from every beacon is a false one.
GOSPA_CUTOFF_M = 1.0
#: The keys :func:`slam_figures` gives each SLAM filter (null when not computable).
SLAM_KEYS = ("ate_m", "map_gospa_m", "map_landmarks", "map_missed", "map_false",
             "joint_nees", "joint_dof")


def true_map(result: RunResult) -> tuple[np.ndarray, np.ndarray]:
    """The beacons a SLAM filter had to map (all but the anchors): IDs (B,), positions (B, 2) [m]."""
    return mapped_beacons(result.scenario)


def mapped_beacons(sc: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The beacons of ``sc`` a SLAM filter had to map (all but the anchors): IDs (B,),
    positions (B, 2) [m] (``grade`` scores a map against them too)."""
    anchors = set(sc.anchor_ids) if not sc.map_known else {b.id for b in sc.world.beacons}
    mapped = [b for b in sc.world.beacons if b.id not in anchors]
    return (np.array([b.id for b in mapped], dtype=int),
            np.array([(b.x, b.y) for b in mapped], dtype=float).reshape(-1, 2))


def _joint_nees(flt: Any, result: RunResult) -> tuple[float | None, int | None]:
    """The final joint NEES of a simulated run (:func:`joint_nees_of` at its last true pose)."""
    truth = {b.id: (b.x, b.y) for b in result.scenario.world.beacons}
    b_ids, b_xy = true_map(result)
    return joint_nees_of(flt, result.truth[-1], truth, b_ids, b_xy)


def joint_nees_at(joint: tuple[Any, Any, Any], sc: Scenario, true_pose: np.ndarray
                  ) -> tuple[float | None, int | None]:
    """:func:`joint_nees_of` for a filter's ``joint()`` already taken (``grade`` gets it over
    the pipe), against the beacons of ``sc`` with the robot at ``true_pose``."""
    truth = {b.id: (b.x, b.y) for b in sc.world.beacons}
    b_ids, b_xy = mapped_beacons(sc)
    return _joint_nees_of(joint, true_pose, truth, b_ids, b_xy)


def joint_nees_of(flt: Any, true_pose: np.ndarray, truth: dict[int, tuple[float, float]],
                  b_ids: np.ndarray, b_xy: np.ndarray) -> tuple[float | None, int | None]:
    """The final joint NEES and its degrees of freedom (3 + 2M), from the filter's
    ``joint()`` (mean, cov, landmark IDs) against ``true_pose`` and the beacons ``truth``
    (ID -> (x, y) [m]); None when it has no ``joint()``. ``b_ids``, ``b_xy``: the beacons
    the filter had to map (landmarks without IDs are paired among these).

    Landmarks with beacon IDs are compared with those beacons. Landmarks without (unknown
    correspondence, ID < 0) are paired with the beacons by GOSPA's assignment (within its
    cut-off) and the unpaired ones marginalised out (their rows and columns dropped, which
    is the marginal of the Gaussian); the pairing picks the nearest beacons, so this NEES
    leans low."""
    joint = getattr(flt, "joint", None)
    if not callable(joint):
        return None, None
    return _joint_nees_of(joint(), true_pose, truth, b_ids, b_xy)


def _joint_nees_of(joint: tuple[Any, Any, Any], true_pose: np.ndarray,
                   truth: dict[int, tuple[float, float]], b_ids: np.ndarray, b_xy: np.ndarray
                   ) -> tuple[float | None, int | None]:
    """:func:`joint_nees_of` on a ``joint()`` (mean, cov, landmark IDs) already taken."""
    mean, cov, ids = joint
    mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    ids = [int(i) for i in ids]
    if any(i >= 0 and i not in truth for i in ids):
        return None, None
    blind = [j for j, i in enumerate(ids) if i < 0]
    if blind:
        taken = {i for i in ids if i >= 0}
        free = [k for k, b in enumerate(b_ids.tolist()) if b not in taken]
        xy = mean[3:3 + 2 * len(ids)].reshape(-1, 2)[blind]
        pairs = gospa(xy, b_xy[free], c=GOSPA_CUTOFF_M).pairs
        for r, k in pairs:
            ids[blind[r]] = int(b_ids[free[k]])
    keep = [j for j, i in enumerate(ids) if i >= 0]
    rows = np.r_[0:3, np.array([[3 + 2 * j, 4 + 2 * j] for j in keep], dtype=int).reshape(-1)]
    value = joint_nees(mean[rows], cov[np.ix_(rows, rows)], [ids[j] for j in keep],
                       np.asarray(true_pose, dtype=float), truth)
    return (value if math.isfinite(value) else None), 3 + 2 * len(keep)


def slam_figures(result: RunResult) -> dict[str, dict[str, Any] | None]:
    """Per SLAM filter (a single-robot run's filter with ``landmarks()``), its figures under
    :data:`SLAM_KEYS`; a failed filter gets None (no score), a filter that is no SLAM filter
    is left out."""
    if not result.team.solo:
        return {}
    _, beacons = true_map(result)
    out: dict[str, dict[str, Any] | None] = {}
    for name in result.names:
        if not result.filters.is_member(name):
            continue
        tr = result.runner.tracks[name]
        flt = tr.filter
        if flt is None or not callable(getattr(flt, "landmarks", None)):
            continue
        if tr.failed or not tr.means:
            out[name] = None
            continue
        row = {s.tick: k for k, s in enumerate(result.team_steps)}
        truths = result.truth[[row[int(t)] for t in tr.ticks]]
        means = np.array(tr.means, dtype=float).reshape(-1, 3)
        lm = flt.landmarks()  # type: ignore[attr-defined]
        g = gospa(np.asarray(lm.means, dtype=float).reshape(-1, 2), beacons, c=GOSPA_CUTOFF_M)
        nees, dof = _joint_nees(flt, result)
        out[name] = {"ate_m": ate(means, truths), "map_gospa_m": g.value,
                     "map_landmarks": len(np.asarray(lm.means).reshape(-1, 2)),
                     "map_missed": g.missed, "map_false": g.false, "joint_nees": nees, "joint_dof": dof}
    return out


def print_slam_table(figures: dict[str, dict[str, Any] | None]) -> None:
    """The SLAM figures under ``run``'s table: one row per SLAM filter."""
    if not figures:
        return
    print(f"{'SLAM filter':<16}{'ATE m':>9}{'GOSPA m':>9}{'landmarks':>10}{'missed':>8}{'false':>7}"
          f"{'joint NEES':>12}{'dof':>5}")
    for name, r in figures.items():
        if r is None:
            print(f"{name:<16}FAILED: no score")
            continue
        nees = "n/a" if r["joint_nees"] is None else f"{r['joint_nees']:.2f}"
        dof = "" if r["joint_dof"] is None else str(r["joint_dof"])
        print(f"{name:<16}{r['ate_m']:>9.3f}{r['map_gospa_m']:>9.3f}{r['map_landmarks']:>10}"
              f"{r['map_missed']:>8}{r['map_false']:>7}{nees:>12}{dof:>5}")
    print(f"(GOSPA cut-off {GOSPA_CUTOFF_M:g} m; joint NEES of the final pose and map, chi-square "
          "with dof degrees of freedom; landmarks without IDs paired by GOSPA; n/a: no joint Gaussian)")


def rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation R (2, 2) and translation t (2,) [m] minimising ``sum |R src_i + t - dst_i|^2``
    over paired points (K, 2), K >= 2 (Kabsch / Umeyama without scale; no reflection)."""
    a, b = np.asarray(src, dtype=float), np.asarray(dst, dtype=float)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rot = vt.T @ np.diag([1.0, d]) @ u.T
    return rot, cb - rot @ ca


def aligned_gospa(est: np.ndarray, truth: np.ndarray, ids: np.ndarray | None,
                  truth_ids: np.ndarray, c: float = GOSPA_CUTOFF_M) -> tuple[float, float]:
    """GOSPA of the map after the rigid motion that best fits it onto the truth, and the
    rotation of that motion [rad]: the map's *shape* error, with the frame error (a map
    rotated and shifted as a whole, which no reading can reveal without anchors) taken out.
    The fit pairs landmarks with beacons by ID when the map has IDs, else by GOSPA's
    assignment, refitted while that lowers the GOSPA. Three fitted parameters: slightly
    optimistic. ``nan`` with fewer than two pairs."""
    est = np.asarray(est, dtype=float).reshape(-1, 2)
    truth = np.asarray(truth, dtype=float).reshape(-1, 2)
    if ids is not None:
        where = {int(b): k for k, b in enumerate(np.asarray(truth_ids).tolist())}
        pairs = [(i, where[int(b)]) for i, b in enumerate(np.asarray(ids).tolist()) if int(b) in where]
    else:
        pairs = list(gospa(est, truth, c=c).pairs)
    best, angle = math.inf, math.nan
    for _ in range(5):
        if len(pairs) < 2:
            break
        rows, cols = (list(x) for x in zip(*pairs, strict=True))
        rot, t = rigid_fit(est[rows], truth[cols])
        g = gospa(est @ rot.T + t, truth, c=c)
        if g.value >= best - 1e-12:
            break
        best, angle = g.value, math.atan2(rot[1, 0], rot[0, 0])
        pairs = list(g.pairs)
    return (best if math.isfinite(best) else math.nan), angle


def mrclam_slam_figures(run: MrclamRun) -> dict[str, dict[str, Any] | None]:
    """Per filter of a ``beacon-sim mrclam --slam`` run (one robot): the path's ATE [m] where
    ground truth exists and, for a filter that was not given the map, the final map's GOSPA
    (``GOSPA_CUTOFF_M``) against the data set's surveyed landmarks with its counts, the GOSPA
    after the best rigid fit of the map onto the survey (``map_gospa_aligned_m``, its rotation
    ``map_rotation_deg``; :func:`aligned_gospa`), and the
    final joint NEES at the ground truth of the last estimate (None: no ``joint()`` or no
    ground truth then). A filter given the map has ``map_given`` True and no map figures; a
    failed filter, or one whose ``landmarks()`` raises or returns garbage, gets None."""
    data = run.data
    beacons = list(run.scenario.world.beacons)
    truth = {b.id: (b.x, b.y) for b in beacons}
    b_ids = np.array([b.id for b in beacons], dtype=int)
    b_xy = np.array([(b.x, b.y) for b in beacons], dtype=float).reshape(-1, 2)
    out: dict[str, dict[str, Any] | None] = {}
    for name, tr in run.tracks.items():
        if tr.failed or not len(tr.times):
            out[name] = None
            continue
        true_path, ok = data.truth_at(tr.times)
        row: dict[str, Any] = dict.fromkeys((*SLAM_KEYS, "map_gospa_aligned_m", "map_rotation_deg"))
        row["ate_m"] = ate(tr.means[ok], true_path[ok]) if ok.any() else None
        row["map_given"] = run.map_given.get(name, True)
        flt = tr.filter
        if row["map_given"] or not callable(getattr(flt, "landmarks", None)):
            out[name] = row
            continue
        try:
            lm = flt.landmarks()
            xy = np.asarray(lm.means, dtype=float).reshape(-1, 2)
            lm_ids = None if lm.ids is None else np.asarray(lm.ids, dtype=int).reshape(-1)
        except Exception:  # the filter's own method: no map score
            out[name] = None
            continue
        if not np.all(np.isfinite(xy)) or (lm_ids is not None and len(lm_ids) != len(xy)):
            out[name] = None
            continue
        g = gospa(xy, b_xy, c=GOSPA_CUTOFF_M)
        shape, turn = aligned_gospa(xy, b_xy, lm_ids, b_ids)
        row.update(map_gospa_m=g.value, map_landmarks=len(xy), map_missed=g.missed, map_false=g.false,
                   map_gospa_aligned_m=None if math.isnan(shape) else shape,
                   map_rotation_deg=None if math.isnan(turn) else math.degrees(turn))
        last, ok_last = data.truth_at(tr.times[-1:])
        if ok_last[0]:
            try:
                row["joint_nees"], row["joint_dof"] = joint_nees_of(flt, last[0], truth, b_ids, b_xy)
            except (np.linalg.LinAlgError, ValueError):
                pass
        out[name] = row
    return out


def print_mrclam_slam_table(figures: dict[str, dict[str, Any] | None]) -> None:
    """``mrclam --slam``'s SLAM table: per filter, whether it had the map, the ATE and the
    final map's figures."""
    print(f"{'SLAM figures':<16}{'map':>7}{'ATE m':>8}{'GOSPA m':>9}{'landmarks':>10}{'missed':>8}"
          f"{'false':>7}{'fitted m':>9}{'turn deg':>9}{'joint NEES':>12}{'dof':>5}")
    for name, r in figures.items():
        if r is None:
            print(f"{name:<16}FAILED: no score")
            continue
        ate_text = "-" if r["ate_m"] is None else f"{r['ate_m']:.3f}"
        if r["map_given"]:
            print(f"{name:<16}{'given':>7}{ate_text:>8}   (the surveyed map: nothing to score)")
            continue
        if r["map_gospa_m"] is None:
            print(f"{name:<16}{'none':>7}{ate_text:>8}   (no landmarks(): map not scored)")
            continue
        nees = "n/a" if r["joint_nees"] is None else f"{r['joint_nees']:.1f}"
        dof = "" if r["joint_dof"] is None else str(r["joint_dof"])
        fitted = "-" if r.get("map_gospa_aligned_m") is None else f"{r['map_gospa_aligned_m']:.3f}"
        turn = "-" if r.get("map_rotation_deg") is None else f"{r['map_rotation_deg']:+.1f}"
        print(f"{name:<16}{'none':>7}{ate_text:>8}{r['map_gospa_m']:>9.3f}{r['map_landmarks']:>10}"
              f"{r['map_missed']:>8}{r['map_false']:>7}{fitted:>9}{turn:>9}{nees:>12}{dof:>5}")
    print(f"(map none: the filter was not given the landmarks; GOSPA against the data set's surveyed "
          f"landmarks, cut-off {GOSPA_CUTOFF_M:g} m; fitted: the GOSPA after the rigid motion that best "
          "fits the map onto the survey, turning it by 'turn'; joint NEES of the final pose and map, "
          "chi-square with dof degrees of freedom; n/a: no joint Gaussian)")
