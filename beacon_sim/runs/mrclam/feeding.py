"""The data fed to a MRCLAM run's runners: one robot's odometry and readings interleaved by
time stamp (:func:`feed_by_time_stamps`), or every robot on one clock
(:func:`feed_on_a_clock`). Times [s] on the data set's clock, controls [m/s, rad/s]."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Control, Measurement, Step
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.io.mrclam import MrclamData
from beacon_sim.runs.mrclam.associations import AssociationCount, score_associations
from beacon_sim.runs.mrclam.calibration import Calibration, command_integrals
from beacon_sim.runs.mrclam.map_history import MapHistory, snapshot_maps
from beacon_sim.runs.mrclam.scenario import SENSOR_NAME, SIGHTING_SENSOR
from beacon_sim.runs.progress import Progress

#: Seed of the shuffle of each time stamp's rows when their IDs are hidden (the file's order
#: must not hint at the landmark); fixed, so a run is the same bit for bit.
UNKNOWN_IDS_SHUFFLE_SEED = 29
_UNKNOWN_POSE = np.full(3, np.nan)
_NO_READINGS: tuple[Measurement, ...] = ()


def _feed(runners: Sequence[TeamRunner], tick: int, time_s: float, dt: float,
          controls: Sequence[Control], readings: Sequence[tuple[Measurement, ...]],
          sightings: Sequence[tuple[Measurement, ...]] | None = None) -> None:
    """One step of ``dt`` [s] ending at ``time_s`` (from the start) for every robot."""
    steps = tuple(Step(tick, time_s, dt, _UNKNOWN_POSE, u, r)
                  for u, r in zip(controls, readings, strict=True))
    step = TeamStep(tick, time_s, dt, steps, tuple(sightings or (_NO_READINGS,) * len(steps)))
    for runner in runners:
        runner.feed(step)



def feed_by_time_stamps(runners: Sequence[TeamRunner], data: MrclamData, cal: Calibration,
                        t_start: float, t_end: float,
                        scores: dict[str, AssociationCount] | None = None,
                        maps: dict[str, MapHistory] | None = None,
                        progress: Progress | None = None) -> tuple[np.ndarray, np.ndarray, int, int]:
    """One robot's odometry and readings interleaved by time stamp (seed 001 section III.C):
    predict with the latest command (times ``cal``'s command scales) up to each reading's time
    stamp, in steps of at most 1.5 median odometry intervals (long gaps are split), update
    with all readings of that stamp, go on.

    Returns the time of every record (the start, every odometry row and every update), the
    runner tick whose estimate it shows (0: the initial belief), the updates and readings.

    ``scores`` given (``--unknown-ids``): every reading reaches the filters with its IDs
    ``UNKNOWN_ID`` and its rows shuffled, and after each update the filters' associations are
    counted into ``scores`` against the barcodes (:func:`score_associations`).

    ``maps`` given (``--slam`` in the window): after each update every working SLAM filter's
    ``landmarks()`` is kept in ``maps`` (:func:`snapshot_maps`), for the playback to draw.

    ``progress`` given: told the whole seconds of data fed so far (it only reports)."""
    od = data.odometry
    shuffle = np.random.default_rng(UNKNOWN_IDS_SHUFFLE_SEED)
    ms = data.measurements
    ms = ms[(ms[:, 0] > t_start) & (ms[:, 0] <= t_end)]
    group_t, group_start = np.unique(ms[:, 0], return_index=True)
    group_end = np.append(group_start[1:], len(ms))
    od_sel = od[(od[:, 0] > t_start) & (od[:, 0] <= t_end)]
    first = int(np.searchsorted(od[:, 0], t_start, side="right")) - 1
    kv, kw = cal.v_scale, cal.omega_scale
    u = Control(float(od[first, 1]) * kv, float(od[first, 2]) * kw)
    max_step = 1.5 * cal.step_dt
    times, ticks = [t_start], [0]
    t, tick = t_start, 0
    i_od = i_me = 0
    n_od, n_me = len(od_sel), len(group_t)
    while i_od < n_od or i_me < n_me:
        t_od = od_sel[i_od, 0] if i_od < n_od else math.inf
        t_me = group_t[i_me] if i_me < n_me else math.inf
        t_next = min(t_od, t_me)
        reading: tuple[Measurement, ...] = _NO_READINGS
        if t_me <= t_od:
            a, b = group_start[i_me], group_end[i_me]
            rows = ms[a:b]
            if scores is not None:
                rows = rows[shuffle.permutation(len(rows))]
                ids = np.full(len(rows), UNKNOWN_ID, dtype=int)
            else:
                ids = rows[:, 1].astype(int)
            reading = (Measurement(SENSOR_NAME, "range_bearing", rows[:, 2:4].copy(), ids),)
        dt = t_next - t
        if dt > 0 or reading:  # a repeated odometry stamp only changes the command
            n = max(1, math.ceil(dt / max_step - 1e-9))
            h = dt / n
            for j in range(n):
                tick += 1
                _feed(runners, tick, t + (j + 1) * h - t_start, h, (u,),
                      (reading if j == n - 1 else _NO_READINGS,))
            if reading and scores is not None:
                score_associations(runners, rows[:, 1].astype(int), t_next - t_start, scores)
            if reading and maps is not None:
                snapshot_maps(runners, t_next, t_start, maps)
        t = t_next
        if reading:
            i_me += 1
        else:
            u = Control(float(od_sel[i_od, 1]) * kv, float(od_sel[i_od, 2]) * kw)
            i_od += 1
        times.append(t)
        ticks.append(tick)
        if progress is not None and int(t - t_start) > progress.done:
            progress.update(min(int(t - t_start), progress.total))
    if progress is not None and progress.done < progress.total:
        progress.update(progress.total)
    return np.array(times), np.array(ticks, dtype=np.int64), n_me, len(ms)


def _per_tick(rows: np.ndarray, sensor: str, kind: str, t_start: float, t_last: float, dt: float,
              n_ticks: int) -> dict[int, tuple[Measurement, ...]]:
    """Readings stamped in (t_k, t_k+1] as tick k's, one per subject and tick (the first)."""
    rows = rows[(rows[:, 0] > t_start) & (rows[:, 0] <= t_last)]
    k = np.clip(np.ceil((rows[:, 0] - t_start) / dt).astype(int) - 1, 0, n_ticks - 1)
    out: dict[int, tuple[Measurement, ...]] = {}
    for kk in np.unique(k):
        sel = rows[k == kk]
        _, first = np.unique(sel[:, 1], return_index=True)
        sel = sel[np.sort(first)]
        out[int(kk)] = (Measurement(sensor, kind, sel[:, 2:4].copy(), sel[:, 1].astype(np.int64)),)
    return out


def feed_on_a_clock(runners: Sequence[TeamRunner], data: Sequence[MrclamData],
                    cals: Sequence[Calibration], t_start: float, t_end: float,
                    dt: float, progress: Progress | None = None
                    ) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Every robot on one clock of ``dt`` [s] from ``t_start``: each tick a robot moves by
    the exact integral of its piecewise-constant odometry commands over the tick
    (v = ds/dt, omega = da/dt, times its calibration's command scales); the landmark readings
    and sightings stamped inside the tick update at its end. Returns the tick times, the
    ticks, the ticks with a landmark reading, and the landmark readings used. ``progress``
    given: told the whole seconds of data fed so far (it only reports)."""
    n_ticks = int((t_end - t_start) // dt)
    times = t_start + dt * np.arange(n_ticks + 1)
    controls = []
    for d, cal in zip(data, cals, strict=True):
        s, a = command_integrals(d.odometry, times)
        controls.append([Control(float(v), float(w)) for v, w in
                         zip(np.diff(s) / dt * cal.v_scale, np.diff(a) / dt * cal.omega_scale, strict=True)])
    landmarks = [_per_tick(d.measurements, SENSOR_NAME, "range_bearing", t_start, times[-1], dt, n_ticks)
                 for d in data]
    seen = [_per_tick(d.sightings, SIGHTING_SENSOR, "robot_range_bearing", t_start, times[-1], dt,
                      n_ticks) for d in data]
    for k in range(n_ticks):
        _feed(runners, k + 1, float(times[k + 1] - t_start), dt, [c[k] for c in controls],
              [lm.get(k, _NO_READINGS) for lm in landmarks], [s.get(k, _NO_READINGS) for s in seen])
        if progress is not None and int(times[k + 1] - t_start) > progress.done:
            progress.update(min(int(times[k + 1] - t_start), progress.total))
    if progress is not None and progress.done < progress.total:
        progress.update(progress.total)
    updates = len(set().union(*landmarks))
    used = sum(len(m) for lm in landmarks for ms in lm.values() for m in ms)
    return times, np.arange(n_ticks + 1), updates, used
