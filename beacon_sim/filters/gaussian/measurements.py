"""What the Gaussian filters share, for one run or for R runs at once.

Shapes: one run has a mean (3,) [m, m, rad], a covariance (3, 3) and m readings (m,); R runs
(``evaluation.montecarlo`` batches them) add a leading axis: (R, 3), (R, 3, 3), (R, M). The
array functions here take either, so one piece of code serves both forms.

- Readings: all readings of a tick (any sensors, any number of beacons) become one vector
  ``z``, one diagonal noise variance vector ``r`` and the angle rows (bearings, the heading
  of a pose fix), whose residuals are wrapped. ``stack`` does it for one run;
  ``SlotPacker`` for R runs, in slots fixed by the sensors (every beacon of every beacon
  sensor, every fix row), so a run's numbers never depend on the other runs of its batch.
  Empty slots have z = 0, r = 1 and ``valid`` False: H = 0 and innovation 0 there, so they
  add an identity block to S and a zero column to K, i.e. nothing.
- The stacked model: ``StackedReadings.predict`` (h at many poses, the UKF's) and
  ``StackedReadings.linearise`` (H and the innovation, the EKF's and the KF's).
- The Kalman update ``kalman_update`` (S, K, mean, Joseph or plain P), the NIS ``nis``.
- The velocity model's process noise ``process_cov_terms``.
- ``BatchableFilter``: a filter that declares the parameters its R-run form reproduces.

Noise comes from the filter's context: ``reading_std()`` for beacon readings,
``fix_std(len(beacon_ids), hdop)`` for pose and position fixes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap as wrap_angle
from beacon_sim.core.batch_simulation import BatchTick, BeaconReadings
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.sensor_kind import MeasurementModel
from beacon_sim.core.sensor_kinds import beacon_kinds, is_scan, model_of, sensor_kind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError

#: The kinds these filters have fast forms of (any other: its record's model,
#: :func:`model_readings`); which of them name a beacon per row, and their angle columns,
#: come from their records (core/sensor_kinds.py).
KINDS = ("bearing", "range_bearing", "pose", "position")
BEACON_KINDS = beacon_kinds(KINDS)
FIX_KINDS = tuple(k for k in KINDS if k not in BEACON_KINDS)
_ANGLE_PATTERN = {k: sensor_kind(k).angles for k in KINDS}
_I3 = np.eye(3)

#: Readings (rows of a tick's stacked update) above which the Kalman updates take their
#: low-rank forms: with R diagonal (independent readings), ``S = H P H^T + R`` (the EKF's,
#: rank 3) and ``S = dZ^T W dZ + R`` (the UKF's, rank 7) are never formed or solved, and the
#: cost is linear in the rows instead of cubic. At or below it the direct m x m solve runs,
#: as it always did (the same bits; cheaper for a few readings). The two agree to 1e-9.
LOW_RANK_ROWS = 24

#: R runs' slots (``SlotPacker``): when at most this fraction holds readings, the models
#: (``StackedReadings.linearise``, ``predict``) compute only those (linear in the readings
#: present, not in the map); above, the whole map on arrays is cheaper. The same bits.
PRESENT_FRACTION = 0.25

#: One sensor's rows: (kind, first row, end row, beacon xy (k, 2) [m] or None for a fix).
Block = tuple[str, int, int, "np.ndarray | None"]
#: The angle rows as a slice (a view, cheaper on the hot path) or an index array; None: none.
AngleRows = slice | np.ndarray | None
#: The angle rows when every row is one (bearings only).
ALL_ROWS = slice(None)


class ReadingModels:
    """Per-filter lookup tables built once from the context: beacon positions by ID [m]
    and the told noise of each sensor (so the hot path does no searching)."""

    def __init__(self, ctx: FilterContext):
        self.ctx = ctx
        self.beacon_xy = {int(b.id): (float(b.x), float(b.y)) for b in ctx.world.beacons}
        self.xy = np.array(ctx.world.beacon_xy, dtype=float).reshape(-1, 2)
        self.row = {int(b.id): i for i, b in enumerate(ctx.world.beacons)}
        self._beacons_of: dict[bytes, np.ndarray] = {}  # IDs' bytes -> positions (k, 2)
        self.specs = {s.name: s for s in ctx.sensors}
        self.reading_var = {s.name: tuple(float(v) ** 2 for v in s.reading_std())
                            for s in ctx.sensors if s.kind in BEACON_KINDS}

    def spec(self, name: str) -> SensorSpec:
        try:
            return self.specs[name]
        except KeyError:
            return self.ctx.sensor(name)  # raises FilterError with a clear message

    def beacon(self, beacon_id: int) -> tuple[float, float]:
        try:
            return self.beacon_xy[beacon_id]
        except KeyError:
            raise FilterError(f"reading from beacon {beacon_id}, which is not on the map") from None

    def beacons(self, ids: np.ndarray) -> np.ndarray:
        """Positions (k, 2) [m] of the beacons with these IDs (remembered per set of IDs)."""
        key = ids.tobytes()
        xy = self._beacons_of.get(key)
        if xy is None:
            try:
                xy = self.xy[[self.row[i] for i in ids.tolist()]]
            except KeyError as exc:
                raise FilterError(f"reading from beacon {exc.args[0]}, which is not on the map") from None
            if len(self._beacons_of) >= 4096:
                self._beacons_of.clear()
            self._beacons_of[key] = xy
        return xy

    def reading_variance(self, sensor: str) -> tuple[float, ...]:
        var = self.reading_var.get(sensor)
        if var is None:
            var = tuple(float(v) ** 2 for v in self.spec(sensor).reading_std())
        return var

    def fix_var(self, m: Measurement) -> tuple[float, ...]:
        """Variances of a pose ``[x, y, theta]`` or position ``[x, y]`` fix row."""
        std = self.spec(m.sensor).fix_std(len(m.beacon_ids), m.hdop)
        return tuple(float(s) ** 2 for s in std)


def _angle_rows(blocks: list[Block], angle: np.ndarray) -> AngleRows:
    if len(blocks) == 1 and blocks[0][0] != "position":
        kind = blocks[0][0]
        return ALL_ROWS if kind == "bearing" else slice(1, None, 2) if kind == "range_bearing" \
            else slice(2, 3)
    return np.flatnonzero(angle) if angle.any() else None


@dataclass
class StackedReadings:
    """One tick's readings as one vector, of one run (m,) or of R runs (R, M). Rows are
    ordered block by block (a block: one sensor's readings), reading by reading, component
    by component (range before bearing)."""

    z: np.ndarray                    # measured values [m or rad]; 0 in empty slots
    r: np.ndarray                    # noise variances [m^2 or rad^2]; 1 in empty slots
    angle: np.ndarray                # (m,) bool: row is an angle (wrap its residuals)
    angle_sel: AngleRows             # the same rows, as a slice when it can
    blocks: list[Block]
    valid: np.ndarray | None = None  # (R, M) bool: the slot holds a reading (None: all rows)

    def __len__(self) -> int:
        return int(self.z.shape[-1])

    def predict(self, poses: np.ndarray, wrap: bool = True) -> np.ndarray:
        """Expected readings h(pose) for poses of shape (N, 3): shape (N, m), angles wrapped
        (``wrap=False`` leaves them unwrapped, for callers that wrap residuals anyway).

        R runs (``valid`` set) and N = R p poses, p per run, run after run (the batched
        UKF's sigma points): the slots without a reading are 0; when few slots hold one
        (``PRESENT_FRACTION``), only those are computed, so the cost follows the readings
        present, not the map (each entry is the same arithmetic, element by element, as
        the whole-map form)."""
        valid = self.valid
        if valid is None or poses.shape[0] % max(valid.shape[0], 1):
            return self._predict_all(poses, wrap)
        if self._sparse():
            return self._predict_present(poses, wrap)
        p = poses.shape[0] // max(valid.shape[0], 1)
        return np.where(np.repeat(valid, p, axis=0), self._predict_all(poses, wrap), 0.0)

    def _sparse(self) -> bool:
        """Whether few enough slots hold a reading (at most :data:`PRESENT_FRACTION` of
        them) that computing only those is cheaper than the whole map on arrays (the two
        give the same bits; scattered entries cost a few times a contiguous one)."""
        valid = self.valid
        return valid is not None and bool(np.count_nonzero(valid) <= PRESENT_FRACTION * valid.size)

    def _predict_all(self, poses: np.ndarray, wrap: bool = True) -> np.ndarray:
        """:meth:`predict` at every row, whether or not its slot holds a reading."""
        out = np.empty((poses.shape[0], self.z.shape[-1]))
        x = poses[:, 0:1]
        y = poses[:, 1:2]
        th = poses[:, 2:3]
        for kind, a, b, bxy in self.blocks:
            if bxy is None:  # pose or position fix
                out[:, a:b] = poses[:, :b - a]
            elif kind == "bearing":
                relative_bearing(bxy[:, 0] - x, bxy[:, 1] - y, th, out=out[:, a:b])
            else:  # range_bearing
                dx = bxy[:, 0] - x
                dy = bxy[:, 1] - y
                np.hypot(dx, dy, out=out[:, a:b:2])
                relative_bearing(dx, dy, th, out=out[:, a + 1:b:2])
        sel = self.angle_sel
        if wrap and sel is not None:
            out[:, sel] = wrap_angle(out[:, sel])
        return out

    def linearise(self, mean: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stacked model at ``mean`` (3,) or (R, 3): H (..., m, 3), the innovation
        ``z - h(mean)`` (..., m) with angle rows wrapped, and the variances (..., m). Empty
        slots get H = 0 and innovation 0.

        bearing h = atan2(dy, dx) - theta, H = [dy/q, -dx/q, -1] (seed 000 eq. 10), q = dx^2 + dy^2;
        range h = sqrt(q), H = [-dx/r, -dy/r, 0] (seed 001); fixes h = x, y(, theta), H = unit rows.
        """
        if mean.ndim == 2 and self._sparse():
            return self._linearise_present(mean)
        return self._linearise_all(mean)

    def _linearise_all(self, mean: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`linearise` at every row, then the empty slots set to 0."""
        x = mean[..., 0:1]
        y = mean[..., 1:2]
        th = mean[..., 2:3]
        H = np.zeros((*self.z.shape, 3))
        h = np.empty(self.z.shape)
        for kind, a, b, bxy in self.blocks:
            if bxy is None:  # pose or position fix
                n = b - a
                H[..., a:b, :] = _I3[:n]
                h[..., a:b] = mean[..., :n]
                continue
            dx = bxy[:, 0] - x
            dy = bxy[:, 1] - y
            q = dx * dx + dy * dy
            rows = slice(a, b) if kind == "bearing" else slice(a + 1, b, 2)
            Hb = H[..., rows, :]
            Hb[..., 0] = dy / q
            Hb[..., 1] = -dx / q
            Hb[..., 2] = -1.0
            h[..., rows] = wrap_angle(relative_bearing(dx, dy, th))
            if kind == "range_bearing":
                rr = np.sqrt(q)
                Hr = H[..., a:b:2, :]
                Hr[..., 0] = -dx / rr
                Hr[..., 1] = -dy / rr
                h[..., a:b:2] = rr
        nu = self.z - h
        sel = self.angle_sel
        if sel is not None:
            nu[..., sel] = wrap_angle(nu[..., sel])
        if self.valid is not None:
            H = np.where(self.valid[..., None], H, 0.0)
            nu = np.where(self.valid, nu, 0.0)
        return H, nu, self.r

    def _present(self, a: int, b: int, width: int) -> tuple[np.ndarray, np.ndarray]:
        """The (run, beacon) pairs of a beacon block's readings (its rows a:b, ``width``
        per beacon): run indices and beacon indices (k,), run by run, beacon by beacon."""
        assert self.valid is not None
        ri, ji = np.nonzero(self.valid[:, a + width - 1:b:width])
        return ri, ji

    def _predict_present(self, poses: np.ndarray, wrap: bool) -> np.ndarray:
        """:meth:`predict` of R runs' p poses each, only where a slot holds a reading."""
        valid = self.valid
        assert valid is not None
        N, M = poses.shape[0], self.z.shape[-1]
        p = N // max(valid.shape[0], 1)
        out = np.zeros((N, M))
        for kind, a, b, bxy in self.blocks:
            if bxy is None:  # pose or position fix
                out[:, a:b] = np.where(np.repeat(valid[:, a:b], p, axis=0), poses[:, :b - a], 0.0)
                continue
            width = 1 if kind == "bearing" else 2
            ri, ji = self._present(a, b, width)
            if ri.size == 0:
                continue
            rows = (ri[:, None] * p + np.arange(p)).reshape(-1)   # every pose of the run
            ji = np.repeat(ji, p)
            x = poses[rows, 0]
            y = poses[rows, 1]
            th = poses[rows, 2]
            dx = bxy[ji, 0] - x
            dy = bxy[ji, 1] - y
            cols = a + ji * width
            if kind == "range_bearing":
                out[rows, cols] = np.hypot(dx, dy)
            out[rows, cols + width - 1] = relative_bearing(dx, dy, th)
        sel = self.angle_sel
        if wrap and sel is not None:
            out[:, sel] = wrap_angle(out[:, sel])
        return out

    def _linearise_present(self, mean: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`linearise` of R runs, computed only where a slot holds a reading (the
        cost follows the readings present, not the map); the same arithmetic, element by
        element, so the same bits."""
        valid = self.valid
        assert valid is not None
        z = self.z
        H = np.zeros((*z.shape, 3))
        nu = np.zeros(z.shape)
        for kind, a, b, bxy in self.blocks:
            if bxy is None:  # pose or position fix: h = x, y(, theta), H = unit rows
                n = b - a
                v = valid[:, a:b]
                H[:, a:b, :] = np.where(v[..., None], _I3[:n], 0.0)
                d = z[:, a:b] - mean[:, :n]
                ang = self.angle[a:b]
                if ang.any():
                    d[:, ang] = wrap_angle(d[:, ang])
                nu[:, a:b] = np.where(v, d, 0.0)
                continue
            width = 1 if kind == "bearing" else 2
            ri, ji = self._present(a, b, width)
            if ri.size == 0:
                continue
            dx = bxy[ji, 0] - mean[ri, 0]
            dy = bxy[ji, 1] - mean[ri, 1]
            q = dx * dx + dy * dy
            cb = a + ji * width + width - 1        # the bearing rows
            H[ri, cb, 0] = dy / q
            H[ri, cb, 1] = -dx / q
            H[ri, cb, 2] = -1.0
            hb = wrap_angle(relative_bearing(dx, dy, mean[ri, 2]))
            nu[ri, cb] = wrap_angle(z[ri, cb] - hb)
            if kind == "range_bearing":
                rr = np.sqrt(q)
                cr = cb - 1                        # the range rows
                H[ri, cr, 0] = -dx / rr
                H[ri, cr, 1] = -dy / rr
                nu[ri, cr] = z[ri, cr] - rr
        return H, nu, self.r

    def only(self, kinds: Sequence[str]) -> StackedReadings | None:
        """The rows of the blocks of these kinds (None: there are none)."""
        keep = [blk for blk in self.blocks if blk[0] in kinds]
        if not keep:
            return None
        if len(keep) == len(self.blocks):
            return self
        cols = np.concatenate([np.arange(a, b) for _, a, b, _ in keep])
        blocks, start = [], 0
        for kind, a, b, bxy in keep:
            blocks.append((kind, start, start + b - a, bxy))
            start += b - a
        angle = self.angle[cols]
        valid = None if self.valid is None else self.valid[..., cols]
        return StackedReadings(self.z[..., cols], self.r[..., cols], angle, _angle_rows(blocks, angle),
                               blocks, valid)


def stack(models: ReadingModels, measurements: Iterable[Measurement],
          kinds: Sequence[str] = KINDS) -> StackedReadings | None:
    """One run's readings of the given ``kinds``; None when there is nothing to use."""
    zs: list[np.ndarray] = []
    rs: list[float] = []
    angles: list[bool] = []
    blocks: list[Block] = []
    m0 = 0
    for m in measurements:
        if m.kind not in kinds or len(m) == 0:
            continue
        bxy: np.ndarray | None
        if m.kind in BEACON_KINDS:
            var = models.reading_variance(m.sensor)
            bxy = models.beacons(m.beacon_ids)
            k = bxy.shape[0]
            rs.extend(var * k)
            angles.extend(_ANGLE_PATTERN[m.kind] * k)
            n = k * len(var)
        else:
            var = models.fix_var(m)
            rs.extend(var)
            angles.extend(_ANGLE_PATTERN[m.kind])
            bxy = None
            n = len(var)
        zs.append(m.z.reshape(-1))
        blocks.append((m.kind, m0, m0 + n, bxy))
        m0 += n
    if not blocks:
        return None
    z = zs[0] if len(zs) == 1 else np.concatenate(zs)
    angle = np.array(angles)
    return StackedReadings(np.asarray(z, dtype=float), np.array(rs), angle, _angle_rows(blocks, angle),
                           blocks)


class SlotPacker:
    """Packs the readings of one tick of R runs into :class:`StackedReadings` (R, M), one
    slot per beacon of each beacon sensor and per fix row, in the order of ``sensors``."""

    def __init__(self, world: World, sensors: Sequence[SensorSpec]):
        xy = np.asarray(world.beacon_xy, dtype=float).reshape(-1, 2)
        ids = np.asarray(world.beacon_ids, dtype=int)
        n_ids = int(ids.max(initial=0)) + 1
        self.specs = {s.name: s for s in sensors}
        self.blocks: list[Block] = []
        # sensor -> its slots: by beacon ID (n_ids, rows per reading; -1: no such beacon) for a
        # beacon sensor, (rows,) for a fix
        self.slots_of: dict[str, np.ndarray] = {}
        angles: list[bool] = []
        r0: list[float] = []
        a = 0
        for s in sensors:
            bxy: np.ndarray | None
            if is_scan(s.kind):   # a laser scan: no Gaussian slots, unread
                continue
            if s.kind in BEACON_KINDS:
                var = [float(v) ** 2 for v in s.reading_std()]
                width, n, bxy = len(var), len(var) * len(xy), xy
                table = np.full((n_ids, width), -1)
                table[ids] = a + np.arange(n).reshape(-1, width)
                self.slots_of[s.name] = table
                r0.extend(var * len(xy))
            elif s.kind in FIX_KINDS:
                width = n = len(_ANGLE_PATTERN[s.kind])
                bxy = None
                self.slots_of[s.name] = np.arange(a, a + n)
                r0.extend([1.0] * n)
            else:
                raise FilterError(f"sensor kind {s.kind!r} has no batched readings")
            self.blocks.append((s.kind, a, a + n, bxy))
            angles.extend(_ANGLE_PATTERN[s.kind] * (n // width))
            a += n
        self.M = a
        self.angle = np.array(angles, dtype=bool)
        self.angle_sel = _angle_rows(self.blocks, self.angle)
        self.r0 = np.array(r0)  # the beacon slots' variances (1 for the fix slots)
        self._columns: dict[tuple[str, bytes], tuple[slice | np.ndarray, np.ndarray]] = {}  # _beacon_columns

    def pack(self, runs: Sequence[Sequence[Measurement]]) -> StackedReadings | None:
        """The readings of each run (one list per run); None when no run has any."""
        R = len(runs)
        z = np.zeros((R, self.M))
        valid = np.zeros((R, self.M), dtype=bool)
        fixes = self._scatter(runs, z, valid)
        return self._finish(z, valid, fixes)

    def pack_tick(self, tick: BatchTick) -> StackedReadings | None:
        """The readings of one tick of ``core.batch_simulation`` (``BatchSimulation.advance``),
        straight from its arrays: the same :class:`StackedReadings`, bit for bit, as
        ``pack([tick.measurements(i) for i in runs])``, without a ``Measurement`` per run for
        the beacon sensors. None when no run has a reading."""
        R = tick.pose.shape[0]
        z = np.zeros((R, self.M))
        valid = np.zeros((R, self.M), dtype=bool)
        others: list[list[Measurement]] | None = None
        for got in tick.readings:
            if isinstance(got, BeaconReadings):
                cols, known = self._beacon_columns(got.sensor, got.beacon_ids)
                seen, zb = got.seen, got.z
                if not known.all():
                    if seen[:, ~known].any():
                        raise FilterError("reading from a beacon that is not on the map")
                    seen, zb = seen[:, known], zb[:, known]
                d = zb.shape[-1]
                rows = seen if d == 1 else np.repeat(seen, d, axis=1)   # (R, n d)
                z[:, cols] = np.where(rows, zb.reshape(R, -1), 0.0)
                valid[:, cols] = rows
            else:
                if others is None:
                    others = [[] for _ in range(R)]
                for i, m in enumerate(got.per_run):
                    if m is not None:
                        others[i].append(m)
        fixes = None if others is None else self._scatter(others, z, valid)
        return self._finish(z, valid, fixes)

    def _beacon_columns(self, sensor: str, beacon_ids: np.ndarray) -> tuple[slice | np.ndarray, np.ndarray]:
        """The slots (n d,) of a beacon sensor's readings of the beacons ``beacon_ids`` (a
        slice when they are consecutive, as for the map the slots were made from), and
        which of these beacons have slots (n,) bool (False: not on the map)."""
        key = (sensor, beacon_ids.tobytes())
        got = self._columns.get(key)
        if got is None:
            try:
                table = self.slots_of[sensor]
            except KeyError:
                raise FilterError(f"reading from sensor {sensor!r}, which has no slots") from None
            ids = np.asarray(beacon_ids, dtype=int)
            rows = np.full((ids.size, table.shape[1]), -1)
            inside = (ids >= 0) & (ids < table.shape[0])
            rows[inside] = table[ids[inside]]
            known = rows[:, 0] >= 0
            flat = rows[known].reshape(-1)
            cols: slice | np.ndarray = flat
            if flat.size and np.array_equal(flat, np.arange(flat[0], flat[0] + flat.size)):
                cols = slice(int(flat[0]), int(flat[0]) + flat.size)
            got = self._columns[key] = (cols, known)
        return got

    def _scatter(self, runs: Sequence[Sequence[Measurement]], z: np.ndarray, valid: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray] | None:
        """Each run's measurements into its slots of ``z`` and ``valid`` (R, M); returns the
        fix slots (flat) and their variances, or None when there are none."""
        M = self.M
        slots: list[np.ndarray] = []
        zs: list[np.ndarray] = []
        starts: list[int] = []  # i * M of each measurement's run i
        counts: list[int] = []
        fix_slots: list[np.ndarray] = []
        fix_var: list[np.ndarray] = []
        for i, measurements in enumerate(runs):
            for m in measurements:
                if is_scan(m.kind):   # scans have no slots (the filters ignore them)
                    continue
                try:
                    table = self.slots_of[m.sensor]
                except KeyError:
                    raise FilterError(f"reading from sensor {m.sensor!r}, which has no slots") from None
                if m.kind in BEACON_KINDS:
                    cols = table[m.beacon_ids].reshape(-1)
                else:
                    cols = table
                    std = self.specs[m.sensor].fix_std(len(m.beacon_ids), m.hdop)
                    fix_slots.append(cols + i * M)
                    fix_var.append(std * std)
                slots.append(cols)
                zs.append(m.z.reshape(-1))
                starts.append(i * M)
                counts.append(cols.size)
        if not slots:
            return None
        cols = np.concatenate(slots)
        if cols.min() < 0:
            raise FilterError("reading from a beacon that is not on the map")
        flat = cols + np.repeat(starts, counts)
        zf = z.reshape(-1)
        vf = valid.reshape(-1)
        before = np.count_nonzero(vf)
        zf[flat] = np.concatenate(zs)
        vf[flat] = True
        if np.count_nonzero(vf) - before != flat.size:
            raise FilterError("two readings for one slot (one measurement per sensor and tick)")
        if not fix_slots:
            return None
        return np.concatenate(fix_slots), np.concatenate(fix_var)

    def _finish(self, z: np.ndarray, valid: np.ndarray, fixes: tuple[np.ndarray, np.ndarray] | None
                ) -> StackedReadings | None:
        if not valid.any():
            return None
        r = np.where(valid, self.r0, 1.0)
        if fixes is not None:
            r.reshape(-1)[fixes[0]] = fixes[1]
        return StackedReadings(z, r, self.angle, self.angle_sel, self.blocks, valid)


# -- the Kalman update, for one run or R runs -------------------------------------------
def _find_gufunc_solve() -> Callable[..., np.ndarray] | None:
    try:  # the ufunc np.linalg.solve wraps (numpy >= 1.8); absent: the public function
        from numpy.linalg import _umath_linalg
    except ImportError:  # pragma: no cover
        return None
    return getattr(_umath_linalg, "solve", None)


_gufunc_solve = _find_gufunc_solve()


def solve(S: np.ndarray, B: np.ndarray, strict: bool = True) -> np.ndarray:
    """``S^-1 B`` for small symmetric positive-definite S (..., m, m), B (..., m, n).

    The gufunc under ``np.linalg.solve`` (its Python wrapper costs ~10 us on a 4x4 system,
    the gufunc ~3 us). A singular S: with ``strict`` LinAlgError (one run: the filter stops);
    otherwise NaN rows (R runs: one bad run must not stop the others).
    """
    if _gufunc_solve is None:  # pragma: no cover
        return np.linalg.solve(S, B)
    X = _gufunc_solve(S, B)
    if strict and not np.isfinite(X).all():
        return np.linalg.solve(S, B)  # raises LinAlgError for a singular S
    return X


def add_diagonal(S: np.ndarray, r: np.ndarray) -> None:
    """``S += diag(r)`` in place, S (..., m, m) C-contiguous (fresh from a product)."""
    m = S.shape[-1]
    S.reshape(*S.shape[:-2], m * m)[..., :: m + 1] += r


def corrected_mean(mean: np.ndarray, Kt: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``mean + K nu`` (..., 3) with ``Kt`` = K^T (..., m, 3); heading wrapped."""
    m = mean + (nu[..., None, :] @ Kt)[..., 0, :]
    if m.ndim == 1:
        m[2] = wrap_angle(m[2])  # a numpy scalar: wrap's fast path
    else:
        m[:, 2] = wrap_angle(m[:, 2])
    return m


def symmetrise(P: np.ndarray) -> np.ndarray:
    """``(P + P^T) / 2`` in place (P fresh from the update); returns P."""
    P += P.swapaxes(-1, -2)
    P *= 0.5
    return P


def kalman_update(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, r: np.ndarray,
                  joseph: bool = True, want_nis: bool = False, strict: bool = True
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The stacked Kalman update of one run or R runs: ``(mean, P, NIS or None)``.

    S = H P H^T + diag(r), K = P H^T S^-1, mean = mean + K nu (heading wrapped),
    P = (I - K H) P (I - K H)^T + K diag(r) K^T (Joseph) or P - K H P, symmetrised;
    NIS = nu^T S^-1 nu. ``strict``: see :func:`solve`. Over :data:`LOW_RANK_ROWS` rows:
    :func:`kalman_update_low_rank`, the same update linear in the rows.
    """
    if H.shape[-2] > LOW_RANK_ROWS:
        return kalman_update_low_rank(mean, P, H, nu, r, joseph, want_nis, strict)
    HP = H @ P                                          # (..., m, 3)
    S = HP @ H.swapaxes(-1, -2)
    add_diagonal(S, r)
    nis = None
    if want_nis:
        X = solve(S, np.concatenate([HP, nu[..., None]], axis=-1), strict)
        Kt = X[..., :3]                                 # K^T = S^-1 H P (P symmetric)
        nis = np.sum(nu * X[..., 3], axis=-1)
    else:
        Kt = solve(S, HP, strict)
    K = Kt.swapaxes(-1, -2)
    mean = corrected_mean(mean, Kt, nu)
    if joseph:
        A = _I3 - K @ H
        P = A @ P @ A.swapaxes(-1, -2) + (K * r[..., None, :]) @ Kt
    else:
        P = P - K @ HP
    return mean, symmetrise(P), nis


def _information(H: np.ndarray, nu: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``G = H^T R^-1 H`` (..., 3, 3) and ``b = H^T R^-1 nu`` (..., 3), R = diag(r): sums over
    the rows, so linear in them."""
    Hr = H / r[..., :, None]
    return H.swapaxes(-1, -2) @ Hr, (nu[..., None, :] @ Hr)[..., 0, :]


def kalman_update_low_rank(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray,
                           r: np.ndarray, joseph: bool = True, want_nis: bool = False,
                           strict: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`kalman_update` without S (m x m): with ``G = H^T R^-1 H``, ``b = H^T R^-1 nu``
    and ``T = (I + P G)^-1 P`` (3 x 3; invertible for P, G positive semi-definite),
    ``S^-1 = R^-1 - R^-1 H T H^T R^-1`` (Woodbury), so ``K = T H^T R^-1``, ``K nu = T b``,
    ``K H = T G``, ``K R K^T = T G T^T`` and ``NIS = nu^T R^-1 nu - b^T T b``."""
    G, b = _information(H, nu, r)
    T = solve(_I3 + P @ G, P, strict)
    mean = corrected_mean(mean, T.swapaxes(-1, -2), b)
    TG = T @ G
    if joseph:
        A = _I3 - TG
        P = A @ P @ A.swapaxes(-1, -2) + TG @ T.swapaxes(-1, -2)
    else:
        P = P - TG @ P
    nis = None
    if want_nis:
        nis = np.sum(nu * nu / r, axis=-1) - np.sum(b * (T @ b[..., None])[..., 0], axis=-1)
    return mean, symmetrise(P), nis


def nis_low_rank(P: np.ndarray, H: np.ndarray, nu: np.ndarray, r: np.ndarray, strict: bool = True
                 ) -> np.ndarray:
    """``nu^T S^-1 nu`` with S = H P H^T + diag(r) never formed (one run or R runs), linear in
    the rows: ``nu^T R^-1 nu - b^T T b`` (:func:`kalman_update_low_rank`)."""
    G, b = _information(H, nu, r)
    T = solve(_I3 + P @ G, P, strict)
    return np.sum(nu * nu / r, axis=-1) - np.sum(b * (T @ b[..., None])[..., 0], axis=-1)


def nis(mean: np.ndarray, P: np.ndarray, st: StackedReadings) -> np.ndarray:
    """Joint NIS ``nu^T S^-1 nu`` (R,) of every reading of the tick against the prior
    ``(mean, P)`` (R runs), as ``evaluation.metrics.nis`` (all kinds, the told noise);
    linear in the rows over :data:`LOW_RANK_ROWS` (see :func:`kalman_update_low_rank`)."""
    H, nu, r = st.linearise(mean)
    if H.shape[-2] > LOW_RANK_ROWS:
        return nis_low_rank(P, H, nu, r, strict=False)
    S = H @ P @ H.swapaxes(-1, -2)
    add_diagonal(S, r)
    return np.sum(nu * solve(S, nu[..., None], strict=False)[..., 0], axis=-1)


# -- kinds weighed by their record's model ------------------------------------------------
def model_readings(ctx: FilterContext, measurements: Iterable[Measurement]
                   ) -> list[tuple[SensorSpec, Measurement, MeasurementModel]]:
    """The readings of kinds these filters have no form of their own for (not in
    :data:`KINDS`) whose record has a measurement model (core/sensor_kinds.py), each with
    its sensor and model: the EKF linearises them with the model's H and R, the UKF passes
    its sigma points through the model's h. A scan (no model) is left out."""
    out = []
    for m in measurements:
        if m.kind in KINDS or not len(m):
            continue
        model = model_of(m.kind)
        if model is not None:
            out.append((ctx.sensor(m.sensor), m, model))
    return out


def kalman_update_full(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, R: np.ndarray,
                       joseph: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman update of one run with a full noise covariance R (m, m) (correlated
    readings): S = H P H^T + R, K = P H^T S^-1, mean + K nu (heading wrapped),
    P = (I - K H) P (I - K H)^T + K R K^T (Joseph) or P - K H P, symmetrised."""
    HP = H @ P
    S = HP @ H.T + R
    Kt = np.linalg.solve(S, HP)                          # K^T = S^-1 H P
    mean = corrected_mean(np.asarray(mean, dtype=float), Kt, nu)
    K = Kt.T
    if joseph:
        A = _I3 - K @ H
        P = A @ P @ A.T + K @ R @ Kt
    else:
        P = P - K @ HP
    return mean, symmetrise(np.array(P))


# -- process noise -----------------------------------------------------------------------
def process_cov_terms(noise: MotionNoise, theta: Any, c: Any, s: Any, v: Any, omega: Any, dt: float
                      ) -> tuple[Any, ...]:
    """``(q00, q01, q02, q11, q12, q22)`` of ``noise.process_cov(pose, v, omega, dt)`` at the
    heading ``theta`` [rad] (c, s its cos and sin), as floats or as arrays (R,).

    Q = B M B^T + diag(pose_std^2) with B = [[dt cos, 0], [dt sin, 0], [0, dt]] and
    M = diag(sigma_v^2, sigma_omega^2), written out for a plain ``MotionNoise``; any other
    noise object is asked for its ``process_cov`` (floats only).
    """
    if type(noise) is not MotionNoise:
        q = noise.process_cov(np.array([0.0, 0.0, theta]), v, omega, dt).tolist()
        return q[0][0], q[0][1], q[0][2], q[1][1], q[1][2], q[2][2]
    g = noise.slip_gain(v, omega)  # slip scales with the command (1.0 while moving)
    sv = g * noise.v_std + noise.v_frac * abs(v)
    sw = g * noise.omega_std + noise.omega_frac * abs(omega)
    qv = dt * dt * sv * sv
    p0, p1, p2 = (g * p for p in noise.pose_std)
    return (qv * c * c + p0 * p0, qv * c * s, 0.0, qv * s * s + p1 * p1, 0.0,
            dt * dt * sw * sw + p2 * p2)


def cov_entries(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                         np.ndarray]:
    """The six distinct entries (p00, p01, p02, p11, p12, p22) of P (..., 3, 3), as views."""
    return P[..., 0, 0], P[..., 0, 1], P[..., 0, 2], P[..., 1, 1], P[..., 1, 2], P[..., 2, 2]


def cov_matrix(p: Sequence[Any]) -> np.ndarray:
    """The symmetric matrices (R, 3, 3) with the six entries ``p`` (arrays (R,) or floats)."""
    p00, p01, p02, p11, p12, p22 = p
    rows = np.empty((9, *np.shape(p00)))  # row-major entries, one row each (fast to fill)
    rows[0] = p00
    rows[1] = rows[3] = p01
    rows[2] = rows[6] = p02
    rows[4] = p11
    rows[5] = rows[7] = p12
    rows[8] = p22
    return rows.T.reshape(-1, 3, 3)


# -- batching ----------------------------------------------------------------------------
class BatchedGaussian:
    """One Gaussian filter for R runs: ``mean`` (R, 3) [m, m, rad], ``cov`` (R, 3, 3).

    ``predict(v, w, dt)`` takes the commands (R,) [m/s, rad/s]; ``update(st)`` the tick's
    readings (R, M) from a :class:`SlotPacker`.
    """

    #: True when ``update`` leaves the NIS of the tick's readings in ``last_nis`` (for free).
    own_nis: ClassVar[bool] = False

    def __init__(self, mean0: np.ndarray, cov0: np.ndarray, runs: int, noise: MotionNoise):
        self.mean = np.tile(np.asarray(mean0, dtype=float), (runs, 1))
        self.cov = np.tile(np.asarray(cov0, dtype=float), (runs, 1, 1))
        self.noise = noise
        self.last_nis: np.ndarray | None = None

    def predict(self, v: np.ndarray, w: np.ndarray, dt: float) -> None:
        raise NotImplementedError

    def update(self, st: StackedReadings) -> None:
        """No measurement update (dead reckoning)."""


#: Degrees of freedom of one gated group of rows: a beacon's reading or a fix.
READING_DOF = {k: sensor_kind(k).dims for k in KINDS}
#: The gate's chi-square quantile when the scenario tells the filters its readings have
#: outliers and ``gate_chi2`` is not given.
OUTLIER_GATE_QUANTILE = 0.99


def outlier_gate(ctx: FilterContext) -> float:
    """The ``gate_chi2`` an EKF or UKF uses when its parameters do not give one: 0 (no
    gate) unless a sensor the filter is told of (``ctx.sensors``) declares outliers
    (``outlier_rate > 0``); then the chi-square ``OUTLIER_GATE_QUANTILE`` point for the
    most degrees of freedom a gated group of those sensors has (9.21 for range-bearing,
    6.63 for bearings alone). Written into the filter's parameters, so a recording keeps the
    gate it ran with."""
    dofs = [READING_DOF.get(s.kind, 0) for s in ctx.sensors if s.outlier_rate > 0.0]
    dofs = [d for d in dofs if d > 0]
    return chi2_quantile(OUTLIER_GATE_QUANTILE, max(dofs)) if dofs else 0.0


def gate_blocks(st: StackedReadings, nu: np.ndarray, r: np.ndarray, gate: float,
                predicted_cov: Callable[[int, int, int], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The per-run filters' chi-square gate on R runs at once (one home for the EKF's and the
    UKF's batched gate): each beacon's reading (range and bearing together) or fix whose
    squared Mahalanobis distance ``nu_b^T S_b^-1 nu_b`` exceeds ``gate`` fails, with
    ``S_b = predicted_cov(a, b, width) + R_b``; ``predicted_cov`` gives the block's predicted
    part (R, G, width, width) for the rows ``a:b`` in groups of ``width``. ``nu`` (R, M), ``r``
    (M,) or (R, M); empty slots pass (their innovation is 0).

    Returns ``(keep, rejected)``: ``keep`` (R, M) bool, False on the rows of failed readings,
    and ``rejected`` (R,) the readings that failed, per run."""
    R = nu.shape[0]
    rr = np.broadcast_to(r, nu.shape)
    keep = np.ones(nu.shape, dtype=bool)
    rejected = np.zeros(R, dtype=np.int64)
    for kind, a, b, bxy in st.blocks:
        width = (b - a) if bxy is None else (1 if kind == "bearing" else 2)
        if width <= 0 or b <= a:
            continue
        S = predicted_cov(a, b, width) + rr[:, a:b].reshape(R, -1, width)[..., None] * np.eye(width)
        nb = nu[:, a:b].reshape(R, -1, width)
        d = np.einsum("rgi,rgi->rg", nb, np.linalg.solve(S, nb[..., None])[..., 0])
        bad = d > gate
        rejected += bad.sum(axis=1)
        keep[:, a:b] &= ~np.repeat(bad, width, axis=1)
    return keep, rejected


def gated_rows(st: StackedReadings, cov: np.ndarray, H: np.ndarray, nu: np.ndarray,
               r: np.ndarray, gate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-run EKF's gate on R runs at once (:func:`gate_blocks` with ``S = H P H^T +
    R`` against the predicted belief ``cov`` (R, 3, 3)): a failed reading gets H = 0 and
    innovation 0 (it then changes nothing). ``H`` (R, M, 3), ``nu`` (R, M), ``r`` (M,) or
    (R, M) as :meth:`StackedReadings.linearise` gives them. Returns ``(H, nu, rejected)``,
    ``rejected`` (R,) readings dropped."""
    R = nu.shape[0]

    def linearised(a: int, b: int, width: int) -> np.ndarray:
        Hb = H[:, a:b].reshape(R, -1, width, 3)
        return Hb @ cov[:, None] @ Hb.swapaxes(-1, -2)

    keep, rejected = gate_blocks(st, nu, r, gate, linearised)
    return np.where(keep[..., None], H, 0.0), np.where(keep, nu, 0.0), rejected


def effective_gate(flt: FilterBase) -> float:
    """Set ``flt.params["gate_chi2"]`` to :func:`outlier_gate` when nobody chose a gate
    (the filter's context did not give one, and its class's ``defaults`` keep the built-in
    0: a student's subclass that declares its own gate keeps it), and return the gate."""
    if "gate_chi2" not in flt.ctx.params and float(flt.params.get("gate_chi2", 0.0)) == 0.0:
        flt.params["gate_chi2"] = outlier_gate(flt.ctx)
    return float(flt.params["gate_chi2"])


class BatchableFilter(FilterBase):
    """A filter with a form that runs R runs at once (:meth:`batched`).

    ``batch_params`` (declared by the class itself) names the parameters that form
    reproduces: None = any value, else the only value it does. A parameter not named there,
    a subclass that does not declare its own, a motion noise other than a plain
    ``MotionNoise`` or a sensor kind without slots keep the filter to one run at a time.
    """

    batch_params: ClassVar[dict[str, Any]] = {}

    @property
    def batch_blocker(self) -> str | None:
        """Why this filter has no batched form (None: :meth:`batched` reproduces it)."""
        cls = type(self)
        if "batch_params" not in vars(cls):
            return f"{cls.__name__} has no batched form"
        for key, value in self.params.items():
            if key not in cls.batch_params:
                return f"parameter {key} is not batched"
            only = cls.batch_params[key]
            if only is not None and value != only:
                return f"{key} = {value!r} is not batched"
        if type(self.ctx.motion_noise) is not MotionNoise:
            return "the motion noise is not a plain MotionNoise"
        for s in self.ctx.sensors:
            if s.kind not in KINDS:
                return f"sensor kind {s.kind!r} is not batched"
            if s.correspondence != "known":  # the batched runs carry beacon IDs
                return f"sensor {s.name!r} has unknown correspondence (not batched)"
        return None

    def batched(self, runs: int) -> BatchedGaussian:
        """This filter, from its current belief, for ``runs`` runs at once."""
        raise NotImplementedError


__all__ = [
    "ALL_ROWS",
    "BEACON_KINDS",
    "FIX_KINDS",
    "KINDS",
    "LOW_RANK_ROWS",
    "OUTLIER_GATE_QUANTILE",
    "PRESENT_FRACTION",
    "READING_DOF",
    "BatchableFilter",
    "BatchedGaussian",
    "ReadingModels",
    "SlotPacker",
    "StackedReadings",
    "add_diagonal",
    "corrected_mean",
    "cov_entries",
    "cov_matrix",
    "effective_gate",
    "gate_blocks",
    "gated_rows",
    "kalman_update",
    "kalman_update_full",
    "kalman_update_low_rank",
    "model_readings",
    "nis",
    "nis_low_rank",
    "outlier_gate",
    "process_cov_terms",
    "solve",
    "stack",
    "symmetrise",
]
