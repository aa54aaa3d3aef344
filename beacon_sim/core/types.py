"""Value types shared by the core, the filters and the front end.

Poses are plain ``ndarray`` of shape (3,): ``[x, y, theta]`` in metres, metres, radians
(world frame, theta counter-clockwise from +x, wrapped to [-pi, pi)).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Measurement kinds and the width of one row of ``Measurement.z``.
#: ``range_finder`` is a laser scan: one row ``[range, beam angle]`` per beam.
MEASUREMENT_DIMS = {"bearing": 1, "range_bearing": 2, "pose": 3, "position": 2, "range_finder": 2}


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` whose base is read-only too, so that the flag cannot be set
    back (``view.flags.writeable = True`` raises). Costs one view, no copy, unless ``a`` is
    a view of someone else's writable array (then it is copied first)."""
    if isinstance(a, np.ndarray) and not a.flags.writeable and a.base is not None \
            and not getattr(a.base, "flags", a.flags).writeable:
        return a
    base = np.array(a) if not isinstance(a, np.ndarray) or a.base is not None else a
    base.flags.writeable = False
    return base.view()


@dataclass(frozen=True)
class Control:
    """A velocity command: forward speed ``v`` [m/s] and turn rate ``omega`` [rad/s].

    Positive ``omega`` turns left (counter-clockwise).
    """

    v: float = 0.0
    omega: float = 0.0

    def as_array(self) -> np.ndarray:
        """``[v, omega]`` as a float array of shape (2,)."""
        return np.array([self.v, self.omega], dtype=float)


@dataclass(frozen=True)
class Beacon:
    """A point landmark with a known ID at ``(x, y)`` [m] in the world frame."""

    id: int
    x: float
    y: float


@dataclass(frozen=True, eq=False)
class Measurement:
    """What one sensor reported on one tick.

    Attributes
    ----------
    sensor : str
        The sensor's name in the scenario (e.g. ``"beacons"``).
    kind : str
        ``"bearing"``, ``"range_bearing"``, ``"pose"`` or ``"position"``.
    z : ndarray, shape (m, d)
        One row per reading. bearing: ``[bearing]`` [rad] relative to the robot's heading;
        range_bearing: ``[range, bearing]`` [m, rad]; pose: ``[x, y, theta]`` [m, m, rad]
        (m = 1); position: ``[x, y]`` [m] (m = 1); range_finder: ``[range, beam angle]``
        [m, rad] per beam, the angle relative to the heading (m = number of beams; a range
        equal to the sensor's max_range is "no return").
    beacon_ids : ndarray of int, shape (m,) for bearing/range_bearing
        The ID of the beacon each row belongs to (known correspondence). For pose and
        position fixes: the IDs of the beacons the fix was computed from. For a
        range_finder: empty (a scan names no beacon).
    hdop : float
        Horizontal dilution of precision of a position fix (nan for other kinds).
    """

    sensor: str
    kind: str
    z: np.ndarray
    beacon_ids: np.ndarray
    hdop: float = float("nan")

    def __post_init__(self) -> None:
        # Read-only: every filter sees the same readings, so none may change them (a write
        # raises, and the runner switches that filter off).
        object.__setattr__(self, "z", read_only(self.z))
        object.__setattr__(self, "beacon_ids", read_only(self.beacon_ids))

    def __len__(self) -> int:
        return int(self.z.shape[0])


@dataclass(frozen=True)
class EventRecord:
    """An event that fired on a tick (kidnap, blackout start/end, noise burst, ...).

    ``pose_before`` / ``pose_after`` are set for kidnaps (shape (3,), world frame).
    """

    kind: str
    tick: int
    time: float
    detail: str = ""
    pose_before: np.ndarray | None = None
    pose_after: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Step:
    """Everything one simulation tick produced.

    Attributes
    ----------
    tick : int
        Tick index, starting at 1 for the first step (tick 0 is the initial state).
    time : float
        Simulated time at the end of the step [s] (``tick * dt``).
    dt : float
        Length of the step [s].
    true_pose : ndarray, shape (3,)
        True pose after the step. Filters must never read it.
    control : Control
        The command given for this step; filters predict with it (the truth ran a noisy
        version of it). When the bumper stopped the robot at a wall, ``v`` is 0 (what the
        robot did) and the events hold a ``bump``.
    measurements : tuple of Measurement
        Readings of this tick, at the true pose after the step.
    events : tuple of EventRecord
        Events that fired on this tick.
    true_ids : dict of str to ndarray of int
        Per sensor with unknown correspondence, the beacon each row of its reading really
        came from (-1: clutter). Like ``true_pose``, filters must never read it.
    """

    tick: int
    time: float
    dt: float
    true_pose: np.ndarray
    control: Control
    measurements: tuple[Measurement, ...] = ()
    events: tuple[EventRecord, ...] = field(default_factory=tuple)
    true_ids: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def kidnapped(self) -> bool:
        """True when the robot was teleported on this tick."""
        return any(e.kind == "kidnap" for e in self.events)
