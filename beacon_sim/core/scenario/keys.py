"""Every key each table of a scenario may hold (a sensor's include the keys every registered
kind declares, core/sensor_kinds.py), so that an unknown key gets a "did you mean" even when
the key it resembles was not written in the file."""

from __future__ import annotations

import re

from beacon_sim.core.sensor_kinds import param_keys

_NOISE_KEYS = {"v_std", "v_frac", "omega_std", "omega_frac", "pose_std"}
_SENSOR_NOISE_KEYS = {"bearing_std", "range_std", "position_std", "heading_std"}
#: A laser scan's keys (a kind whose record has ``scan``; docs/maps.md): beams per scan and the
#: truth's beam model.
RANGE_MODEL_KEYS = ("z_hit", "z_short", "z_max", "z_rand", "sigma_hit", "lambda_short")
_RANGE_FINDER_KEYS = {"n_beams", *RANGE_MODEL_KEYS}


_KNOWN: dict[str, set[str]] = {
    "": {"name", "description", "dt", "duration", "seed", "world", "robot", "sensors",
         "driver", "keyboard", "events", "initial_belief", "model", "default_filters",
         "filters"},
    "world": {"bounds", "beacons", "map", "walls"},
    "world.walls": {"resolution", "segments", "polygons"},
    "world.beacons[]": {"id", "x", "y", "anchor"},
    "robot": {"initial_pose", "radius", "motion_noise"},
    "robot.motion_noise": _NOISE_KEYS,
    "sensors[]": {"name", "kind", "period", "max_range", "fov", "detection_prob",
                  "outlier_rate", "min_beacons", "beacon_height", "correspondence",
                  "clutter_rate", "occluded_by_walls"} | _SENSOR_NOISE_KEYS | _RANGE_FINDER_KEYS,
    "driver": {"kind", "v", "omega", "radius", "speed", "gain", "max_omega", "tolerance",
               "margin", "points", "loop"},
    "keyboard": {"v_step", "v_max", "v_min", "omega_step", "omega_max"},
    "events[]": {"kind", "time", "duration", "pose", "offset", "random", "sensors", "v_std",
                 "omega_std"},
    "initial_belief": {"mean", "std", "global"},
    "model": {"motion_noise", "sensors", "map"},
    "model.motion_noise": _NOISE_KEYS,
}


def keys_at(path: str) -> set[str] | None:
    """The keys a table at ``path`` (``sensors[]``) may have: a sensor's include the keys
    every registered kind declares (core/sensor_kinds.py)."""
    known = _KNOWN.get(path)
    if path == "sensors[]" and known is not None:
        return known | set(param_keys())
    return known


def generic_path(path: str) -> str:
    return re.sub(r"\[\d+\]", "[]", path)


__all__ = ["RANGE_MODEL_KEYS", "generic_path", "keys_at"]
