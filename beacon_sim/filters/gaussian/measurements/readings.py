"""A tick's readings as one stacked vector for the Gaussian filters (one run or R runs):
the kinds they have fast forms of, the readings' models (``ReadingModels``), ``z`` with its
noise variances and angle rows (``StackedReadings``: h at many poses, H and the innovation),
``stack`` for one run, and the readings of other kinds weighed by their record's model.

Shapes: one run (m,), R runs (R, M); poses [m, m, rad], world frame."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from beacon_sim.core.angles import wrap as wrap_angle
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.sensor_kind import MeasurementModel
from beacon_sim.core.sensor_kinds import beacon_kinds, model_of, sensor_kind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterContext, FilterError

#: The kinds these filters have fast forms of (any other: its record's model,
#: :func:`model_readings`); which of them name a beacon per row, and their angle columns,
#: come from their records (core/sensor_kinds.py).
KINDS = ("bearing", "range_bearing", "pose", "position")
BEACON_KINDS = beacon_kinds(KINDS)
FIX_KINDS = tuple(k for k in KINDS if k not in BEACON_KINDS)
#: The angle columns of a row of each of :data:`KINDS`.
ANGLE_PATTERN = {k: sensor_kind(k).angles for k in KINDS}
_I3 = np.eye(3)

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


def angle_rows(blocks: list[Block], angle: np.ndarray) -> AngleRows:
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
        return StackedReadings(self.z[..., cols], self.r[..., cols], angle, angle_rows(blocks, angle),
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
            angles.extend(ANGLE_PATTERN[m.kind] * k)
            n = k * len(var)
        else:
            var = models.fix_var(m)
            rs.extend(var)
            angles.extend(ANGLE_PATTERN[m.kind])
            bxy = None
            n = len(var)
        zs.append(m.z.reshape(-1))
        blocks.append((m.kind, m0, m0 + n, bxy))
        m0 += n
    if not blocks:
        return None
    z = zs[0] if len(zs) == 1 else np.concatenate(zs)
    angle = np.array(angles)
    return StackedReadings(np.asarray(z, dtype=float), np.array(rs), angle, angle_rows(blocks, angle),
                           blocks)


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


__all__ = ["ALL_ROWS", "ANGLE_PATTERN", "BEACON_KINDS", "FIX_KINDS", "KINDS", "PRESENT_FRACTION",
           "AngleRows", "Block", "ReadingModels", "StackedReadings", "angle_rows",
           "model_readings", "stack"]
