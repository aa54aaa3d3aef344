"""One run with every filter object in this process on its steps (:func:`one_run`), and
a team scenario's run over N robots (:func:`team_one_run`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.evaluation.metrics import nis_batch
from beacon_sim.evaluation.montecarlo.records import RunOutput, TeamRunOutput, finish_filter
from beacon_sim.evaluation.montecarlo.simulation import start_run
from beacon_sim.filters.base import FilterError
from beacon_sim.hosting.guard import estimate_arrays
from beacon_sim.hosting.host import call_guarded
from beacon_sim.hosting.loading import (
    build_filter,
    filter_display_name,
    filter_names,
)
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S
from beacon_sim.hosting.watchdog import failure_line, is_filter_failure
from beacon_sim.runs.headless import run_headless


def one_run(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]],
            seed: int, duration: float, index: int = 0, keep_means: bool = False,
            run_limit_s: float | None = None, secret: bytes | None = None) -> RunOutput:
    """Simulate one run and feed every filter the same steps.

    Each filter's cost counts ``predict + update + estimate``; the prior estimate read for
    the NIS between predict and update is not counted. ``run_limit_s`` [s]: a filter whose
    steps take longer than this in all is stopped ("time limit"; an endless loop), see
    ``hosting.runner.time_limit``. ``secret``: the key of the filters' random streams
    (None: the public key; a grade's secret gives its figures,
    :func:`~beacon_sim.core.streams.filter_stream`).
    """
    names = filter_names(specs)
    built: dict[str, Any] = {}
    failed: dict[str, str | None] = dict.fromkeys(names)
    for name, spec in zip(names, specs, strict=True):
        try:
            built[name] = build_filter(spec, scenario, seed, name=name,
                                       params=params.get(filter_display_name(spec)), secret=secret)
        except FilterError:
            raise  # a name or parameter that cannot work: one line, exit 2
        except BaseException as exc:  # a student's __init__ or reset: that filter fails
            if not is_filter_failure(exc):
                raise
            failed[name] = f"construction failed: {_failure_text(exc)}"
    sensors = {s.name: s for s in scenario.model_sensors}
    world = scenario.world
    sim, T, truth, controls, kidnapped = start_run(scenario, seed, duration)
    means = {n: np.full((T, 3), np.nan) for n in names}
    covs = {n: np.full((T, 3, 3), np.nan) for n in names}
    records: list = []  # measurements of the ticks that had any
    priors = {n: (np.full((T, 3), np.nan), np.full((T, 3, 3), np.nan)) for n in names}
    ns = dict.fromkeys(names, 0)
    cpu = dict.fromkeys(names, 0)  # CPU time of each filter's steps [ns]: the run limit's budget
    done = dict.fromkeys(names, 0)
    cpu_clock = time.thread_time_ns
    over = None if run_limit_s is None else f"time limit: over {run_limit_s:g} s of filter time in the run"
    for i in range(T):
        step = sim.step()
        truth[i + 1] = step.true_pose
        controls[i] = (step.control.v, step.control.omega)
        kidnapped[i] = step.kidnapped
        j = len(records)
        if step.measurements:
            records.append(step.measurements)
        for name, f in built.items():
            if failed[name]:
                continue
            left = None if run_limit_s is None else run_limit_s - cpu[name] / 1e9
            c0 = cpu_clock()
            got, why, _ = call_guarded(lambda: _timed_step(f, step), left, cpu=True,  # noqa: B023
                                       over=over)
            cpu[name] += cpu_clock() - c0
            if why is not None:  # a user's filter: switch it off, go on with the others
                failed[name] = why
                continue
            wall, prior, est = got  # type: ignore[misc]
            why = _store(est, means[name], covs[name], i)
            if why is None and prior is not None:
                why = _store(prior, priors[name][0], priors[name][1], j)
                why = None if why is None else "after predict: " + why
            if why is not None:  # a wrong shape or type: the guard's plain message
                failed[name] = why
                continue
            ns[name] += wall
            done[name] += 1
    out = RunOutput(index, seed, truth, controls, kidnapped, sim.truth_checksum)
    n_rec = len(records)
    for name in names:
        pm, pc = priors[name]
        good = np.all(np.isfinite(pm[:n_rec]), axis=1) & np.all(np.isfinite(pc[:n_rec]), axis=(1, 2))
        n_good = int(np.argmin(good)) if not good.all() else n_rec
        with np.errstate(all="ignore"):
            nis_sum, nis_dof = nis_batch(records[:n_good], pm[:n_good], pc[:n_good], sensors, world)
        out.filters[name] = finish_filter(means[name], covs[name], truth, done[name], failed[name],
                                          nis_sum, nis_dof, ns[name], keep_means)
    return out


def _store(est: object, means: np.ndarray, covs: np.ndarray, i: int) -> str | None:
    """Write ``est`` (a ``(mean (3,), cov (3, 3))`` pair) into row ``i`` of ``means`` and
    ``covs``; its values are judged later (:func:`finish_filter`). Anything else: the
    guard's one plain line (a wrong shape says so, not numpy's "could not broadcast")."""
    got = estimate_arrays(est)
    if isinstance(got, str):
        return got
    means[i], covs[i] = got
    return None


def _timed_step(f: Any, step: Any) -> tuple[int, Any, Any]:
    """One step of one filter: (wall time of predict + update + estimate [ns], the estimate
    after predict when the tick has readings (for the NIS, not timed) or None, the
    estimate)."""
    clock = time.perf_counter_ns
    t0 = clock()
    f.predict(step.control, step.dt)
    t1 = clock()
    prior = f.estimate() if step.measurements else None
    t2 = clock()
    f.update(step.measurements)
    est = f.estimate()
    t3 = clock()
    return (t1 - t0) + (t3 - t2), prior, est


def _failure_text(exc: BaseException) -> str:
    """One line for what a filter's code raised (SystemExit and KeyboardInterrupt included)."""
    return failure_line(exc)


def team_one_run(team: TeamScenario, specs: list[str], params: dict[str, dict[str, Any]] | None,
                 seed: int, duration: float, index: int = 0,
                 step_limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                 run_limit_s: float | None = None, secret: bytes | None = None) -> TeamRunOutput:
    """One guarded headless run over N robots reduced to arrays; the limits and ``secret``
    as :func:`~beacon_sim.runs.headless.run_headless`'s. A filter's time is its time per
    tick over every robot."""
    res = run_headless(team, specs, seed=seed, duration=duration, params=params,
                       step_limit_s=step_limit_s, run_limit_s=run_limit_s, secret=secret)
    T, N = len(res.team_steps), team.n_robots
    truth = np.empty((T + 1, N, 3))
    truth[0] = res.initial_poses
    truth[1:] = res.true_poses
    kidnapped = np.array([[st.kidnapped for st in s.steps] for s in res.team_steps],
                         dtype=bool).reshape(T, N)
    out = TeamRunOutput(index, seed, truth, res.controls, kidnapped, res.truth_checksum)
    for name in res.names:
        _, got_means, got_covs = res.filters.series(name)
        done = len(got_means)
        means = np.full((T, N, 3), np.nan)
        covs = np.full((T, N, 3, 3), np.nan)
        means[:done], covs[:done] = got_means, got_covs
        step_ns = (sum(m.tracks[name].step_ns for m in res.filters.members) if res.filters.is_member(name)
                   else res.filters.joint.tracks[name].step_ns)
        failed = res.track(name).failed
        out.filters[name] = [finish_filter(means[:, i].copy(), covs[:, i].copy(), truth[:, i], done,
                                           failed, 0.0, 0, step_ns, keep_means=index == 0)
                             for i in range(N)]
    return out
