"""Measures the evaluation adds to ``core.metrics``: NIS, recovery time after a kidnap and
divergence.

NIS (normalised innovation squared) is ``nu^T S^-1 nu`` with ``nu = z - h(prior mean)`` and
``S = H P_prior H^T + R``, computed outside the filter from its predicted belief and the
noise it was told; for an honest filter it is chi-square with as many degrees of freedom as
the readings have rows times columns.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.gaussian.measurements import LOW_RANK_ROWS, nis_low_rank


def innovation(meas: Measurement, spec: SensorSpec, mean: np.ndarray, world: World):
    """Innovation ``nu`` (k,), Jacobian ``H`` (k, 3) and noise variances ``r`` (k,) of one
    measurement against a prior ``mean`` [m, m, rad]; angles in ``nu`` wrapped."""
    if meas.kind == "bearing":
        b = world.beacon_positions(meas.beacon_ids)
        nu = wrap(meas.z[:, 0] - mm.bearing(mean, b))
        H = mm.bearing_jacobian(mean, b)
        r = np.full(len(nu), spec.noise.bearing_std**2)
        return np.atleast_1d(nu), H, r
    if meas.kind == "range_bearing":
        b = world.beacon_positions(meas.beacon_ids)
        zhat = mm.range_bearing(mean, b)
        nu = meas.z - zhat
        nu[:, 1] = wrap(nu[:, 1])
        H = mm.range_bearing_jacobian(mean, b).reshape(-1, 3)
        r = np.tile(spec.reading_std() ** 2, len(b))
        return nu.reshape(-1), H, r
    n = len(meas.beacon_ids)
    if meas.kind == "pose":
        nu = meas.z[0] - mean
        nu[2] = wrap(nu[2])
        return nu, np.eye(3), spec.fix_std(n) ** 2
    if meas.kind == "position":
        h = meas.hdop if math.isfinite(meas.hdop) else 1.0
        return meas.z[0] - mean[:2], mm.POSITION_H, spec.fix_std(n, h) ** 2
    raise ValueError(f"unknown measurement kind {meas.kind!r}")


def nis(measurements: Sequence[Measurement], sensors: dict[str, SensorSpec], mean, cov,
        world: World) -> tuple[float, int]:
    """Joint NIS of all readings of one tick against the prior ``(mean, cov)``, and its
    degrees of freedom. ``(0.0, 0)`` when there is no reading."""
    if not measurements:
        return 0.0, 0
    parts = [innovation(m, sensors[m.sensor], mean, world) for m in measurements]
    nu = np.concatenate([p[0] for p in parts])
    H = np.vstack([p[1] for p in parts])
    r = np.concatenate([p[2] for p in parts])
    try:
        if nu.size > LOW_RANK_ROWS:  # many readings: linear in them, S never formed
            value = float(nis_low_rank(np.asarray(cov, dtype=float), H, nu, r))
        else:
            S = H @ cov @ H.T + np.diag(r)  # S = H P H^T + R
            value = float(nu @ np.linalg.solve(S, nu))
    except np.linalg.LinAlgError:
        value = math.inf
    return value, int(nu.size)


def recovery_times(pos_err, times, kidnap_idx, threshold: float, hold: float = 5.0) -> list[float]:
    """Time [s] from each kidnap until the position error falls below ``threshold`` [m]
    and then stays below it for ``hold`` seconds.

    The figure depends only on the error up to ``recovery + hold`` after the kidnap, so a
    longer run (or a later next kidnap) gives the same number whenever the shorter one saw
    the recovery. A hold that the next kidnap or the end of the run cuts short does not count.

    Parameters
    ----------
    pos_err : array (T,) [m]
        Position error after each step.
    times : array (T,) [s]
        Time of each step.
    kidnap_idx : sequence of int
        Indices into ``pos_err`` of the steps on which a kidnap happened (ascending).
    threshold : float [m]
    hold : float [s]
        How long the error must stay below ``threshold``; 0 accepts the first step below.

    Returns
    -------
    list of float
        One per kidnap: ``t_i - t_kidnap`` for the first step ``i`` (from the kidnap's own
        step on) that starts a stretch below the threshold lasting ``hold``; ``inf`` when
        there is none before the next kidnap or the end of the run.
    """
    err = np.asarray(pos_err, dtype=float)
    t = np.asarray(times, dtype=float)
    kidnap_idx = [int(k) for k in kidnap_idx]
    out: list[float] = []
    ends = [*kidnap_idx[1:], len(err)]
    eps = 1e-9 * max(1.0, abs(hold))
    for k, end in zip(kidnap_idx, ends[:len(kidnap_idx)], strict=True):
        below = err[k:end] < threshold  # NaN (a failed filter) counts as above
        ts = t[k:end]
        found = math.inf
        i = 0
        n = below.size
        while i < n:
            if not below[i]:
                i += 1
                continue
            j = i
            while j + 1 < n and below[j + 1]:
                j += 1
            # steps i..j are below: every sample from ts[i] to ts[i] + hold must be among them
            if ts[j] - ts[i] >= hold - eps:
                found = float(ts[i] - t[k])
                break
            i = j + 1
        out.append(found)
    return out


def diverged(pos_err, threshold: float, tail: float = 0.1) -> bool:
    """True when the position error [m] stays above ``threshold`` over the whole last
    ``tail`` share of the run (or is not finite there): the filter is lost."""
    err = np.asarray(pos_err, dtype=float)
    if err.size == 0:
        return True
    n = max(1, math.ceil(tail * err.size))
    last = err[-n:]
    return bool(np.all(~(last < threshold)))


def nis_batch(records, prior_means: np.ndarray, prior_covs: np.ndarray,
              sensors: dict[str, SensorSpec], world: World) -> tuple[float, int]:
    """Sum of the joint NIS of many ticks and the sum of their degrees of freedom.

    The same numbers as adding up :func:`nis` tick by tick, computed in a few array
    operations. ``records[j]`` is the list of measurements of tick ``j`` and
    ``prior_means[j]`` (3,), ``prior_covs[j]`` (3, 3) the filter's predicted belief there.
    """
    index = np.full(int(world.beacon_ids.max(initial=0)) + 1, -1)
    index[world.beacon_ids] = np.arange(len(world.beacon_ids))
    groups: dict[str, list] = {"bearing": [], "range_bearing": [], "pose": [], "position": []}
    for j, meas in enumerate(records):
        for m in meas:
            if m.kind not in groups:
                continue  # a range finder's scan: no Gaussian model to test
            if m.kind in ("bearing", "range_bearing") and len(m) and m.beacon_ids[0] < 0:
                continue  # no beacon ID (unknown correspondence): no model to test
            if m.kind not in groups:
                continue  # a laser scan: no Gaussian reading model to test
            groups[m.kind].append((j, m))
    tick, nu, H, var = [], [], [], []

    def beacon_rows(items, pick):
        js = np.repeat([j for j, _ in items], [len(m) for _, m in items])
        ids = np.concatenate([m.beacon_ids for _, m in items])
        z = np.concatenate([m.z for _, m in items])
        std = np.concatenate([np.broadcast_to(sensors[m.sensor].reading_std(), m.z.shape)
                              for _, m in items])
        d = world.beacon_xy[index[ids]] - prior_means[js, :2]
        q = np.maximum(np.sum(d * d, axis=1), 1e-300)
        hb = np.stack([d[:, 1] / q, -d[:, 0] / q, -np.ones_like(q)], axis=1)
        nub = wrap(z[:, pick] - relative_bearing(d[:, 0], d[:, 1], prior_means[js, 2]))
        tick.append(js)
        nu.append(nub)
        H.append(hb)
        var.append(std[:, pick] ** 2)
        if pick == 1:  # the range rows of range-bearing readings
            r = np.sqrt(q)
            tick.append(js)
            nu.append(z[:, 0] - r)
            H.append(np.stack([-d[:, 0] / r, -d[:, 1] / r, np.zeros_like(r)], axis=1))
            var.append(std[:, 0] ** 2)

    if groups["bearing"]:
        beacon_rows(groups["bearing"], 0)
    if groups["range_bearing"]:
        beacon_rows(groups["range_bearing"], 1)
    for kind in ("pose", "position"):
        for j, m in groups[kind]:
            e, Hm, r = innovation(m, sensors[m.sensor], prior_means[j], world)
            tick.append(np.full(e.size, j))
            nu.append(e)
            H.append(Hm)
            var.append(r)
    if not tick:
        return 0.0, 0
    tick_a = np.concatenate(tick)
    order = np.argsort(tick_a, kind="stable")
    tick_a = tick_a[order]
    nu_a = np.concatenate(nu)[order]
    H_a = np.vstack(H)[order]
    var_a = np.concatenate(var)[order]
    starts = np.flatnonzero(np.r_[True, tick_a[1:] != tick_a[:-1]])
    sizes = np.diff(np.r_[starts, tick_a.size])
    total = 0.0
    for k in np.unique(sizes):
        st = starts[sizes == k]
        rows = st[:, None] + np.arange(k)[None, :]  # (n, k)
        Hk = H_a[rows]  # (n, k, 3)
        P = prior_covs[tick_a[st]]
        if k > LOW_RANK_ROWS:  # many readings in a tick: linear in them, S never formed
            try:
                total += float(np.sum(nis_low_rank(P, Hk, nu_a[rows], var_a[rows])))
            except np.linalg.LinAlgError:
                return math.inf, int(nu_a.size)
            continue
        S = Hk @ P @ np.swapaxes(Hk, 1, 2)  # S = H P H^T + R
        S[:, np.arange(k), np.arange(k)] += var_a[rows]
        e = nu_a[rows]
        try:
            total += float(np.sum(e * np.linalg.solve(S, e[..., None])[..., 0]))
        except np.linalg.LinAlgError:
            return math.inf, int(nu_a.size)
    return total, int(nu_a.size)
