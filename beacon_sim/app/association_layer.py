"""The window's association layer: for readings without IDs, a line from each
filter's estimate to the beacon it gave each reading to, in the filter's colour when that is
the beacon the reading came from, dashed vermillion when it is not (the simulator knows:
``Step.true_ids``; clutter given a beacon is wrong too). Readings a filter left unpaired
(clutter, to it) get no line.

The renderer calls :func:`seen_by_truth` (so that beacons seen without IDs are drawn as seen,
not as missed) and :func:`draw` (after the particles, under the estimates). Both read the
session duck-typed (``last_step``, ``filters``): a session without them draws nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from beacon_sim.core.team import TeamStep

#: The dash pattern (px on, px off) of a wrong association.
WRONG_DASH = (14, 9)
#: The colour of a wrong association.
WRONG = (170, 0, 0)  # dark red: apart from every filter colour and the vermillion warnings

#: Per session (by id): the tick and, per sensor, the true IDs of its latest reading without
#: IDs (a reading stays drawn while later ticks have none of that sensor).
_truth: dict[int, tuple[int, dict[str, np.ndarray]]] = {}


def latest_truth(session: Any) -> dict[str, np.ndarray]:
    """Per sensor with unknown correspondence, the true beacon of each row of its latest
    reading (-1: clutter), kept across the ticks without one."""
    step = getattr(session, "last_step", None)
    if step is None:
        return {}
    if isinstance(step, TeamStep):  # a live session's tick: the driven robot's Step
        step = step.steps[session.driven]
    key = id(session)
    tick, truth = _truth.get(key, (-1, {}))
    if step.tick < tick:  # a new run in the same object (restart): forget
        truth = {}
    if step.tick != tick:
        truth = {**truth, **getattr(step, "true_ids", {})}
        if len(_truth) > 8 and key not in _truth:
            _truth.clear()
        _truth[key] = (step.tick, truth)
    return truth


def seen_by_truth(session: Any) -> set[int]:
    """The beacons the shown readings without IDs really came from (to draw them as seen)."""
    return {int(i) for ids in latest_truth(session).values() for i in ids if i >= 0}


def association_lines(mean: np.ndarray, given: Mapping[str, tuple[int | None, ...]],
                      truth: Mapping[str, np.ndarray], world: Any
                      ) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    """(from [m], to [m], wrong) for each reading a filter gave a beacon to: from its
    estimate's position ``mean`` to that beacon; wrong when the truth of that row is known
    and is another beacon (or clutter)."""
    out = []
    ids = set(world.beacon_ids.tolist())
    for sensor, rows in given.items():
        true = truth.get(sensor)
        aligned = true is not None and len(true) == len(rows)
        for i, bid in enumerate(rows):
            if bid is None or bid not in ids:
                continue
            wrong = bool(aligned and true is not None and int(true[i]) != int(bid))
            out.append((np.asarray(mean[:2], dtype=float), world.beacon_positions([bid])[0], wrong))
    return out


def draw(surf: Any, view: Any, session: Any, colours: Mapping[str, Any], width: int,
         line: Callable[..., None]) -> None:
    """Every visible filter's association lines (``line``: the renderer's polyline)."""
    filters = getattr(session, "filters", None)
    if not filters or not getattr(session, "last_step", None):
        return
    truth = latest_truth(session)
    if not truth:
        return  # no sensor hides IDs: nothing to associate
    world = session.scenario.world
    wrong_lines = []
    for name in session.names:
        flt = filters.get(name)
        report = getattr(flt, "associations", None)
        if report is None or not session.visible.get(name) or session.status[name].failed:
            continue
        try:
            given = report()
            est = session.estimate(name)
        except Exception:  # a student's method: no lines, the window goes on
            continue
        if est is None or not isinstance(given, dict):
            continue
        for a, b, wrong in association_lines(est[0], given, truth, world):
            px = view.to_px(np.stack([a, b]))
            if wrong:
                wrong_lines.append(px)
            else:
                line(surf, colours[name], px, max(width // 2, 2))
    for px in wrong_lines:  # on top: a wrong pairing is what the lesson is about
        line(surf, WRONG, px, width, WRONG_DASH)
