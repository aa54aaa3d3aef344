"""Small builders shared by the tests: scenarios written inline, without files."""

from __future__ import annotations

from beacon_sim.core.scenario import Scenario, parse_scenario


def make_scenario(extra: dict | None = None, **top) -> Scenario:
    """A 10 m x 10 m world with four beacons and one range-bearing sensor, overridable."""
    data = {
        "name": "test",
        "dt": 0.1,
        "world": {
            "bounds": [0.0, 0.0, 10.0, 10.0],
            "beacons": [{"id": 1, "x": 2.0, "y": 2.0}, {"id": 2, "x": 8.0, "y": 2.0},
                        {"id": 3, "x": 8.0, "y": 8.0}, {"id": 4, "x": 2.0, "y": 8.0}],
        },
        "robot": {"initial_pose": [5.0, 5.0, 0.0],
                  "motion_noise": {"v_std": 0.02, "omega_std": 0.02}},
        "sensors": [{"name": "rb", "kind": "range_bearing", "max_range": 20.0,
                     "range_std": 0.1, "bearing_std": 0.05}],
        "driver": {"kind": "constant", "v": 0.2, "omega": 0.1},
    }
    data.update(top)
    for key, value in (extra or {}).items():
        data[key] = value
    return parse_scenario(data, "<test>")
