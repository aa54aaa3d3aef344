"""Occupancy grids: the map value, world <-> cell conversion, ROS map_server files, walls.

Frames (docs/maps.md): the world is metres, x right, y up. A grid's cell ``(row, col)`` covers
``[col, col + 1) x [row, row + 1)`` in *grid units* (cells), measured from the map's
``origin`` (x, y, yaw) -- the world pose of the lower-left corner of cell (0, 0), as in ROS
map_server. Row 0 is the bottom row (the image's last line), as in ``nav_msgs/OccupancyGrid``.

Cell values are trinary like map_server's default mode: ``FREE`` (0), ``OCCUPIED`` (100),
``UNKNOWN`` (-1).

The map_server YAML is read with PyYAML when it is installed (the ``maps`` extra: any valid
YAML), else its flat subset (``key: value`` lines, ``#`` comments, ``origin: [x, y, yaw]``)
by hand, so the basic install needs no YAML library. PGM
images (P5 binary and P2 ASCII, 8 or 16 bit) are read and written with numpy; PNG needs
Pillow (the ``gif`` extra) and says so in one line when it is absent.
"""

from __future__ import annotations

import io
import itertools
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.files import atomic_write, read_user_bytes, read_user_text, write_text_atomic
from beacon_sim.core.optional import install_hint, optional
from beacon_sim.core.types import read_only
from beacon_sim.errors import BeaconSimError

FREE = 0
OCCUPIED = 100
UNKNOWN = -1

#: The largest image accepted, in pixels (cells): 16.7 million (4096 x 4096), ~17 MB as int8.
MAX_CELLS = 4096 * 4096

#: The largest PGM file read [bytes]: MAX_CELLS values of up to 5 digits and a space (P2).
MAX_PGM_BYTES = 6 * MAX_CELLS + 4096

#: The largest PNG file read [bytes]: MAX_CELLS pixels of 16-bit RGBA, uncompressed, and 1 MiB.
MAX_PNG_BYTES = 8 * MAX_CELLS + 2**20

#: The largest map YAML read [bytes].
MAX_YAML_BYTES = 1_000_000

#: The keys a map_server YAML must have (``negate`` defaults to 0, ``mode`` to trinary).
REQUIRED_KEYS = ("image", "resolution", "origin", "occupied_thresh", "free_thresh")


class MapError(BeaconSimError):
    """A map file or map description is missing, unreadable or invalid (one line)."""


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A trinary occupancy grid.

    Attributes
    ----------
    cells : ndarray, shape (rows, cols), int8
        ``FREE``, ``OCCUPIED`` or ``UNKNOWN``; row 0 is the bottom row (smallest y).
    resolution : float
        Side of one square cell [m/cell], > 0.
    origin : tuple of 3 floats
        World pose (x [m], y [m], yaw [rad]) of the lower-left corner of cell (0, 0).
    """

    cells: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        cells = np.asarray(self.cells)
        if cells.ndim != 2 or cells.size == 0:
            raise MapError(f"occupancy grid: cells must be a non-empty 2-D array, got shape {cells.shape}")
        if cells.size > MAX_CELLS:
            raise MapError(f"occupancy grid: {cells.shape[1]}x{cells.shape[0]} cells is over the cap "
                           f"of {MAX_CELLS} cells")
        if not np.isin(cells, (FREE, OCCUPIED, UNKNOWN)).all():
            raise MapError("occupancy grid: cells must be 0 (free), 100 (occupied) or -1 (unknown)")
        res = float(self.resolution)
        if not math.isfinite(res) or res <= 0:
            raise MapError(f"occupancy grid: resolution must be a number > 0 [m/cell], "
                           f"got {self.resolution!r}")
        origin = tuple(float(v) for v in self.origin)
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise MapError(f"occupancy grid: origin must be 3 finite numbers [x, y, yaw], "
                           f"got {self.origin!r}")
        object.__setattr__(self, "cells", read_only(cells.astype(np.int8)))
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "origin", origin)

    def __getstate__(self) -> dict:
        """Pickled without the cached properties (rebuilt on use)."""
        return {k: v for k, v in self.__dict__.items() if k in self.__dataclass_fields__}

    def __eq__(self, other: object) -> bool:
        """Equal when the cells, the resolution and the origin are (a value, like the
        scenario that holds it: a replay compares the scenario it rebuilt)."""
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (self.resolution == other.resolution and self.origin == other.origin
                and self.cells.shape == other.cells.shape and bool(np.array_equal(self.cells, other.cells)))

    def __hash__(self) -> int:
        return hash((self.resolution, self.origin, self.cells.shape, self._digest))

    @cached_property
    def _digest(self) -> bytes:
        import hashlib

        return hashlib.sha256(self.cells.tobytes()).digest()

    def sha256(self) -> str:
        """SHA-256 (64 hex digits) of the grid as a value: its shape, resolution, origin
        (their reprs, exact for floats) and cells (int8, row 0 first). Equal grids, equal
        digests: what a recording stores to name its map (docs/replay.md)."""
        import hashlib

        rows, cols = self.shape
        head = f"{rows} {cols} {self.resolution!r} {self.origin[0]!r} {self.origin[1]!r} {self.origin[2]!r}\n"
        return hashlib.sha256(head.encode("ascii") + self.cells.tobytes()).hexdigest()

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return int(self.cells.shape[0]), int(self.cells.shape[1])

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the grid [m] (along its own axes)."""
        return self.shape[1] * self.resolution, self.shape[0] * self.resolution

    @cached_property
    def occupied(self) -> np.ndarray:
        """Boolean mask of occupied cells, shape (rows, cols); unknown counts as free."""
        return read_only(self.cells == OCCUPIED)

    @cached_property
    def _rotation(self) -> tuple[float, float]:
        yaw = self.origin[2]
        s, c = pm.sincos1(float(yaw))   # portable: the walls' frame is part of the truth
        return c, s

    def world_to_grid(self, xy) -> np.ndarray:
        """Continuous grid coordinates (u along columns, v along rows) [cells] of world points.

        ``xy`` has shape (..., 2) [m]; the result has the same shape. Cell (row, col) is
        ``(floor(v), floor(u))``.
        """
        xy = np.asarray(xy, dtype=float)
        c, s = self._rotation
        dx = xy[..., 0] - self.origin[0]
        dy = xy[..., 1] - self.origin[1]
        inv = 1.0 / self.resolution
        return np.stack([(c * dx + s * dy) * inv, (-s * dx + c * dy) * inv], axis=-1)

    def grid_to_world(self, uv) -> np.ndarray:
        """World points [m] of continuous grid coordinates ``uv`` (..., 2) [cells]."""
        uv = np.asarray(uv, dtype=float) * self.resolution
        c, s = self._rotation
        x = self.origin[0] + c * uv[..., 0] - s * uv[..., 1]
        y = self.origin[1] + s * uv[..., 0] + c * uv[..., 1]
        return np.stack([x, y], axis=-1)

    def world_to_cell(self, xy) -> np.ndarray:
        """Integer cell indices ``(row, col)``, shape (..., 2), of world points [m] (may lie
        outside the grid: check with :meth:`in_grid`)."""
        uv = np.floor(self.world_to_grid(xy)).astype(np.int64)
        return np.stack([uv[..., 1], uv[..., 0]], axis=-1)

    def cell_to_world(self, rc) -> np.ndarray:
        """World position [m], shape (..., 2), of the centres of cells ``(row, col)``."""
        rc = np.asarray(rc, dtype=float)
        return self.grid_to_world(np.stack([rc[..., 1] + 0.5, rc[..., 0] + 0.5], axis=-1))

    def in_grid(self, rc) -> np.ndarray:
        """Whether cell indices ``(row, col)`` (..., 2) lie inside the grid."""
        rc = np.asarray(rc)
        rows, cols = self.shape
        return (rc[..., 0] >= 0) & (rc[..., 0] < rows) & (rc[..., 1] >= 0) & (rc[..., 1] < cols)

    def is_occupied(self, xy) -> np.ndarray:
        """Whether world points [m] (..., 2) fall in occupied cells (outside the grid: False)."""
        rc = self.world_to_cell(xy)
        inside = self.in_grid(rc)
        rows, cols = self.shape
        r = np.clip(rc[..., 0], 0, rows - 1)
        c = np.clip(rc[..., 1], 0, cols - 1)
        return inside & self.occupied[r, c]


# --------------------------------------------------------------------------- walls


def from_walls(bounds: tuple[float, float, float, float], resolution: float, *,
               segments: Iterable[Sequence[Sequence[float]]] = (),
               polygons: Iterable[Sequence[Sequence[float]]] = ()) -> OccupancyGrid:
    """Rasterise walls into a grid covering ``bounds`` (xmin, ymin, xmax, ymax) [m].

    ``segments`` are polylines ``[(x0, y0), (x1, y1), ...]`` [m]: every cell a line passes
    through is occupied (a line on the far edge, x = xmax or y = ymax, occupies the last
    column or row). ``polygons`` are closed outlines: their edges are drawn the same
    way and every cell whose centre lies inside (even-odd rule) is filled. All other cells
    are free. The grid's origin is (xmin, ymin, 0).
    """
    xmin, ymin, xmax, ymax = (float(b) for b in bounds)
    res = float(resolution)
    if not (math.isfinite(res) and res > 0):
        raise MapError(f"walls: resolution must be a number > 0 [m/cell], got {resolution!r}")
    if not (xmax > xmin and ymax > ymin):
        raise MapError(f"walls: bounds must be (xmin, ymin, xmax, ymax) with xmax > xmin and ymax > ymin, "
                       f"got {bounds!r}")
    cols = math.ceil((xmax - xmin) / res - 1e-9)
    rows = math.ceil((ymax - ymin) / res - 1e-9)
    if rows * cols > MAX_CELLS:
        raise MapError(f"walls: {cols}x{rows} cells is over the cap of {MAX_CELLS} cells")
    occ = np.zeros((rows, cols), dtype=bool)

    def grid_pts(points, what: str) -> np.ndarray:
        p = np.asarray(points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2 or not np.isfinite(p).all():
            raise MapError(f"walls: each {what} must be a list of at least two [x, y] points, got {points!r}")
        return np.stack([(p[:, 0] - xmin) / res, (p[:, 1] - ymin) / res], axis=1)

    for line in segments:
        _draw_polyline(occ, grid_pts(line, "segment"), closed=False)
    for poly in polygons:
        uv = grid_pts(poly, "polygon")
        _fill_polygon(occ, uv)
        _draw_polyline(occ, uv, closed=True)
    cells = np.where(occ, OCCUPIED, FREE).astype(np.int8)
    return OccupancyGrid(cells, res, (xmin, ymin, 0.0))


def _draw_polyline(occ: np.ndarray, uv: np.ndarray, *, closed: bool) -> None:
    """Mark every cell each segment of the polyline ``uv`` [cells] passes through, and where
    a slanted segment passes exactly through a grid corner, the two cells beside it too: a
    ray through a corner passes between diagonal neighbours (raycast.py), so a wall must not
    have such a gap."""
    pts = np.vstack([uv, uv[:1]]) if closed else uv
    rows, cols = occ.shape
    for a, b in itertools.pairwise(pts):
        d = b - a
        length = pm.hypot1(float(d[0]), float(d[1]))
        corners = np.zeros((0, 2))
        if length == 0.0:
            ts = np.zeros(1)
        else:
            # Exact cells: the segment's ends and every grid-line crossing between them split it
            # into pieces that each lie in one cell; the midpoint of a piece names that cell.
            t = [0.0, 1.0]
            crossings = []
            for axis in (0, 1):
                if d[axis] != 0.0:
                    lo, hi = sorted((a[axis], b[axis]))
                    lines = np.arange(math.floor(lo) + 1, math.ceil(hi))
                    crossings.append((lines - a[axis]) / d[axis])
                    t.extend(crossings[-1].tolist())
            t_sorted = np.unique(np.clip(np.array(t), 0.0, 1.0))
            ts = np.concatenate([(t_sorted[:-1] + t_sorted[1:]) / 2, [0.0, 1.0]])
            if len(crossings) == 2:   # slanted: the crossings of both kinds of line at once
                tu, tv = np.sort(crossings[0]), np.sort(crossings[1])
                j = np.clip(np.searchsorted(tv, tu), 0, max(tv.size - 1, 0))
                at = tu[(tv.size > 0) & (np.abs(tv[j] - tu) <= 1e-9)] if tv.size else tu[:0]
                corners = np.rint(a + at[:, None] * d)
        p = a + ts[:, None] * d
        c = np.floor(p[:, 0]).astype(int)
        r = np.floor(p[:, 1]).astype(int)
        if corners.size:   # the side cells: (c - [d_u < 0], r - [d_v > 0]) and its mirror
            cu, cv = corners[:, 0].astype(int), corners[:, 1].astype(int)
            side_c = np.concatenate([cu - int(d[0] < 0), cu - int(d[0] > 0)])
            side_r = np.concatenate([cv - int(d[1] > 0), cv - int(d[1] < 0)])
            c, r = np.concatenate([c, side_c]), np.concatenate([r, side_r])
            p = np.vstack([p, np.column_stack([side_c + 0.5, side_r + 0.5])])
        # A wall on the far edge of the bounds (x = xmax or y = ymax) belongs to the last
        # column / row, not to the cell beyond the grid.
        c[(c == cols) & (p[:, 0] <= cols * (1 + 1e-9))] = cols - 1
        r[(r == rows) & (p[:, 1] <= rows * (1 + 1e-9))] = rows - 1
        ok = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        occ[r[ok], c[ok]] = True


def _fill_polygon(occ: np.ndarray, uv: np.ndarray) -> None:
    """Fill the cells whose centres are inside the closed polygon ``uv`` [cells] (even-odd)."""
    rows, cols = occ.shape
    cu = np.arange(cols) + 0.5
    cv = np.arange(rows) + 0.5
    inside = np.zeros((rows, cols), dtype=bool)
    x0, y0 = uv[:, 0], uv[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    for xa, ya, xb, yb in zip(x0, y0, x1, y1, strict=True):
        if ya == yb:
            continue
        crosses = (cv[:, None] >= min(ya, yb)) & (cv[:, None] < max(ya, yb))
        x_at = xa + (cv[:, None] - ya) * (xb - xa) / (yb - ya)
        inside ^= crosses & (cu[None, :] < x_at)
    occ |= inside


# --------------------------------------------------------------------------- map_server files


def _parse_value(text: str):
    """A value of a map_server YAML line: a flat list (its items scalars: a nested list is
    not read, so its text reaches the key's check) or a scalar."""
    text = text.strip()
    if text.startswith("[") and text.endswith("]"):
        inner = text[1:-1].strip()
        return [_parse_scalar(p) for p in inner.split(",")] if inner else []
    return _parse_scalar(text)


def _parse_scalar(text: str):
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1]
    if text in ("true", "True", "false", "False"):
        return text.lower() == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


#: The keys whose values are numbers (a YAML 1.1 reader takes ``5e-2``, no dot, as a string).
_NUMBER_KEYS = ("resolution", "occupied_thresh", "free_thresh", "negate")


def parse_map_yaml(text: str, source: str) -> dict:
    """The mapping of a map_server YAML text (``source`` names it in errors).

    With PyYAML installed (the ``maps`` extra), any valid YAML: a leading ``---``, an origin
    as a block list, ``negate: false``, a one-line ``{...}`` mapping. Without it, the flat
    subset map_server writes (:func:`parse_flat_map_yaml`); both give the same mapping for
    that subset (tests/core/test_map_yaml.py).
    """
    yaml = optional("yaml")
    if yaml is None:
        return parse_flat_map_yaml(text, source)
    try:
        meta = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        why = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise MapError(f"{source}: {where}not valid YAML: {why}") from None
    if not isinstance(meta, dict):
        raise MapError(f"{source}: expected a mapping of 'key: value' lines, got {type(meta).__name__}")
    out = {str(k): v for k, v in meta.items()}
    for key in _NUMBER_KEYS:
        value = out.get(key)
        if isinstance(value, str):
            out[key] = _parse_scalar(value)
    if isinstance(out.get("origin"), list):
        out["origin"] = [_parse_scalar(v) if isinstance(v, str) else v for v in out["origin"]]
    return out


def parse_flat_map_yaml(text: str, source: str) -> dict:
    """The flat ``key: value`` mapping of a map_server YAML text, read by hand (the base
    install's reader): ``key: value`` lines, ``#`` comments, ``[a, b, c]`` lists, a leading
    ``---``; a line it cannot read is an error naming the line and PyYAML."""
    out: dict = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = re.sub(r"\s+#.*$", "", raw).strip() if not raw.lstrip().startswith("#") else ""
        if not line or (line in ("---", "...") and not out):
            continue
        key, sep, value = line.partition(":")
        if not sep or not re.fullmatch(r"[A-Za-z_][\w.-]*", key.strip()):
            raise MapError(f"{source}: line {number}: expected 'key: value', got {raw.strip()!r} "
                           f"(this reader takes map_server's flat form; for any YAML: "
                           f"{install_hint('yaml', 'reading it')})")
        out[key.strip()] = _parse_value(value)
    return out


def _number(meta: dict, key: str, source: str) -> float:
    value = meta[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapError(f"{source}: key {key!r} must be a number, got {value!r}")
    return float(value)


def load_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a ROS map_server map: the YAML file and the image it names (relative to it).

    Each pixel's occupancy probability is ``p = (255 - value) / 255`` (``negate: 0``) or
    ``value / 255`` (``negate: 1``), colour channels averaged; ``p > occupied_thresh`` is
    occupied, ``p < free_thresh`` free, anything else unknown (map_server's trinary mode).
    """
    path = Path(yaml_path)
    text = read_user_text(path, what="map file", cap=MAX_YAML_BYTES, error=MapError,
                          hint=" (a map_server YAML)")
    meta = parse_map_yaml(text, str(path))
    for key in REQUIRED_KEYS:
        if key not in meta:
            raise MapError(f"{path}: missing key {key!r} "
                           f"(a map_server YAML needs {', '.join(REQUIRED_KEYS)})")
    resolution = _number(meta, "resolution", str(path))
    if resolution <= 0:
        raise MapError(f"{path}: key 'resolution' must be > 0 [m/cell], got {meta['resolution']!r}")
    occ_t = _number(meta, "occupied_thresh", str(path))
    free_t = _number(meta, "free_thresh", str(path))
    for key, v in (("occupied_thresh", occ_t), ("free_thresh", free_t)):
        if not 0.0 <= v <= 1.0:
            raise MapError(f"{path}: key {key!r} must be in [0, 1], got {v!r}")
    if free_t >= occ_t:
        raise MapError(f"{path}: key 'free_thresh' ({free_t}) must be below 'occupied_thresh' ({occ_t})")
    origin = meta["origin"]
    if (not isinstance(origin, list) or len(origin) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                       for v in origin)):
        raise MapError(f"{path}: key 'origin' must be [x, y, yaw] (3 numbers), got {origin!r}")
    negate = meta.get("negate", 0)
    if negate not in (0, 1):
        raise MapError(f"{path}: key 'negate' must be 0 or 1, got {negate!r}")
    mode = meta.get("mode", "trinary")
    if mode != "trinary":
        raise MapError(f"{path}: key 'mode' must be 'trinary' (the only mode read), got {mode!r}")
    image = meta["image"]
    if not isinstance(image, str) or not image:
        raise MapError(f"{path}: key 'image' must be a file name, got {image!r}")
    image_path = path.parent / image
    pixels = read_image(image_path)
    p = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    cells = np.full(p.shape, UNKNOWN, dtype=np.int8)
    cells[p > occ_t] = OCCUPIED
    cells[p < free_t] = FREE
    x, y, yaw = (float(v) for v in origin)
    return OccupancyGrid(cells[::-1].copy(), resolution, (x, y, yaw))


def save_map(grid: OccupancyGrid, yaml_path: str | Path, *, image: str | None = None,
             negate: int = 0, occupied_thresh: float = 0.65, free_thresh: float = 0.196,
             ascii_pgm: bool = False) -> Path:
    """Write ``grid`` as a map_server YAML and a PGM image beside it (map_saver's values:
    free 254, occupied 0, unknown 205, inverted when ``negate`` is 1). Returns the image path.
    ``ascii_pgm`` writes P2 instead of P5."""
    path = Path(yaml_path)
    if negate not in (0, 1):
        raise MapError(f"{path}: negate must be 0 or 1, got {negate!r}")
    if not (0.0 <= free_thresh < occupied_thresh <= 1.0):
        raise MapError(f"{path}: need 0 <= free_thresh < occupied_thresh <= 1, got "
                       f"{free_thresh}, {occupied_thresh}")
    image_name = image or path.with_suffix(".pgm").name
    grey_free, grey_occupied, grey_unknown = _save_greys(free_thresh, occupied_thresh, path)
    values = np.full(grid.shape, grey_unknown, dtype=np.uint8)
    values[grid.cells == FREE] = grey_free
    values[grid.cells == OCCUPIED] = grey_occupied
    if negate:
        values = 255 - values
    image_path = path.parent / image_name
    write_pgm(image_path, values[::-1], ascii_pgm=ascii_pgm)
    x, y, yaw = grid.origin
    write_text_atomic(
        path,
        f"image: {image_name}\nresolution: {grid.resolution!r}\norigin: [{x!r}, {y!r}, {yaw!r}]\n"
        f"negate: {negate}\noccupied_thresh: {occupied_thresh!r}\nfree_thresh: {free_thresh!r}\n"
        "mode: trinary\n", what="map YAML", error=MapError)
    return image_path


def _save_greys(free_thresh: float, occupied_thresh: float, path: Path) -> tuple[int, int, int]:
    """Grey values (negate 0) that load back as free, occupied and unknown under the given
    thresholds: map_saver's 254, 0 and 205 where they do, the nearest that do otherwise."""
    def p(v: int) -> float:
        return (255.0 - v) / 255.0
    free = 254 if p(254) < free_thresh else 255
    occupied = 0
    middle = round(255.0 * (1.0 - (free_thresh + occupied_thresh) / 2))
    unknown = 205 if free_thresh <= p(205) <= occupied_thresh else middle
    if not (p(free) < free_thresh and p(occupied) > occupied_thresh
            and free_thresh <= p(unknown) <= occupied_thresh):
        raise MapError(f"{path}: thresholds free {free_thresh}, occupied {occupied_thresh} leave no "
                       "8-bit grey value for a free, occupied or unknown cell")
    return free, occupied, unknown


def read_image(path: Path) -> np.ndarray:
    """Grey values 0..255 (float, shape (height, width), top line first) of a PGM or PNG."""
    if path.suffix.lower() == ".png":
        return _read_png(path)
    data = read_user_bytes(path, what="map image", cap=MAX_PGM_BYTES, error=MapError,
                           hint=f" (a PGM of {MAX_CELLS:,} pixels)")
    return read_pgm_bytes(data, str(path))


def png_size(data: bytes, source: str) -> tuple[int, int]:
    """(width, height) from a PNG file's IHDR chunk, read before anything is decoded."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR" or len(data) < 24:
        raise MapError(f"{source}: not a PNG image (no PNG signature and IHDR header)")
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def _read_png(path: Path) -> np.ndarray:
    try:
        from PIL import Image
    except ImportError:
        raise MapError(f"{path}: {install_hint('PIL', 'reading PNG maps')}, "
                       "or convert the image to PGM") from None
    data = read_user_bytes(path, what="map image", cap=MAX_PNG_BYTES, error=MapError)
    w, h = png_size(data, str(path))
    if w * h > MAX_CELLS:  # before Pillow sees it: no DecompressionBombWarning or Error
        raise MapError(f"{path}: image of {w}x{h} pixels is over the cap of {MAX_CELLS} pixels "
                       "(cells)")
    try:
        with Image.open(io.BytesIO(data), formats=["PNG"]) as img:
            mode = img.mode
            if mode in ("L", "1", "LA"):          # grey (alpha ignored, as map_server's trinary mode)
                arr = np.asarray(img.convert("L"), dtype=float)
            elif mode.startswith("I"):            # 16-bit grey: scaled to 0..255, not clipped
                arr = np.asarray(img, dtype=float) * (255.0 / 65535.0)
            else:                                 # colour and palette: the channels' mean
                arr = np.asarray(img.convert("RGB"), dtype=float).mean(axis=2)
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise MapError(f"{path}: cannot read the map image ({exc.__class__.__name__})") from None
    return arr


def read_pgm_bytes(data: bytes, source: str) -> np.ndarray:
    """Grey values 0..255 (float, top line first) of a P5 or P2 PGM file's bytes."""
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise MapError(f"{source}: not a PGM image (expected P5 or P2, got {magic!r})")
    fields: list[bytes] = []
    pos = 2
    n = len(data)
    while len(fields) < 3:
        while pos < n and data[pos:pos + 1].isspace():
            pos += 1
        if pos < n and data[pos:pos + 1] == b"#":
            while pos < n and data[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < n and not data[pos:pos + 1].isspace() and data[pos:pos + 1] != b"#":
            pos += 1
        if start == pos:
            raise MapError(f"{source}: PGM header ends early (expected width, height, maxval)")
        fields.append(data[start:pos])
    try:
        width, height, maxval = (int(f) for f in fields)
    except ValueError:
        raise MapError(f"{source}: PGM header must give integers width, height, maxval, got "
                       f"{b' '.join(fields)[:60]!r}") from None
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise MapError(f"{source}: PGM header out of range (width {width}, height {height}, maxval {maxval})")
    if width * height > MAX_CELLS:
        raise MapError(f"{source}: image of {width}x{height} pixels is over the cap of {MAX_CELLS} pixels "
                       "(cells)")
    count = width * height
    if magic == b"P5":
        pos += 1  # exactly one whitespace byte before the raster
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        raster = data[pos:]
        if len(raster) != count * dtype.itemsize:
            raise MapError(f"{source}: PGM raster has {len(raster)} bytes, the header's {width}x{height} "
                           f"needs {count * dtype.itemsize}")
        values = np.frombuffer(raster, dtype=dtype).astype(float)
    else:
        try:
            values = np.array(data[pos:].split(), dtype=float)
        except ValueError:
            raise MapError(f"{source}: P2 raster must be whitespace-separated integers") from None
        if values.size != count:
            raise MapError(f"{source}: PGM raster has {values.size} values, the header's {width}x{height} "
                           f"needs {count}")
        if values.size and (values.min() < 0 or values.max() > maxval):
            raise MapError(f"{source}: PGM values must lie in [0, {maxval}]")
    values = values.reshape(height, width)
    return values if maxval == 255 else values * (255.0 / maxval)


def write_pgm(path: Path, values: np.ndarray, *, ascii_pgm: bool = False) -> None:
    """Write 8-bit grey ``values`` (shape (height, width), top line first) as P5 (or P2),
    whole or not at all (the previous file stays on an error)."""
    values = np.asarray(values, dtype=np.uint8)
    h, w = values.shape
    if ascii_pgm:
        rows = "\n".join(" ".join(str(int(v)) for v in row) for row in values)
        data = f"P2\n# beacon-sim map\n{w} {h}\n255\n{rows}\n".encode("ascii")
    else:
        data = f"P5\n# beacon-sim map\n{w} {h}\n255\n".encode("ascii") + values.tobytes()
    with atomic_write(path, "wb", what="map image", error=MapError) as fh:
        fh.write(data)
