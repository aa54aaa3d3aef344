"""The Foxglove topics' fixed parts: the frames, colours and sizes, the JSON schemas of
beacon-sim's own topics (``beacon_sim.FilterStats``, ``beacon_sim.BoundStats``,
``beacon_sim.Readings``) and the numbers one ``/filters/NAME/stats`` message carries
(:func:`filter_stats`: error [m, m, rad], sigma, NEES, covariance). The topics themselves are
in :mod:`beacon_sim.io.foxglove`."""


from __future__ import annotations

import math
from typing import Any

import numpy as np

from beacon_sim.core.metrics import pose_errors
from beacon_sim.io.tables import COV_COLUMNS, UPPER

FRAME = "world"
ROBOT_FRAME = "robot"
#: The 95 % x-y ellipse: sqrt of the chi-square quantile for 2 degrees of freedom.
ELLIPSE_SCALE = math.sqrt(-2.0 * math.log(0.05))

TRUTH_COLOUR = (0.1, 0.1, 0.1)

#: Filter colours (r, g, b), in the filters' order, repeated when there are more filters.
FILTER_COLOURS = ((0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
                  (0.58, 0.4, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5))

READING_COLOUR = (0.9, 0.6, 0.0)

#: Points of one trail entity: a path is sent in pieces of this many ticks, so each tick's
#: message stays small (only the last piece changes).
TRAIL_PIECE = 50

#: The numbers of ``/filters/NAME/stats`` (beacon_sim.FilterStats), with their units.
STATS_FIELDS = ("err_x_m", "err_y_m", "err_theta_rad", "err_pos_m", "sigma_x_m", "sigma_y_m",
                "sigma_theta_rad", "nees", *COV_COLUMNS)

#: The most particles ``/filters/NAME/particles`` carries per tick.
MAX_PARTICLES_SHOWN = 500

BOUND_COLOUR = (0.35, 0.35, 0.35)

#: The numbers of ``/pcrb/stats`` (beacon_sim.BoundStats).
BOUND_FIELDS = ("sigma_x_m", "sigma_y_m", "sigma_theta_rad", "sigma_pos_m", *COV_COLUMNS)

_STAMP = {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                          "nsec": {"type": "integer", "minimum": 0}},
          "required": ["sec", "nsec"]}

BOUND_SCHEMA: dict[str, Any] = {
    "title": "beacon_sim.BoundStats", "type": "object",
    "description": "The posterior Cramer-Rao bound at one tick: no unbiased estimator's error "
                   "covariance is smaller. sigma_pos_m: sqrt of the x-y block's largest eigenvalue",
    "properties": {"timestamp": _STAMP, "tick": {"type": "integer", "minimum": 0},
                   **{f: {"type": ["number", "null"]} for f in BOUND_FIELDS}},
    "required": ["timestamp", "tick", *BOUND_FIELDS],
}

#: A reading's numbers on ``/readings/values`` (null where its kind has none).
READING_FIELDS = ("range_m", "bearing_rad", "x_m", "y_m", "theta_rad")

READINGS_SCHEMA: dict[str, Any] = {
    "title": "beacon_sim.Readings", "type": "object",
    "description": "One tick's landmark readings (range finder scans are on /scan/SENSOR): "
                   "sensor, kind, beacon ID (-1 for a fix or an unknown ID) and the numbers, "
                   "robot frame for range and bearing, world frame for a fix",
    "properties": {
        "timestamp": _STAMP, "tick": {"type": "integer", "minimum": 0},
        "readings": {"type": "array", "items": {
            "type": "object",
            "properties": {"sensor": {"type": "string"}, "kind": {"type": "string"},
                           "beacon_id": {"type": "integer"},
                           **{f: {"type": ["number", "null"]} for f in READING_FIELDS}},
            "required": ["sensor", "kind", "beacon_id", *READING_FIELDS]}},
    },
    "required": ["timestamp", "tick", "readings"],
}

STATS_SCHEMA: dict[str, Any] = {
    "title": "beacon_sim.FilterStats", "type": "object",
    "description": "A filter's estimate against the truth at one tick: error (estimate - truth, "
                   "heading wrapped), standard deviations from its covariance, NEES (e^T P^-1 e; "
                   "null when P is singular)",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                                       "nsec": {"type": "integer", "minimum": 0}},
                      "required": ["sec", "nsec"]},
        "tick": {"type": "integer", "minimum": 0},
        **{f: {"type": ["number", "null"]} for f in STATS_FIELDS},
        "particles_total": {"type": "integer", "minimum": 0,
                            "description": "a particle filter: its particle count"},
        "particles_shown": {"type": "integer", "minimum": 0,
                            "description": "a particle filter: how many /filters/NAME/particles carries"},
    },
    "required": ["timestamp", "tick", *STATS_FIELDS],
}

#: The JSON topics' schemas, by the kind :meth:`Publisher.channel` takes.
JSON_SCHEMAS = {"stats": STATS_SCHEMA, "bound": BOUND_SCHEMA, "readings": READINGS_SCHEMA}

def colour_of(index: int) -> tuple[float, float, float]:
    return FILTER_COLOURS[index % len(FILTER_COLOURS)]

def filter_stats(mean: np.ndarray, cov: np.ndarray, truth: np.ndarray) -> dict[str, float | None]:
    """Error [m, m, rad], sigma [m, m, rad] and NEES of one estimate, as the ``estimates``
    table computes them (the same operations, so the same bits)."""
    err = pose_errors(np.asarray(mean, dtype=float)[None], np.asarray(truth, dtype=float)[None])[0]
    with np.errstate(all="ignore"):
        try:
            nees: float | None = float(err @ np.linalg.solve(cov, err))
        except np.linalg.LinAlgError:
            nees = None
        sig = np.sqrt(np.diag(cov))
    out: dict[str, float | None] = {"err_x_m": float(err[0]), "err_y_m": float(err[1]),
                                    "err_theta_rad": float(err[2]),
                                    "err_pos_m": float(np.hypot(err[0], err[1]))}
    out.update({"sigma_x_m": float(sig[0]), "sigma_y_m": float(sig[1]), "sigma_theta_rad": float(sig[2]),
                "nees": nees})
    cov = np.asarray(cov, dtype=float)
    out.update({c: float(cov[i, j]) for c, (i, j) in zip(COV_COLUMNS, UPPER, strict=True)})
    return {k: (v if v is None or math.isfinite(v) else None) for k, v in out.items()}

