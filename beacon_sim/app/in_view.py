"""What the robot senses now, as the window tells it (the beacons drawn seen or missed, the
panel's lines): the sensors read so far, the beacons in range but missed, the IDs in view,
the scan's hits, the readings of kinds registered beside the built-in ones.
"""

from __future__ import annotations

import numpy as np

from beacon_sim.app import association_layer
from beacon_sim.core import sensor_kinds
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.schedule import period_ticks
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.sensors import visible_beacons


def sensors_read(scenario, tick: int) -> list:
    """The scenario's sensors that have been read by ``tick`` (one period has passed): before
    its first reading a sensor has missed nothing."""
    return [s for s in scenario.sensors if tick >= period_ticks(s.period, scenario.dt)]


def missed_ids(sensors, world, pose, seen) -> set[int]:
    """IDs of the beacons within some beacon sensor's range and field of view at the true
    ``pose`` that are not in ``seen`` (missed by detection probability, or blacked out).
    The beacons in view are worked out once per pose (a ray cast per beacon in a world with
    walls, about 0.5 ms), not once per frame and caller."""
    ids = np.array([b.id for b in world.beacons], dtype=np.int64)
    if not len(ids):
        return set()
    return {int(i) for i in ids[_in_view(list(sensors), world, np.asarray(pose, dtype=float))]} - set(seen)


#: The last answer of :func:`_in_view`: its sensors, world and pose (kept, compared by
#: identity and bits) and the mask.
_last: list = [None, None, None, None]


def _in_view(sensors: list, world, pose: np.ndarray) -> np.ndarray:
    """Which of ``world``'s beacons some of ``sensors`` can detect at ``pose`` (bool mask)."""
    s, w, p, mask = _last
    if w is world and p is not None and p.tobytes() == pose.tobytes() and s is not None \
            and len(s) == len(sensors) and all(a is b for a, b in zip(s, sensors, strict=True)):
        return mask
    mask = np.zeros(len(world.beacons), dtype=bool)
    for spec in sensors:  # every kind of sensor detects beacons one by one
        mask |= visible_beacons(spec, pose, world)
    _last[:] = [sensors, world, pose.copy(), mask]
    return mask


def beacons_in_view(session) -> tuple[list[int], int, set[int]]:
    """What the panel says is in view: the beacon IDs the readings carry (sorted), how many
    readings carry none (unknown correspondence, clutter included), and the beacons really
    seen (those IDs and, for readings without IDs, the beacons they came from: the
    simulator's truth, ``association_layer.seen_by_truth``), so none of them is "missed"."""
    labelled: set[int] = set()
    unlabelled = 0
    for m in session.readings():
        if m.kind.startswith("robot_"):
            continue
        ids = np.asarray(m.beacon_ids, dtype=np.int64)
        labelled |= {int(i) for i in ids[ids != UNKNOWN_ID]}
        unlabelled += int(np.count_nonzero(ids == UNKNOWN_ID))
    return sorted(labelled), unlabelled, labelled | association_layer.seen_by_truth(session)


def kind_lines(session) -> list[str]:
    """The panel's line for each sensor of a kind registered beside the built-in ones
    (core/sensor_kinds.py): ``<kind label> (<sensor>): <rows> readings`` of this tick."""
    rows: dict[str, int] = {}
    for m in session.readings():
        rows[m.sensor] = rows.get(m.sensor, 0) + len(m)
    out = []
    for s in session.scenario.sensors:
        kind = sensor_kinds.KINDS.get(s.kind)
        if kind is not None and s.kind not in sensor_kinds.BUILTIN:
            n = rows.get(s.name, 0)
            out.append(f"{kind.label or kind.name} ({s.name}): {n} reading{'s' if n != 1 else ''}")
    return out


def scan_in_view(session) -> tuple[int, int]:
    """What the panel says the range finder senses: the beams of this tick's scans and how
    many of them hit something (read less than the sensor's max range)."""
    spec = {s.name: s for s in session.scenario.sensors}
    beams = hits = 0
    for m in session.readings():
        if not is_scan(m.kind):
            continue
        r = np.asarray(m.z, dtype=float)[:, 0]
        beams += len(r)
        s = spec.get(m.sensor)
        hits += int(np.count_nonzero(r < s.max_range)) if s is not None else len(r)
    return beams, hits


def ids_text(labelled: list[int], unlabelled: int) -> str:
    """The panel's line under "beacons in view": ``  IDs 1, 4``, ``  no IDs (3 readings)``,
    both when sensors of both kinds read, or ``  IDs none``."""
    parts = []
    if labelled:
        parts.append("IDs " + ", ".join(map(str, labelled)))
    if unlabelled:
        parts.append(f"no IDs ({unlabelled} reading{'s' if unlabelled != 1 else ''})")
    return "  " + ("; ".join(parts) if parts else "IDs none")
