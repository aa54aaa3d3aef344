"""R runs together, each filter that has a batched form as one object whose state is arrays
(:func:`batch_runs`; :func:`batch_reason` says when a run cannot be batched).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation.montecarlo.records import RunOutput, finish_filter
from beacon_sim.filters.base import Batchable, FilterError
from beacon_sim.filters.gaussian.measurements import BatchableFilter, SlotPacker, nis
from beacon_sim.hosting.loading import (
    build_filter,
    filter_display_name,
    filter_names,
    load_filter_class,
)


def batch_reason(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]]) -> str | None:
    """Why the runs cannot be batched (None: every filter has a batched form that
    reproduces it, as the filter itself says: ``batch_blocker``)."""
    for spec in specs:
        try:
            cls = load_filter_class(spec)
        except Exception as exc:  # reported by the per-run path
            return str(exc)
        if not issubclass(cls, BatchableFilter):
            return f"{spec} has no batched form"
        try:
            flt = build_filter(spec, scenario, 0, params=params.get(filter_display_name(spec)))
        except Exception as exc:
            return str(exc)
        if not isinstance(flt, Batchable):  # the batched contract (filters/base.py)
            return f"{spec} has no batched form"
        why = flt.batch_blocker
        if why is not None:
            return f"{spec}: {why}"
    return None


def _batchable(flt: object) -> Batchable:
    """``flt`` as a filter with a batched form (batch_reason has checked it)."""
    if not isinstance(flt, Batchable):
        raise FilterError(f"{type(flt).__name__} has no batched form")
    return flt


def batch_runs(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]],
               seeds: list[int], duration: float, indices: list[int],
               keep_means_index: int = 0) -> list[RunOutput]:
    """Runs ``seeds`` together, every filter batched (see :func:`batch_reason`); returns one
    :class:`RunOutput` per seed, as :func:`one_run` would. Costs: the batch's per run-step;
    the NIS against the predicted belief is not timed (as in one_run), except for a filter
    whose update gives it (``own_nis``)."""
    names = filter_names(specs)
    R = len(seeds)
    batched = {name: _batchable(build_filter(spec, scenario, seeds[0], name=name,
                                             params=params.get(filter_display_name(spec)))).batched(R)
               for name, spec in zip(names, specs, strict=True)}
    batch = BatchSimulation(scenario, seeds, readings_checksums=False)   # R single runs, bit for bit
    packer = SlotPacker(scenario.world, scenario.model_sensors)
    T = round(duration / scenario.dt)
    truth = np.empty((R, T + 1, 3))
    truth[:, 0] = batch.pose
    controls = np.empty((R, T, 2))
    kidnapped = np.zeros((R, T), dtype=bool)
    means = {n: np.empty((R, T, 3)) for n in names}
    covs = {n: np.empty((R, T, 3, 3)) for n in names}
    nis_sum = {n: np.zeros(R) for n in names}
    nis_dof = {n: np.zeros(R, dtype=int) for n in names}
    nis_alive = {n: np.ones(R, dtype=bool) for n in names}
    ns = dict.fromkeys(names, 0)
    clock = time.perf_counter_ns
    with np.errstate(all="ignore"):
        for t in range(T):
            tick = batch.advance()   # the tick as arrays: no Step or Measurement per run
            v = tick.v
            w = tick.omega
            controls[:, t, 0] = v
            controls[:, t, 1] = w
            truth[:, t + 1] = tick.pose
            kidnapped[:, t] = tick.kidnapped
            dt = tick.dt
            st = packer.pack_tick(tick)
            if st is not None:
                valid = st.valid if st.valid is not None else np.ones(st.z.shape, dtype=bool)
                dof = np.count_nonzero(valid, axis=1)
                has = dof > 0   # the run had a reading: its NIS is recorded
            for name, f in batched.items():
                t0 = clock()
                f.predict(v, w, dt)
                t1 = clock()
                prior = None
                if st is not None and not f.own_nis:  # not timed (as one_run)
                    prior = nis(f.mean, f.cov, st)
                t2 = clock()
                if st is not None:
                    f.update(st)
                    if prior is None:
                        prior = f.last_nis
                means[name][:, t] = f.mean
                covs[name][:, t] = f.cov
                t3 = clock()
                ns[name] += (t1 - t0) + (t3 - t2)
                if st is not None and prior is not None:
                    alive = nis_alive[name]
                    alive &= np.isfinite(prior) | ~has
                    use = alive & has
                    nis_sum[name][use] += prior[use]
                    nis_dof[name][use] += dof[use]
    checksums = batch.truth_checksums()
    out = []
    for i in range(R):
        run = RunOutput(indices[i], seeds[i], truth[i], controls[i], kidnapped[i], checksums[i])
        for name in names:
            run.filters[name] = finish_filter(
                means[name][i].copy(), covs[name][i].copy(), truth[i], T, None,
                float(nis_sum[name][i]), int(nis_dof[name][i]), round(ns[name] / R),
                keep_means=indices[i] == keep_means_index)
        out.append(run)
    return out


def batch_task(args) -> list[RunOutput]:
    return batch_runs(*args)
