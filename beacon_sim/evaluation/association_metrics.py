"""How well filters associate readings without IDs, and what their mistakes cost.

A scenario whose sensors say ``correspondence = "unknown"`` is run once as it is; after every
update each filter's ``associations()`` (``FilterBase``; for each reading without IDs, the
beacon it was given to, or None) is compared row by row with the truth the simulation keeps
aside (``Step.true_ids``, -1 for clutter). The same scenario, seed and filters are then run
with every sensor's correspondence known (and no clutter): the truth and the real readings are
the same draws (clutter and the shuffle have streams of their own), so the difference in
position RMSE is what association costs.

Per reading row, with ``t`` the true beacon (-1: clutter) and ``g`` the one given (None: none):

- correct: ``g == t``, or ``t`` clutter and ``g`` None;
- false association: ``g`` is a beacon and not ``t`` (clutter given a beacon counts here);
- missed: ``g`` None while ``t`` is a beacon.

``beacon-sim run SCENARIO --associations`` prints :func:`format_scores` after the run's summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filters, filter_names
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner, failure_text


@dataclass
class AssociationScore:
    """One filter's association figures over a run.

    Attributes
    ----------
    readings : int
        Reading rows without IDs the filter reported on (clutter included).
    correct, false, missed : int
        See the module docstring; ``correct + false + missed == readings``.
    clutter : int
        Of the readings, how many were clutter.
    rmse : float
        Position RMSE [m] of the run with unknown correspondence.
    rmse_known : float
        Position RMSE [m] of the same run with known correspondence (nan when that failed).
    failed : str or None
        Why the filter was switched off (then it gets no score), in either run.
    reported : bool
        Whether the filter reports associations at all (an ``associations()`` method).
    """

    readings: int = 0
    correct: int = 0
    false: int = 0
    missed: int = 0
    clutter: int = 0
    rmse: float = math.nan
    rmse_known: float = math.nan
    failed: str | None = None
    reported: bool = True

    @property
    def fraction_correct(self) -> float:
        """Share of the readings associated correctly (nan with no readings)."""
        return self.correct / self.readings if self.readings else math.nan

    @property
    def rmse_cost(self) -> float:
        """What association cost in position RMSE [m]: ``rmse - rmse_known``."""
        return self.rmse - self.rmse_known

    def add(self, given: tuple[int | None, ...], truth: np.ndarray) -> None:
        """Count one reading's rows: ``given`` per row (beacon ID or None), ``truth`` (-1 clutter)."""
        for g, t in zip(given, truth.tolist(), strict=True):
            self.readings += 1
            self.clutter += t < 0
            if (g is None and t < 0) or g == t:
                self.correct += 1
            elif g is None:
                self.missed += 1
            else:
                self.false += 1


def with_known_correspondence(scenario: Scenario) -> Scenario:
    """``scenario`` with every sensor's IDs told and no clutter (the same truth and readings)."""
    def known(sensors):
        return tuple(replace(s, correspondence="known", clutter_rate=0.0) for s in sensors)
    return replace(scenario, sensors=known(scenario.sensors), model_sensors=known(scenario.model_sensors))


def has_unknown_correspondence(scenario: Scenario) -> bool:
    """Whether any sensor of ``scenario`` hides its beacon IDs."""
    return any(s.correspondence != "known" for s in scenario.sensors)


def _run(scenario: Scenario, specs: list[str], seed: int, duration: float,
         params: dict[str, dict[str, Any]] | None, scores: dict[str, AssociationScore] | None
         ) -> tuple[dict[str, float], dict[str, str | None], str]:
    """One run; counts associations into ``scores`` when given. Returns per filter the
    position RMSE [m] and the failure (None), and the truth checksum."""
    built, broken = build_filters(specs, scenario, seed, params)
    runner = FilterRunner(built, step_limit_s=HEADLESS_STEP_LIMIT_S)
    for name, (message, tb) in broken.items():
        runner.tracks[name].failed, runner.tracks[name].traceback = message, tb
    sim = Simulation(scenario, seed)
    truth: dict[int, np.ndarray] = {}
    for _ in range(round(duration / scenario.dt)):
        step = sim.step()
        truth[step.tick] = step.true_pose[:2]
        runner.feed(step)
        if scores is None or not step.true_ids:
            continue
        for name, track in runner.tracks.items():
            report = getattr(track.filter, "associations", None)
            if track.failed or report is None:
                scores[name].reported = report is not None
                continue
            try:
                given = report()
            except Exception as exc:  # a filter's own method: its report is not scored
                runner.fail(name, f"associations() raised {type(exc).__name__}: {exc}"[:200], "",
                            step.time)
                continue
            for sensor, ids in step.true_ids.items():
                rows = given.get(sensor) if isinstance(given, dict) else None
                if rows is not None and len(rows) == len(ids):
                    scores[name].add(tuple(rows), ids)
    rmse: dict[str, float] = {}
    failed: dict[str, str | None] = {}
    for name, track in runner.tracks.items():
        failed[name] = failure_text(track)
        if track.means:
            err = np.array([m[:2] for m in track.means]) - np.array([truth[k] for k in track.ticks])
            rmse[name] = float(np.sqrt(np.mean(np.sum(err * err, axis=1))))
        else:
            rmse[name] = math.nan
    return rmse, failed, sim.truth_checksum


def association_scores(scenario: Scenario, filters: list[str] | None = None, seed: int | None = None,
                       duration: float | None = None, params: dict[str, dict[str, Any]] | None = None
                       ) -> dict[str, AssociationScore]:
    """Each filter's :class:`AssociationScore` on ``scenario`` (its default filters, seed and
    duration unless given): one run as it is, one with known correspondence."""
    seed = scenario.seed if seed is None else seed
    duration = scenario.duration if duration is None else duration
    specs = list(scenario.default_filters if filters is None else filters)
    scores = {name: AssociationScore() for name in filter_names(specs)}
    rmse, failed, checksum = _run(scenario, specs, seed, duration, params, scores)
    rmse_k, failed_k, checksum_k = _run(with_known_correspondence(scenario), specs, seed, duration,
                                        params, None)
    if checksum != checksum_k:  # the two runs must share their truth, or the cost means nothing
        raise RuntimeError(f"truth differs with known correspondence ({checksum} != {checksum_k})")
    for name, s in scores.items():
        s.failed = failed[name] or (failed_k[name] and f"with known correspondence: {failed_k[name]}")
        s.rmse, s.rmse_known = rmse[name], rmse_k[name]
    return scores


def format_scores(scores: dict[str, AssociationScore]) -> str:
    """The table ``beacon-sim run --associations`` prints."""
    lines = [f"{'association':<16}{'readings':>9}{'correct':>9}{'false':>7}{'missed':>7}"
             f"{'clutter':>8}{'RMSE m':>9}{'known m':>9}{'cost m':>9}"]
    for name, s in scores.items():
        if s.failed:
            lines.append(f"{name:<16}failed: {s.failed} (no score)")
        elif not s.reported:
            lines.append(f"{name:<16}reports no associations (no associations() method)"
                         f"{s.rmse:>9.3f}{s.rmse_known:>9.3f}{s.rmse_cost:>+9.3f}")
        else:
            frac = f"{100 * s.fraction_correct:.1f}%" if s.readings else "-"
            lines.append(f"{name:<16}{s.readings:>9}{frac:>9}{s.false:>7}{s.missed:>7}{s.clutter:>8}"
                         f"{s.rmse:>9.3f}{s.rmse_known:>9.3f}{s.rmse_cost:>+9.3f}")
    return "\n".join(lines)


@dataclass(frozen=True)
class AssociationReport:
    """What ``run --associations`` prints: the table (``text``) or, with ``--json``, the
    per-filter figures (``json``: filter -> figures, None when nothing hides IDs)."""

    text: str
    json: dict[str, dict[str, Any]] | None


def scores_json(scores: dict[str, AssociationScore]) -> dict[str, dict[str, Any]]:
    """Per filter, its figures as plain numbers (a failed filter: only ``failed``)."""
    out: dict[str, dict[str, Any]] = {}
    for name, s in scores.items():
        if s.failed:
            out[name] = {"failed": s.failed}
            continue
        out[name] = {"reported": s.reported, "readings": s.readings, "correct": s.correct,
                     "false": s.false, "missed": s.missed, "clutter": s.clutter,
                     "fraction_correct": None if not s.readings else s.fraction_correct,
                     "rmse_m": s.rmse, "rmse_known_m": s.rmse_known, "rmse_cost_m": s.rmse_cost}
    return out


def association_report(scenario: Scenario, filters: list[str] | None = None, seed: int | None = None,
                       duration: float | None = None, params: dict[str, dict[str, Any]] | None = None
                       ) -> AssociationReport:
    """:func:`format_scores` and :func:`scores_json` of :func:`association_scores`, or a line
    saying there is nothing to score (every sensor's correspondence known)."""
    if not has_unknown_correspondence(scenario):
        return AssociationReport("association: every sensor of this scenario tells its beacon IDs "
                                 "(nothing to score)", None)
    scores = association_scores(scenario, filters, seed, duration, params)
    return AssociationReport(format_scores(scores), scores_json(scores))
