"""The SLAM filters of a MRCLAM run (``--slam``): which filters are not given the landmark
map (:func:`map_withheld`), and each one's map after every update (:class:`MapHistory`),
for the window to draw."""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from beacon_sim.filters.base import LandmarkMap
from beacon_sim.hosting.team_runner import TeamRunner


@dataclass
class MapHistory:
    """One SLAM filter's map after each update of a run (``--slam`` shown in the window):
    the data set times [s] and the :class:`~beacon_sim.filters.base.LandmarkMap` then."""

    times: list[float] = field(default_factory=list)
    maps: list[LandmarkMap] = field(default_factory=list)

    def at(self, t: float) -> LandmarkMap | None:
        """The latest map at or before time ``t`` [s]; None before the first."""
        i = bisect.bisect_right(self.times, t) - 1
        return self.maps[i] if i >= 0 else None


def snapshot_maps(runners: Sequence[TeamRunner], t: float, t_start: float,
                  maps: dict[str, MapHistory]) -> None:
    """Every working single-robot filter's ``landmarks()`` at data set time ``t`` [s] into
    ``maps``; a filter whose method raises is switched off (it would not be drawn either)."""
    for runner in runners:
        for name, track in runner.members[0].tracks.items():
            report = getattr(track.filter, "landmarks", None)
            if track.failed or not callable(report):
                continue
            try:
                lm = report()
                snap = LandmarkMap(None if lm.ids is None else np.array(lm.ids).copy(),
                                   np.array(lm.means, dtype=float).reshape(-1, 2),
                                   np.array(lm.covs, dtype=float).reshape(-1, 2, 2))
            except Exception as exc:  # the filter's own method: switched off
                runner.fail(name, f"landmarks() raised {type(exc).__name__}: {exc}"[:200], "", t - t_start)
                continue
            hist = maps.setdefault(name, MapHistory())
            hist.times.append(float(t))
            hist.maps.append(snap)


#: The filters of ``--slam`` unless others are named: EKF-SLAM and FastSLAM 2.0 (no map),
#: and the EKF given the surveyed map, for comparison.
SLAM_MRCLAM_FILTERS = ("ekf_slam", "fastslam", "ekf")


def map_withheld(spec: str) -> bool:
    """Whether ``--slam`` withholds the map from filter ``spec``: a SLAM filter (its class has
    ``landmarks()``, docs/slam.md) maps the landmarks itself; any other filter keeps the
    surveyed map (it could not run without it) and is the known-map reference."""
    from beacon_sim.hosting.loading import load_filter_class

    return callable(getattr(load_filter_class(spec), "landmarks", None))
