"""Readings given to the filters without their landmark IDs (``--unknown-ids``): how each
filter associated them, scored against the barcodes the data set recorded."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.runs.mrclam.scenario import SENSOR_NAME


@dataclass
class AssociationCount:
    """One filter's associations of the readings it was given without IDs (``--unknown-ids``),
    scored against the barcodes the data set recorded (which the filter never saw).

    ``correct``: given the landmark whose barcode the camera read; ``false``: given another
    landmark; ``missed``: given none (dropped as clutter). ``readings`` = their sum: the rows
    of the updates after which the filter reported ``associations()`` for the camera.
    ``times_s`` and ``hits``: per scored row, its time from the run's start [s] and whether it
    was correct, for intervals over blocks of the run (:meth:`block_sums`)."""

    readings: int = 0
    correct: int = 0
    false: int = 0
    missed: int = 0
    times_s: list[float] = field(default_factory=list, repr=False)
    hits: list[bool] = field(default_factory=list, repr=False)

    @property
    def fraction_correct(self) -> float:
        """Share of the scored readings given the right landmark (nan with none)."""
        return self.correct / self.readings if self.readings else math.nan

    def add(self, given: Sequence[int | None], truth: np.ndarray, time_s: float = math.nan) -> None:
        """Count one reading's rows: ``given`` per row (landmark ID or None), ``truth`` the
        barcodes, ``time_s`` [s] the reading's time from the run's start."""
        for g, t in zip(given, truth.tolist(), strict=True):
            self.readings += 1
            hit = g is not None and int(g) == int(t)
            if g is None:
                self.missed += 1
            elif hit:
                self.correct += 1
            else:
                self.false += 1
            self.times_s.append(float(time_s))
            self.hits.append(hit)

    def block_sums(self, block_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Per ``block_s``-second block of the run that holds scored rows: (correct rows, rows),
        for a block-bootstrap interval of :attr:`fraction_correct`."""
        t = np.asarray(self.times_s, dtype=float)
        if not t.size or not np.all(np.isfinite(t)):
            return np.zeros(0), np.zeros(0)
        blk = np.floor((t - t.min()) / block_s).astype(int)
        rows = np.bincount(blk).astype(float)
        hits = np.bincount(blk, np.asarray(self.hits, dtype=float))
        keep = rows > 0
        return hits[keep], rows[keep]

    def as_json(self) -> dict[str, float]:
        return {"readings": self.readings, "correct": self.correct, "false": self.false,
                "missed": self.missed, "fraction_correct": self.fraction_correct}


def score_associations(runners: Sequence[TeamRunner], truth: np.ndarray, time_s: float,
                       scores: dict[str, AssociationCount]) -> None:
    """After an update with hidden IDs: each working filter's ``associations()`` for the camera
    against the barcodes ``truth`` of the rows it was given (in the order given). A filter
    without the method is not scored; one whose method raises is switched off."""
    for runner in runners:
        for name, track in runner.members[0].tracks.items():
            report = getattr(track.filter, "associations", None)
            if track.failed or report is None:
                continue
            try:
                given = report()
            except Exception as exc:  # the filter's own method: switched off, never scored
                runner.fail(name, f"associations() raised {type(exc).__name__}: {exc}"[:200], "", time_s)
                continue
            rows = given.get(SENSOR_NAME) if isinstance(given, dict) else None
            if rows is not None and len(rows) == len(truth):
                scores.setdefault(name, AssociationCount()).add(tuple(rows), truth, time_s)
