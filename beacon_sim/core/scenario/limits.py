"""The ranges a scenario's numbers must lie in (docs/scenarios.md, "Ranges"), so that nothing
overflows, hangs or fills the memory;
a few of the caps can be raised by environment variables (``BEACON_SIM_MAX_*``,
:func:`~beacon_sim.core.scenario.toml_files.env_limit`)."""

from __future__ import annotations

from typing import Final

# Physical ranges (docs/scenarios.md, "Ranges"): every number in a scenario is finite and
# within these, so that nothing overflows, hangs or fills the memory.
#: Largest coordinate, length or angle in a vector [m or rad].
MAX_COORD: Final = 1e6
#: Smallest and largest tick [s].
MIN_DT: Final = 1e-3
MAX_DT: Final = 10.0
#: Most ticks in a run (duration / dt), and latest event time in ticks.
MAX_TICKS: Final = 1_000_000
#: Largest speed [m/s], turn rate [rad/s] and their noise.
MAX_SPEED: Final = 100.0
MAX_TURN: Final = 100.0
#: Largest sensor noise standard deviation [m or rad] and fraction of the command.
MAX_STD: Final = 1e3
MAX_FRAC: Final = 10.0
#: Most beacons, sensors and events in a scenario, and most ticks covered by all the
#: blackouts and noise bursts together (their per-tick tables must fit in memory).
MAX_BEACONS: Final = 10_000
#: Most beacons with ``model.map = "unknown"`` (SLAM: the filters' state grows with the map).
MAX_SLAM_BEACONS: Final = 500
MAX_SENSORS: Final = 100
MAX_EVENTS: Final = 10_000
MAX_EVENT_TICKS: Final = 2_000_000
#: Smallest sensor noise standard deviation [m or rad]: a filter divides by its square
#: (zero, or a subnormal, would divide by zero or overflow in the bound and the filters).
MIN_SENSOR_STD: Final = 1e-6
#: Shortest side of the world [m] (the window draws a grid of it, the drivers pick goals in it).
MIN_WORLD_SIDE: Final = 0.1

# Caps on the input itself, checked before parsing (docs/scenarios.md, "Caps"); each can be
# raised with the environment variable ``BEACON_SIM_MAX_<NAME>`` (a whole number).
#: Largest scenario file [bytes] (10,000 beacons and 10,000 events take under 1 MiB; a
#: file of this size parses in about a second).
MAX_SCENARIO_BYTES: Final = 2 * 2**20
#: Deepest nesting of arrays and tables in a scenario or a recording line (the shipped
#: files nest at most 5 deep).
MAX_NESTING: Final = 32
#: Most decimal digits of an integer in a scenario or a recording (2^63 has 19).
MAX_INT_DIGITS: Final = 20



#: Most beams in one scan.
MAX_BEAMS: Final = 4096
#: Most points in all the walls of a scenario together.
MAX_WALL_POINTS: Final = 100_000


#: Most false detections per reading a sensor may declare (clutter).
MAX_CLUTTER_RATE: Final = 5.0


__all__ = ["MAX_BEACONS", "MAX_BEAMS", "MAX_CLUTTER_RATE", "MAX_COORD", "MAX_DT", "MAX_EVENTS",
           "MAX_EVENT_TICKS", "MAX_FRAC", "MAX_INT_DIGITS", "MAX_NESTING", "MAX_SCENARIO_BYTES",
           "MAX_SENSORS", "MAX_SLAM_BEACONS", "MAX_SPEED", "MAX_STD", "MAX_TICKS", "MAX_TURN",
           "MAX_WALL_POINTS", "MIN_DT", "MIN_SENSOR_STD", "MIN_WORLD_SIDE"]
