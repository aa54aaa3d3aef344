"""A headless run's SLAM figures (docs/slam.md, "In `run`"): for each single-robot filter
with ``landmarks()`` that was not switched off, the path's ATE [m], the final map's GOSPA
[m] against the beacons the filters were not given, and the final joint NEES (landmarks
without IDs paired with beacons by GOSPA's assignment).

It lives here, not in ``runs/headless.py``, because the metrics are the evaluation layer's
(``evaluation/slam_metrics.py``) and the layers forbid ``runs`` to import them; ``run``
merges the figures into each filter's row of ``RunResult.as_json()``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation.slam_metrics import ate, gospa, joint_nees
from beacon_sim.runs.headless import RunResult

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
    """The final joint NEES and its degrees of freedom (3 + 2M), from the filter's
    ``joint()`` (mean, cov, landmark IDs); None when it has no ``joint()``.

    Landmarks with beacon IDs are compared with those beacons. Landmarks without (unknown
    correspondence, ID < 0) are paired with the beacons by GOSPA's assignment (within its
    cut-off) and the unpaired ones marginalised out (their rows and columns dropped, which
    is the marginal of the Gaussian); the pairing picks the nearest beacons, so this NEES
    leans low."""
    joint = getattr(flt, "joint", None)
    if not callable(joint):
        return None, None
    return joint_nees_at(joint(), result.scenario, result.truth[-1])


def joint_nees_at(joint: tuple[Any, Any, Any], sc: Scenario, true_pose: np.ndarray
                  ) -> tuple[float | None, int | None]:
    """The joint NEES and its degrees of freedom of a filter's ``joint()`` (mean, cov,
    landmark IDs) against the truth of ``sc`` with the robot at ``true_pose`` (the run's
    last): what :func:`slam_figures` reports, for ``grade`` too."""
    mean, cov, ids = joint
    mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    truth = {b.id: (b.x, b.y) for b in sc.world.beacons}
    ids = [int(i) for i in ids]
    if any(i >= 0 and i not in truth for i in ids):
        return None, None
    blind = [j for j, i in enumerate(ids) if i < 0]
    if blind:
        b_ids, b_xy = mapped_beacons(sc)
        taken = {i for i in ids if i >= 0}
        free = [k for k, b in enumerate(b_ids.tolist()) if b not in taken]
        xy = mean[3:3 + 2 * len(ids)].reshape(-1, 2)[blind]
        pairs = gospa(xy, b_xy[free], c=GOSPA_CUTOFF_M).pairs
        for r, k in pairs:
            ids[blind[r]] = int(b_ids[free[k]])
    keep = [j for j, i in enumerate(ids) if i >= 0]
    rows = np.r_[0:3, np.array([[3 + 2 * j, 4 + 2 * j] for j in keep], dtype=int).reshape(-1)]
    value = joint_nees(mean[rows], cov[np.ix_(rows, rows)], [ids[j] for j in keep],
                       true_pose, truth)
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
