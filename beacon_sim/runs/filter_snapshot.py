"""What a live session shows of its filters after a tick, read on the thread that fed them
(:class:`FilterTick`), so that a window whose filters run on a worker thread
(``runs/filter_worker.py``) draws the filters of one finished tick and never calls into a
filter the worker may be stepping.

A :class:`FilterTick` holds every filter's latest estimate (every robot's), which filters gave
one on this tick, why a filter is switched off, each robot's status line; and, for the newest
tick only (:class:`Drawing`), what the world's layers read from the filter objects: each
robot's checked belief, each SLAM filter's ``landmarks()``, each ``associations()`` report, the
step view's beliefs after predict. The window reads these instead of the filters
(:class:`FilterFace` stands for a filter object in ``Session.filters``). Arrays are the
runner's own (never changed after a tick) or fresh copies.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.filters.base import Belief
from beacon_sim.hosting.runner import WINDOW_STEP_LIMIT_S, call_guarded, status_line, validate_belief
from beacon_sim.hosting.team_runner import TeamRunner

#: ``(mean (3,), cov (3, 3))`` of each robot's filter after predict, by filter name (the step view).
Priors = dict[str, tuple[np.ndarray, np.ndarray]]


class FilterFace:
    """Stands for a filter object in a threaded session's ``filters``: what the window's
    layers read of one (``supports_global``, ``landmarks()``, ``associations()``), as the
    filter gave it after the tick shown. A method the filter lacks is absent here too; one
    that raised raises the same exception again."""

    def __init__(self, flt: Any) -> None:
        self.supports_global = bool(getattr(flt, "supports_global", False))
        self._answers: dict[str, tuple[bool, Any]] = {}
        for method in ("landmarks", "associations"):
            call = getattr(flt, method, None)
            if not callable(call):
                continue
            try:
                self._answers[method] = (True, call())
            except Exception as exc:  # a student's method: raised again where it is read
                self._answers[method] = (False, exc)
            setattr(self, method, self._answer(method))

    def _answer(self, method: str) -> Callable[[], Any]:
        def read() -> Any:
            ok, value = self._answers[method]
            if not ok:
                raise value
            return value
        return read


@dataclass
class Drawing:
    """What the world's layers read from the filters of the newest tick, per robot (team
    order): ``beliefs[name][i]`` (checked, or None), ``faces[i][name]``, ``priors[i]``."""

    beliefs: dict[str, list[Belief | None]] = field(default_factory=dict)
    faces: list[dict[str, FilterFace]] = field(default_factory=list)
    priors: list[Priors] = field(default_factory=list)


@dataclass
class FilterTick:
    """The filters after tick ``tick``: ``latest[name]`` every robot's latest estimate
    ``(means (N, 3), covs (N, 3, 3))`` [m, m, rad] or None; ``fresh``: the names with an
    estimate of this tick on every robot; ``failed[name]``: why it is switched off;
    ``warnings[name][i]``: robot i's status line; ``drawing``: None but on the newest tick."""

    tick: int
    latest: dict[str, tuple[np.ndarray, np.ndarray] | None]
    fresh: frozenset[str]
    failed: dict[str, str | None]
    warnings: dict[str, list[str | None]]
    drawing: Drawing | None = None


def read_drawing(run: TeamRunner, switch_off: Callable[[str, str, str], None]) -> Drawing:
    """Every robot's working filters read for drawing, each call under the window's guard
    (``belief()`` checked as ``Session.belief`` checks it; one that raises, hangs or returns
    something unusable is switched off through ``switch_off(name, why, traceback)``)."""
    out = Drawing()
    for runner in run.members:
        faces: dict[str, FilterFace] = {}
        for name, tr in runner.tracks.items():
            out.beliefs.setdefault(name, [])
            bel = None
            if tr.filter is not None and not tr.failed:
                value, why, tb = call_guarded(tr.filter.belief, WINDOW_STEP_LIMIT_S, cpu=True)
                if why is None:
                    checked = validate_belief(value)
                    if isinstance(checked, str):
                        switch_off(name, checked, "")
                    else:
                        bel = checked
                else:
                    switch_off(name, "belief(): " + why, tb)
            out.beliefs[name].append(bel)
            if tr.filter is not None:
                faces[name] = FilterFace(tr.filter)
        out.faces.append(faces)
        out.priors.append(dict(runner.priors))
    for name, tr in run.joint.tracks.items():
        if tr.filter is not None:
            for faces in out.faces:
                faces[name] = FilterFace(tr.filter)
    return out


def filter_tick(run: TeamRunner, names: list[str], tick: int,
                latest: Callable[[str], tuple[np.ndarray, np.ndarray] | None],
                drawing: Drawing | None = None) -> FilterTick:
    """The :class:`FilterTick` of ``run`` just after tick ``tick`` (``latest(name)``: the
    session's estimates, the initial belief before the first tick)."""
    fresh = []
    for name in names:
        tracks = ([r.tracks[name] for r in run.members] if run.is_member(name)
                  else [run.joint.tracks[name]])
        if all(t.ticks and t.ticks[-1] == tick for t in tracks):
            fresh.append(name)
    n = len(run.members)
    return FilterTick(
        tick=tick, latest={name: latest(name) for name in names}, fresh=frozenset(fresh),
        failed={name: run.failed(name) for name in names},
        warnings={name: [status_line(run.track(name, i)) for i in range(n)] for name in names},
        drawing=drawing)


__all__ = ["Drawing", "FilterFace", "FilterTick", "Priors", "filter_tick", "read_drawing"]
