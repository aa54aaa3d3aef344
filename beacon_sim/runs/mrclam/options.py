"""How a MRCLAM run feeds and scores its filters, besides which filters and what noise: one
typed record (:class:`MrclamOptions`) in place of mode flags passed down separately."""

from __future__ import annotations

from dataclasses import dataclass

from beacon_sim.io.mrclam import MrclamError


@dataclass(frozen=True)
class MrclamOptions:
    """The modes of a MRCLAM run.

    ``dt``: None feeds one robot's odometry and readings interleaved by time stamp; a number
    [s] puts every robot on one clock of ``dt`` (a team run's clock is ``TEAM_DT`` unless
    given). ``unknown_ids`` (one robot, by time stamp): the readings reach the filters without
    their barcodes, which only score the filters' associations. ``slam`` (one robot, by time
    stamp): the SLAM filters are not given the landmark map. ``record_maps``: keep every SLAM
    filter's map after each update, for the window. ``graph`` (with ``slam``, barcodes):
    graph SLAM solved over the whole run too (``graph_slam.py``), one more track.
    """

    dt: float | None = None
    unknown_ids: bool = False
    slam: bool = False
    record_maps: bool = False
    graph: bool = False

    def by_time_stamps(self, n_robots: int) -> bool:
        """Whether a run of ``n_robots`` robots is fed by time stamp (else on a clock)."""
        return n_robots == 1 and self.dt is None

    def check(self, n_robots: int) -> None:
        """:class:`MrclamError` when a one-robot mode is asked of a team or of a clock."""
        if self.unknown_ids and not self.by_time_stamps(n_robots):
            raise MrclamError("--unknown-ids runs one robot by its time stamps: use --robot N, not --team")
        if self.slam and not self.by_time_stamps(n_robots):
            raise MrclamError("--slam runs one robot by its time stamps: use --robot N, not --team "
                              "(the team filters are localization filters; none maps landmarks)")
        if self.graph and not self.slam:
            raise MrclamError("--graph is graph SLAM: give --slam too")
        if self.graph and self.unknown_ids:
            raise MrclamError("--graph needs the readings' barcodes (its graph has no data "
                              "association): drop --unknown-ids")
