"""Replaying a recording bit for bit, with the recorded filters or any others, over any
number of robots (a single robot's file is a team of one).

The one home of "how a recording is replayed": :func:`replay_recording` re-simulates a
file headless and checks its checksums; :class:`ReplaySession` is the same, one tick at a
time, for the window. The file format is beacon_sim/io/recording/ (and docs/replay.md). The
filters' checks are runs/replay_filters.py, the tick's checks runs/replay_checks.py, the
window's session runs/replay_session.py; their names are re-exported here.

Each tick goes as it went live: the recorded user commands (a kidnap of the robot it names,
a reset of the filters), then every robot steps, the recorded driven robot on its recorded
command (or, on a team's file where its own driver chose it live, that driver again, so the
driver's state follows), the others on their drivers; then the filters are fed
(:class:`~beacon_sim.hosting.team_runner.TeamRunner`: each single-robot filter on each
robot, each team filter once). A recording never makes beacon-sim import code: only
built-in filters and installed entry points are run from a file
(:func:`is_builtin_spec`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.io.recording import Recording
from beacon_sim.runs.headless import RunResult
from beacon_sim.runs.replay_checks import (
    ReplayedTruth,
    autopilot_mismatch,
    checksums_mismatch,
    end_estimates,
    first_bad_tick,
    inputs_differ,
    mismatch_error,
    recorded_controls,
    tick_checked,
    verification_status,
    with_signature,
)
from beacon_sim.runs.replay_filters import (
    FilterVerifier,
    ReplayMismatch,
    default_params,
    is_builtin_spec,
    recorded_filter_specs,
    recorded_names,
    recorded_params,
    replay_verifier,
    settings_compared,
    settings_error,
    skipped_note,
    without_added_defaults,
)
from beacon_sim.runs.replay_session import ReplaySession, replay_label, session_status
from beacon_sim.runs.user_commands import apply_to_run


def replay_recording(recording: Recording, filters: list[str] | None = None,
                     params: dict[str, dict[str, Any]] | None = None,
                     verify: bool = True, *,
                     on_tick: Callable[[Any, TeamRunner], None] | None = None) -> RunResult:
    """Re-simulate a recording of any number of robots, feeding the filters; check the
    truth, the readings and (a version 3 file, the recorded filters) the filter settings
    and estimates against the file.

    ``filters`` None runs the recorded built-in filters with the recorded parameters
    (filters named by module or file path are skipped: pass them explicitly). Raises
    :class:`ReplayMismatch` naming the first tick (or line) and the field that differs.
    Returns what ``run`` gives on the recording's scenario, a
    :class:`~beacon_sim.runs.headless.RunResult` over its robots, with ``extra["replay"]``:
    what was checked (file, ticks, checksum status, skipped filters, warnings).
    ``on_tick(step, runner)`` is called after the filters took each tick (an export reads
    their beliefs there).
    """
    specs, skipped = recorded_filter_specs(recording, filters)
    used = recorded_params(recording, params)
    runner = TeamRunner(recording.team, specs, recording.seed, used,
                        step_limit_s=HEADLESS_STEP_LIMIT_S)
    verifier = replay_verifier(recording, runner, specs, used)
    if verify:
        why = verifier.check_settings()
        if why is not None:
            raise settings_error(recording, why)
    sim = TeamSimulation(recording.team, recording.seed)
    truth = ReplayedTruth(recording, sim)
    steps: list[TeamStep] = []
    checked = 0
    t0 = time.perf_counter()
    sim_ns = 0
    estimates = recording.parts.estimates
    unverified: str | None = None  # a file of unknown maths whose truth differs: why
    for rec in recording.ticks:
        a = time.perf_counter_ns()
        apply_to_run(rec.commands, sim, runner, HEADLESS_STEP_LIMIT_S, sim.time)
        step = sim.step(recorded_controls(rec))
        truth.observe(step)
        sim_ns += time.perf_counter_ns() - a
        if verify and unverified is None:
            why, bad = autopilot_mismatch(rec, step) or truth.tick_mismatch(rec), rec.tick
            cp = recording.checkpoints.get(rec.tick)
            if why is None and cp is not None and truth.state_differs(cp):
                why, bad = "the checkpoint", first_bad_tick(recording, rec.tick)
            if why is not None:
                unverified = inputs_differ(recording, bad, rec.line, why)
            checked += tick_checked(recording, rec)
        steps.append(step)
        runner.feed(step)
        if on_tick is not None:
            on_tick(step, runner)
        if verify and unverified is None:
            line = estimates.get(rec.tick)
            verifier.fold(rec.tick)
            why = verifier.compare_line(rec.tick, line)
            if why is not None:
                raise mismatch_error(recording, rec.tick, line["line"] if line else rec.line, why)
    wall = time.perf_counter() - t0
    end = recording.end
    if verify and unverified is None and end is not None \
            and (end.get("ticks") != sim.tick or truth.state_differs(end)):
        unverified = inputs_differ(recording, sim.tick, len(recording.ticks), "the final checksum")
    if verify and unverified is None and end is not None and "estimates" in end:
        why = verifier.compare_line(sim.tick, end_estimates(end))
        if why is not None:
            raise mismatch_error(recording, sim.tick, len(recording.ticks), why + " at the end")
    status = unverified or verification_status(recording, checked, len(recording.ticks),
                                               at_end=True, coverage=verifier.coverage())
    replay = {
        "file": str(recording.path), "ticks": len(recording.ticks), "complete": recording.complete,
        "checksum_status": with_signature(status, recording) if verify else "not checked",
        "recorded_checksum": end["checksum"] if end else None,
        "skipped_filters": skipped, "warnings": list(recording.warnings),
        "maths": verifier.maths.as_json(),
        "estimate_differences": {n: d.as_json() for n, d in sorted(verifier.differences.items())},
    }
    out = RunResult(recording.team, recording.seed, steps, runner, wall, sim_ns / 1e9, truth.truth)
    out.extra["replay"] = replay
    return out


__all__ = ["FilterVerifier", "ReplayMismatch", "ReplaySession", "ReplayedTruth",
           "autopilot_mismatch", "checksums_mismatch", "default_params", "end_estimates",
           "inputs_differ", "is_builtin_spec", "mismatch_error", "recorded_controls",
           "recorded_filter_specs", "recorded_names", "recorded_params", "replay_label",
           "replay_recording", "replay_verifier", "session_status", "settings_compared",
           "settings_error", "skipped_note", "tick_checked", "verification_status",
           "with_signature", "without_added_defaults"]
