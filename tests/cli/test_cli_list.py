"""``beacon-sim list``: every scenario described in words a student
understands, in full (wrapped to the terminal, never cut), without the design notes'
"Seed 00x:" labels."""

from __future__ import annotations

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario


@pytest.mark.parametrize("columns", ["100", "48"])
def test_list_describes_every_scenario_in_full(capsys, monkeypatch, columns):
    monkeypatch.setenv("COLUMNS", columns)
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "Seed 00" not in out
    assert max(len(line) for line in out.splitlines()) <= max(int(columns), 36)
    flat = " ".join(out.split())
    for name in shipped_scenarios():
        sc = load_scenario(name)
        text = " ".join(sc.description.split())
        assert len(text) > 120, f"{name}: describe it in sentences, not a label"
        assert not text.lower().startswith("seed"), name
        assert text in flat, f"{name}: description cut or missing"
        assert f"{sc.duration:g} s" in flat
    assert out.split("filters:")[1].split()[0] == "kf"


def test_list_names_the_team_scenarios_and_team_filters(capsys):
    from beacon_sim.cli.main import main

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    team = out[out.index("team scenarios"):]
    assert "  team_sparse\n" in team and "robots scout, relay, explorer" in team
    filters = out[out.index("team filters"):]
    for name in ("independent", "centralised", "decentralised", "ci"):
        assert f"  {name}\n" in filters
