"""R runs' readings in fixed slots (``SlotPacker``): every beacon of every beacon sensor and
every fix row has its slot, so a run's numbers never depend on the other runs of its batch.
Empty slots have z = 0, r = 1 and ``valid`` False: H = 0 and innovation 0 there."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from beacon_sim.core.batch_simulation import BatchTick, BeaconReadings
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.gaussian.measurements.readings import (
    ANGLE_PATTERN,
    BEACON_KINDS,
    FIX_KINDS,
    Block,
    StackedReadings,
    angle_rows,
)


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
                width = n = len(ANGLE_PATTERN[s.kind])
                bxy = None
                self.slots_of[s.name] = np.arange(a, a + n)
                r0.extend([1.0] * n)
            else:
                raise FilterError(f"sensor kind {s.kind!r} has no batched readings")
            self.blocks.append((s.kind, a, a + n, bxy))
            angles.extend(ANGLE_PATTERN[s.kind] * (n // width))
            a += n
        self.M = a
        self.angle = np.array(angles, dtype=bool)
        self.angle_sel = angle_rows(self.blocks, self.angle)
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


__all__ = ["SlotPacker"]
