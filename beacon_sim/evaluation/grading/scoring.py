"""From runs to a row: each student's figures per scenario (team, SLAM and scan scenarios
beside their built-in references), the findings of the probes, the rank and status.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.metrics import anees_band
from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.core.sensor_kinds import scan_sensors
from beacon_sim.evaluation.grading.config import GradeConfig
from beacon_sim.evaluation.grading.roster import Student
from beacon_sim.evaluation.grading.rubric import score_row, tracking_figures
from beacon_sim.evaluation.grading.rubric import total as rubric_total
from beacon_sim.evaluation.grading.students import StudentResult
from beacon_sim.evaluation.grading.svg import svg_plot
from beacon_sim.evaluation.grading.tasks import TaskResult
from beacon_sim.evaluation.montecarlo import (
    RunOutput,
    SimulatedRun,
    TeamRunOutput,
    one_run,
)
from beacon_sim.evaluation.slam_metrics import ate, gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, joint_nees_at, mapped_beacons
from beacon_sim.evaluation.summary import Thresholds, evaluate, overall_verdict
from beacon_sim.evaluation.team_summary import evaluate_team
from beacon_sim.hosting.guard import NEES_NOT_FINITE
from beacon_sim.hosting.runner import SLOW_STEP_MS
from beacon_sim.runs.headless import anees_verdict

#: The built-in filter graded beside the students on a SLAM scenario (``[model] map =
#: "unknown"``), in the grader's process on the same simulated runs: the map's reference.
SLAM_REFERENCE_SPEC = "ekf_slam"
#: A SLAM row's figures (docs/grading.md, "A SLAM assignment"): the path's ATE [m], the
#: final map's GOSPA [m] (cut-off ``GOSPA_CUTOFF_M``, as ``run``), its landmarks, missed
#: and false ones, and the final joint NEES (where the filter has ``joint()``), seed means.
#: The built-in filter graded beside the students on a map world with a range finder (a
#: scan-based assignment, docs/maps.md): in the grader's process, on the same seeds.
SCAN_REFERENCE_SPEC = "mcl"
SLAM_FIGURES = ("ate_m", "map_gospa_m", "map_landmarks", "map_missed", "map_false", "joint_nees")


#: A result this far below the bound is "suspicious" (RMSE/PCRB), and an ANEES below this
#: (errors far smaller than the filter's own covariance says: 3 is consistent).
SUSPICIOUS_RMSE_OVER_PCRB = 0.5
SUSPICIOUS_ANEES = 0.1


def add_findings(row: dict[str, Any], res: StudentResult | None) -> None:
    """The row's flags: suspicious (kept out of the ranking), and ``check``'s findings
    (global RNG, deterministic, heading wrapped, readings used, time per step) as columns
    and warnings."""
    flags: list[str] = []
    f = res.findings if res is not None else {}
    row["global_rng"] = f.get("global_rng")
    row["deterministic"] = f.get("deterministic")
    row["heading_wrapped"] = f.get("heading_wrapped") if res is not None else None
    row["readings_used"] = f.get("readings_used")
    row["form"] = f.get("form")
    row["log"] = bool(res and res.log)
    row["suspicious"] = None
    if not row["failed_runs"]:
        ratio, anees = row.get("rmse_over_pcrb"), row.get("anees")
        if ratio is not None and ratio < SUSPICIOUS_RMSE_OVER_PCRB:
            row["suspicious"] = (f"RMSE/PCRB {ratio:.2f} is under {SUSPICIOUS_RMSE_OVER_PCRB:g}: "
                                 "better than the bound allows")
        elif anees is not None and anees < SUSPICIOUS_ANEES:
            row["suspicious"] = (f"ANEES {anees:.3f} is far below its band (3 is consistent): errors "
                                 "far smaller than the filter's own covariance")
    if row["suspicious"]:
        flags.append("suspicious: " + row["suspicious"])
    if row["global_rng"]:
        flags.append("draws from the global np.random / random generator (reproducible here "
                     "only because the grader seeds them from the grade's secret; use ctx.rng)")
    if row["deterministic"] is False:
        flags.append("not deterministic: the same run fed again gives other estimates (or, for a "
                     "filter that draws from the global generators, their seed alone changes them)")
    if row["heading_wrapped"] is False:
        flags.append("heading not wrapped to [-pi, pi)")
    if row["readings_used"] is False:
        flags.append("uses none of the readings: the estimates do not change when the readings are "
                     "drawn again")
    unmapped = [] if row["failed_runs"] else [n for n, v in (row.get("slam") or {}).items()
                                              if not v.get("mapped")]
    if unmapped:
        flags.append(f"no landmarks(): the filter reports no map, so its map is not scored on "
                     f"{', '.join(unmapped)} (docs/slam.md)")
    if row.get("anees_by_scenario"):
        flags.append(row["anees_by_scenario"])
    row["limits_hit"] = limits_hit(row)
    flags += [f"limit hit: {what}" for what in row["limits_hit"]]
    if row.get("us_per_step") is not None and row["us_per_step"] > SLOW_STEP_MS * 1e3:
        flags.append(f"slow: {row['us_per_step'] / 1e3:.0f} ms per step (over {SLOW_STEP_MS:g} ms)")
    row["flags"] = flags


#: The student's limits, by the words of the failure each gives, and how the page names
#: them (each a grade config key, docs/grading.md "Settings").
LIMIT_WORDS = (
    ("time limit: over", "CPU time per run (time_limit; every thread of the filter counts)"),
    ("construction failed: __init__: time limit", "CPU time to build the filter (30 s)"),
    ("total time limit", "total wall time of the student (total_time_s)"),
    ("MemoryError", "memory (memory_limit_gb per run; all the filter's threads together)"),
    ("memory limit", "memory (memory_limit_gb per run; all the filter's threads together)"),
    ("disk limit", "disk (disk_limit_mb: its folder, /tmp and /dev/shm together)"),
    ("No space left on device", "disk (disk_limit_mb: its folder, /tmp and /dev/shm together)"),
    ("started a process", "processes (none may be started: their use cannot be counted)"),
    ("CPU time limit", "CPU time of the student's process (its backstop)"),
)


def limits_hit(row: dict[str, Any]) -> list[str]:
    """The limits a row's failures hit, by :data:`LIMIT_WORDS`, each once, in that order."""
    reasons = [str(f.get("reason") or "") for f in row.get("failures", [])]
    out = []
    for words, name in LIMIT_WORDS:
        if name not in out and any(words in r for r in reasons):
            out.append(name)
    return out


def is_slam_scenario(sc: Scenario | TeamScenario) -> bool:
    """A single-robot scenario whose beacon map is withheld from the filters (docs/slam.md)."""
    return isinstance(sc, Scenario) and not sc.map_known


def run_slam_figures(sc: Scenario, err: np.ndarray, landmarks: tuple[Any, Any, Any] | None,
                     joint: tuple[Any, Any, Any] | None, final_pose: np.ndarray) -> dict[str, Any]:
    """One run's SLAM figures (:data:`SLAM_FIGURES`) from the filter's pose errors ``err``
    (T, 3), its final map ``(ids, means, covs)`` (None: no ``landmarks()``, no map figures)
    and its final ``joint()`` (None: no joint NEES), against the truth of ``sc``."""
    out: dict[str, Any] = dict.fromkeys(SLAM_FIGURES)
    out["ate_m"] = ate(err[:, :2], np.zeros((len(err), 2)))
    if landmarks is not None:
        means = np.asarray(landmarks[1], dtype=float).reshape(-1, 2)
        g = gospa(means, mapped_beacons(sc)[1], c=GOSPA_CUTOFF_M)
        out.update(map_gospa_m=g.value, map_landmarks=len(means), map_missed=g.missed, map_false=g.false)
    if joint is not None:
        try:
            out["joint_nees"] = joint_nees_at(joint, sc, final_pose)[0]
        except (np.linalg.LinAlgError, ValueError, IndexError, KeyError):
            out["joint_nees"] = None  # a singular or malformed joint: not reported
    return out


def _mean_figures(per_run: list[dict[str, Any]]) -> dict[str, Any]:
    """The seed mean of each SLAM figure, None unless every run has it; ATE as the RMS over
    the seeds (the runs are of one length), so that it is the pooled position RMSE the row's
    "pos RMSE" is on that scenario: one quantity, one number."""
    out: dict[str, Any] = {}
    for k in SLAM_FIGURES:
        vals = [r[k] for r in per_run]
        ok = vals and all(v is not None and math.isfinite(v) for v in vals)
        if not ok:
            out[k] = None
        elif k == "ate_m":
            out[k] = float(np.sqrt(np.mean(np.square(vals))))
        else:
            out[k] = float(np.mean(vals))
    return out


def reference_slam_run(sr: SimulatedRun, spec: str = SLAM_REFERENCE_SPEC) -> dict[str, Any] | None:
    """The built-in ``spec`` (EKF-SLAM) fed the simulated run ``sr`` in this process (a
    built-in filter: trusted code; the grader's own pickled ticks), its SLAM figures; None
    when it failed (a built-in that raises or diverges there says nothing of the students)."""
    import pickle

    from beacon_sim.hosting.loading import build_filter

    try:
        flt: Any = build_filter(spec, sr.scenario, sr.seed, name=spec)
        means = np.empty((len(sr.frames), 3))
        for i, frame in enumerate(sr.frames):
            _op, control, dt, meas, _want_prior = pickle.loads(frame[4:])
            flt.predict(control, dt)
            flt.update(meas)
            means[i] = flt.estimate()[0]
        lm = flt.landmarks()
        joint = flt.joint() if callable(getattr(flt, "joint", None)) else None
    except Exception:
        return None
    err = means - sr.truth[1:]
    return run_slam_figures(sr.scenario, err, (lm.ids, lm.means, lm.covs), joint, sr.truth[-1])


def score_slam_reference(sims: list[SimulatedRun], names: list[str]) -> dict[str, dict[str, Any]]:
    """The built-in EKF-SLAM's seed-mean SLAM figures on each SLAM scenario ``names``."""
    out = {}
    for name in names:
        per = [reference_slam_run(sr) for sr in sims if sr.label == name]
        out[name] = ({"filter": SLAM_REFERENCE_SPEC, **_mean_figures(per)} if per and all(per)  # type: ignore[arg-type]
                     else {"filter": SLAM_REFERENCE_SPEC, **dict.fromkeys(SLAM_FIGURES)})
    return out


def is_scan_scenario(sc: Scenario | TeamScenario) -> bool:
    """A single-robot map world (walls) with a range finder: a scan-based assignment."""
    return (isinstance(sc, Scenario) and sc.world.grid is not None
            and bool(scan_sensors(sc.model_sensors)))


def score_scan_reference(scenarios: dict[str, Scenario | TeamScenario], names: list[str],
                    config: GradeConfig) -> dict[str, dict[str, Any]]:
    """The built-in ``mcl``'s figures (position and heading RMSE, ANEES) on each scan
    scenario ``names``, run in process (a built-in filter: trusted) on the config's seeds:
    :func:`~beacon_sim.evaluation.montecarlo.one_run`, the path ``eval`` takes."""
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        sc = scenarios[name]
        assert isinstance(sc, Scenario)
        duration = sc.duration if config.duration is None else config.duration
        try:
            runs = [one_run(sc, [SCAN_REFERENCE_SPEC], {}, seed, duration, index=i)
                    for i, seed in enumerate(config.seeds)]
            fr = evaluate(sc, runs, Thresholds())[0]["filters"][SCAN_REFERENCE_SPEC]
        except Exception:  # a built-in that fails there says nothing of the students
            fr = {}
        out[name] = {"filter": SCAN_REFERENCE_SPEC,
                     **{k: fr.get(k) for k in ("pos_rmse_m", "heading_rmse_rad", "anees")}}
    return out


def team_figures(team: TeamScenario, runs: list[TeamRunOutput]) -> dict[str, Any]:
    """A graded filter's figures on a team scenario (its one team filter): the team's, each
    robot's, its failures, and its first seed's position error averaged over the robots."""
    meta = evaluate_team(team, runs)
    name, fr = next(iter(meta["filters"].items()))
    t = fr["team"]
    err = np.mean([np.hypot(f.err[:, 0], f.err[:, 1]) for f in runs[0].filters[name]], axis=0)
    return {"pos_rmse_m": t["pos_rmse_m"], "heading_rmse_rad": t["heading_rmse_rad"],
            "anees": t["anees"], "anees_verdict": t["anees_verdict"],
            "rmse_over_pcrb": t["rmse_over_pcrb_alone"], "us_per_step": fr["us_per_step"],
            "robots": {rn: {k: v[k] for k in ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict",
                                              "rmse_over_pcrb_alone")}
                       for rn, v in fr["robots"].items()},
            "failures": fr["failures"],
            "curve": (meta["dt"] * np.arange(1, meta["steps"] + 1), err)}


def score_together(scenarios: dict[str, Scenario | TeamScenario], names: list[str],
                    by: dict[tuple[str, str], list[TaskResult]], students: list[Student],
                    n_seeds: int) -> dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]]:
    """Every student's runs of each single-robot scenario scored in one
    :func:`~beacon_sim.evaluation.summary.evaluate` (the bound, the same for all, computed
    once): (student, scenario) -> (its row of figures, its curves, the times). A filter's
    figures depend on its own runs and the truth only, so they are those of scoring it alone."""
    out: dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]] = {}
    for name in names:
        sc = scenarios[name]
        whole = []
        for st in students:
            res = sorted(by.get((st.name, name), []), key=lambda r: r.task.index)
            if len(res) == n_seeds and all(isinstance(r.run, RunOutput) for r in res):
                whole.append((st.name, [r.run for r in res]))
        if not whole:
            continue
        merged = []
        for i in range(n_seeds):
            first: Any = whole[0][1][i]
            run = RunOutput(first.index, first.seed, first.truth, first.controls, first.kidnapped,
                            first.truth_checksum)
            for student, runs in whole:
                run.filters[student] = next(iter(runs[i].filters.values()))  # type: ignore[union-attr,assignment]
            merged.append(run)
        meta, curve = evaluate(sc, merged, Thresholds())  # type: ignore[arg-type]
        for student, _ in whole:
            out[(student, name)] = (meta["filters"][student], curve["filters"][student], curve["time"])
    return out


def student_row(st: Student, config: GradeConfig, scenarios: dict[str, Scenario | TeamScenario],
                 by: dict[tuple[str, str], list[TaskResult]], n_runs: int,
                 reference: dict[str, dict[str, Any]] | None = None,
                 scored: dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]] | None = None,
                 slam_reference: dict[str, dict[str, Any]] | None = None,
                 probe_failures: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    """A student's row; ``probe_failures``: the probes its filter failed on its own (a probe
    is one more run: failing it fails the student, shown as a failed run)."""
    row: dict[str, Any] = {"student": st.name, "file": st.path.name, "runs": n_runs,
                           "pos_rmse_m": None, "heading_rmse_rad": None, "anees": None,
                           "anees_verdict": "FAILED", "verdict": "FAILED", "rmse_over_pcrb": None,
                           "us_per_step": None,
                           "failed_runs": n_runs, "failures": [], "plot": ""}
    if slam_reference:  # a SLAM assignment: the map columns (docs/grading.md)
        row.update(dict.fromkeys(("ate_m", "map_gospa_m", "joint_nees")))
    if st.spec is None:
        row["failures"] = [{"scenario": "-", "seed": None, "time_s": None, "reason": st.problem}]
        return row
    figures: dict[str, list[float]] = {k: [] for k in ("pos_rmse_m", "heading_rmse_rad", "anees",
                                                        "rmse_over_pcrb", "us_per_step")}
    verdicts, failures, curves = [], [], []
    seen: list[str] = []  # the scenarios with a verdict, in order
    tracks: dict[int, list[dict[str, Any]]] = {}
    team_rows: dict[str, Any] = {}
    slam_rows: dict[str, Any] = {}
    for name in config.scenarios:
        res = sorted(by.get((st.name, name), []), key=lambda r: r.task.index)
        for r in res:
            if r.run is None:
                failures.append({"scenario": name, "seed": r.task.seed, "time_s": None,
                                 "reason": r.problem})
        runs = [r.run for r in res if r.run is not None]
        if not runs:
            continue
        sc = scenarios[name]
        if isinstance(sc, TeamScenario):
            tf = team_figures(sc, runs)  # type: ignore[arg-type]
            failures += [{"scenario": name, **f} for f in tf["failures"]]
            for key in figures:
                if tf.get(key) is not None:
                    figures[key].append(float(tf[key]))
            verdicts.append(tf["anees_verdict"])
            seen.append(name)
            curves.append((f"{name} (mean over robots)", *tf["curve"]))
            ref = (reference or {}).get(name, {})
            team_rows[name] = {k: tf[k] for k in ("pos_rmse_m", "heading_rmse_rad", "anees",
                                                  "anees_verdict", "robots")}
            team_rows[name]["reference_pos_rmse_m"] = ref.get("pos_rmse_m")
            team_rows[name]["over_reference"] = (tf["pos_rmse_m"] / ref["pos_rmse_m"]
                                                 if tf["pos_rmse_m"] is not None and ref.get("pos_rmse_m")
                                                 else None)
            continue
        if (st.name, name) in (scored or {}):  # the class's runs scored together (one PCRB)
            fr, c, times = (scored or {})[(st.name, name)]
        else:
            meta, curve = evaluate(sc, runs, Thresholds())  # type: ignore[arg-type]
            fr = next(iter(meta["filters"].values()))
            c, times = next(iter(curve["filters"].values())), curve["time"]
        for f in fr["failures"]:
            failures.append({"scenario": name, **f})
        for key in figures:
            if fr.get(key) is not None:
                figures[key].append(float(fr[key]))
        verdicts.append(fr["anees_verdict"])
        seen.append(name)
        curves.append((name, times, np.hypot(c["err0"][:, 0], c["err0"][:, 1])))
        if slam_reference and name in slam_reference and len(runs) == len(res):
            slam_rows[name] = _slam_row(sc, runs, slam_reference[name])  # type: ignore[arg-type]
    if config.rubric:  # the course's tracking tests: each single-robot run's figures
        for i, item in enumerate(config.rubric):
            if item.test in ("builds", "keeps"):
                tracks[i] = [tracking_figures(next(iter(r.run.filters.values())).err, scenarios[n].dt, item)
                             for n in config.scenarios if not isinstance(scenarios[n], TeamScenario)
                             for r in sorted(by.get((st.name, n), []), key=lambda r: r.task.index)
                             if isinstance(r.run, RunOutput)]
    failures += list(probe_failures)
    if not failures and verdicts and (not figures["anees"] or not all(map(math.isfinite, figures["anees"]))):
        # a working filter without a finite ANEES is never "ok": the guard's words
        failures.append({"scenario": "-", "seed": None, "time_s": None, "reason": NEES_NOT_FINITE})
    row["failures"] = failures
    row["failed_runs"] = len(failures)
    row["run_detail"] = _run_detail(st, config, by)
    if team_rows:
        row["team"] = team_rows
    if slam_rows:
        row["slam"] = slam_rows
    row["us_per_step"] = float(np.mean(figures["us_per_step"])) if figures["us_per_step"] else None
    row["plot"] = svg_plot(curves) if curves else ""
    if not failures:
        for key in ("pos_rmse_m", "heading_rmse_rad", "anees", "rmse_over_pcrb"):
            row[key] = float(np.mean(figures[key])) if figures[key] else None
        row["anees_verdict"], scen_flag = row_anees_verdict(row["anees"], verdicts, figures["anees"],
                                                            [n for n in config.scenarios if n in seen],
                                                            len(config.seeds))
        if scen_flag:
            row["anees_by_scenario"] = scen_flag
        # what the page shows: the ANEES word with the distance from the bound, so
        # no row says a bare "consistent" beside an error over twice the bound
        row["verdict"] = overall_verdict(row["anees_verdict"], row["rmse_over_pcrb"])
        for key in ("ate_m", "map_gospa_m", "joint_nees"):  # over the SLAM scenarios
            vals = [v[key] for v in slam_rows.values()]
            if slam_rows:
                row[key] = float(np.mean(vals)) if all(v is not None for v in vals) else None
    if tracks:
        row["rubric_tracking"] = tracks
    return row


def add_rubric(row: dict[str, Any], config: GradeConfig) -> None:
    """The course's rubric on a finished row (after :func:`add_findings`: a suspicious row
    gets no points): ``rubric`` (the tests), ``rubric_score`` and ``rubric_max``."""
    if not config.rubric:
        return
    row["rubric"] = score_row(row, config.rubric, row.get("rubric_tracking") or {})
    row["rubric_score"] = rubric_total(row["rubric"])
    row["rubric_max"] = float(sum(item.points for item in config.rubric))


def _slam_row(sc: Scenario, runs: list[RunOutput], ref: dict[str, Any]) -> dict[str, Any]:
    """A student's SLAM figures on one SLAM scenario (seed means, :data:`SLAM_FIGURES`),
    the reference's beside them, and whether the filter reported a map at all."""
    per = []
    mapped = True
    for run in runs:
        fr = next(iter(run.filters.values()))
        mapped &= fr.landmarks is not None
        per.append(run_slam_figures(sc, fr.err, fr.landmarks, fr.joint, run.truth[-1]))
    out = _mean_figures(per)
    out["mapped"] = mapped
    for key in ("ate_m", "map_gospa_m", "joint_nees"):
        out["reference_" + key] = ref.get(key)
    g, rg = out["map_gospa_m"], ref.get("map_gospa_m")
    out["gospa_over_reference"] = g / rg if g is not None and rg else None
    return out


def _run_detail(st: Student, config: GradeConfig, by: dict[tuple[str, str], list[TaskResult]]
                ) -> list[dict[str, Any]]:
    """One line per run of a student (the student's page): scenario, seed, position RMSE
    [m] over the steps it ran, steps, cost [us/step], and why it failed."""
    out = []
    for name in config.scenarios:
        for r in sorted(by.get((st.name, name), []), key=lambda r: r.task.index):
            line: dict[str, Any] = {"scenario": name, "seed": r.task.seed, "pos_rmse_m": None,
                                    "steps": 0, "us_per_step": None, "failed": r.problem}
            if isinstance(r.run, RunOutput):
                fr = next(iter(r.run.filters.values()))
                e = fr.err[np.isfinite(fr.err[:, 0]) & np.isfinite(fr.err[:, 1])]
                rmse = float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))) if len(e) else None
                line.update(pos_rmse_m=rmse, steps=int(fr.steps),
                            us_per_step=fr.step_ns / 1e3 / max(fr.steps, 1), failed=fr.failed)
            out.append(line)
    return out


def row_anees_verdict(anees: float | None, verdicts: list[str], per_scenario: list[float],
                      names: list[str], n_seeds: int) -> tuple[str, str | None]:
    """The row's consistency word for the row's ANEES, by the one rule every front end uses
    (:func:`~beacon_sim.runs.headless.anees_verdict` against the band of the runs it
    averages): one scenario, its own verdict; several, the mean judged against the band of
    all their runs, never a list of words beside a number only one of them fits
    ("consistent/optimistic" beside ANEES 30,884). Also, when the scenarios' words differ,
    each scenario's ANEES and word (shown as a warning)."""
    if len(verdicts) == 1:
        return verdicts[0], None
    if anees is None or not math.isfinite(anees):
        return "FAILED", None
    lo, hi = anees_band(n_seeds * len(verdicts))
    word = anees_verdict(anees, lo, hi)
    if len(set(verdicts)) == 1:
        return word, None
    parts = [f"{n} {v:,.2f} ({w})" for n, v, w in zip(names, per_scenario, verdicts, strict=False)]
    return word, "ANEES by scenario: " + "; ".join(parts)


def rank_key(row: dict[str, Any]) -> tuple:
    """Working filters first by position RMSE, then suspicious ones (kept out of the
    ranking), then failed ones (fewest failed runs first): a failed filter never ranks
    above a working one."""
    failed = row["failed_runs"] > 0
    rmse = row["pos_rmse_m"] if row["pos_rmse_m"] is not None else math.inf
    return (failed, bool(row.get("suspicious")), row["failed_runs"] if failed else 0, rmse,
            row["student"])


def status(row: dict[str, Any]) -> str:
    """FAILED (no score), SUSPICIOUS (kept out of the ranking) or ok."""
    if row["failed_runs"]:
        return "FAILED"
    return "SUSPICIOUS" if row.get("suspicious") else "ok"
