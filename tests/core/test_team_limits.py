"""A team scenario has the single-robot limits: a robot whose filters build the map (an
unknown map) may have at most MAX_SLAM_BEACONS beacons in the world, checked at load with
the number in the one-line message, through every front end that loads a team."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario import MAX_SLAM_BEACONS, ScenarioError, load_team_scenario


def _team(tmp_path: Path, n_beacons: int, unknown_robot: int | None) -> Path:
    text = (scenario_dir() / "team" / "team_sparse.toml").read_text()
    beacons = ",\n".join(f"  {{ id = {k + 10}, x = {0.5 + (k % 100) * 0.13:.2f}, "
                         f"y = {0.5 + (k // 100) * 0.5:.2f} }}" for k in range(n_beacons))
    text = re.sub(r"beacons = \[.*?\]\n", "beacons = [\n" + beacons + "\n]\n", text, flags=re.S)
    if unknown_robot is not None:   # that robot's filters are not given the map
        parts = text.split("[[robots]]")
        parts[unknown_robot + 1] = parts[unknown_robot + 1].replace(
            "initial_belief = ", 'model = { map = "unknown" }\ninitial_belief = ', 1)
        text = "[[robots]]".join(parts)
    path = tmp_path / "team.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("robot", [0, 2])
def test_an_unknown_map_of_too_many_beacons_is_refused_at_load(tmp_path, capsys, robot):
    path = _team(tmp_path, MAX_SLAM_BEACONS + 1, robot)
    with pytest.raises(ScenarioError, match=rf"robots\[{robot}\]\.model\.map.*at most {MAX_SLAM_BEACONS}"):
        load_team_scenario(path)
    for argv in (["run", str(path), "--duration", "0.1"], ["eval", str(path), "--runs", "1"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"has {MAX_SLAM_BEACONS + 1:,}" in err[0]


def test_the_cap_itself_loads_and_a_known_map_has_no_cap(tmp_path):
    assert len(load_team_scenario(_team(tmp_path, MAX_SLAM_BEACONS, 1)).world.beacons) == MAX_SLAM_BEACONS
    assert len(load_team_scenario(_team(tmp_path, MAX_SLAM_BEACONS + 1, None)).world.beacons) \
        == MAX_SLAM_BEACONS + 1
