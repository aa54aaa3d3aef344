"""A second laser-scan kind needs its record only: the scenario's scan keys, the corridor
filter, the Gaussian filters' slots (none), the observation layout, the MCAP scan channel
and the Cramer-Rao information all ask the record (``SensorKind.scan``), never the name
``range_finder``."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from beacon_sim import api
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.sensor_kinds import KINDS, is_scan, scan_sensors
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.pcrb import measurement_information
from beacon_sim.filters.gaussian.measurements import SlotPacker

TOY = "toy_laser"
CORRIDOR = Path(__file__).resolve().parents[2] / "scenarios" / "corridor.toml"


@pytest.fixture
def toy(monkeypatch):
    """A copy of the range finder's record under another name, registered for this test."""
    record = replace(KINDS["range_finder"], name=TOY, label="toy laser")
    monkeypatch.setitem(KINDS, TOY, record)
    return record


def corridor_as(tmp_path, kind: str, max_range: str = "4.0"):
    text = CORRIDOR.read_text(encoding="utf-8")
    assert text.count('kind = "range_finder"') == 1 and text.count("max_range = 4.0") == 1
    text = text.replace('kind = "range_finder"', f'kind = "{kind}"').replace("max_range = 4.0",
                                                                              f"max_range = {max_range}")
    path = tmp_path / f"{kind}.toml"
    path.write_text(text, encoding="utf-8")
    return load_scenario(path)


def test_the_scan_flag_is_the_records(toy):
    assert is_scan("range_finder") and is_scan(TOY)
    assert not any(is_scan(k) for k in KINDS if k not in ("range_finder", TOY))
    assert not is_scan("robot_bearing")      # not registered: not a scan


def test_a_toy_scan_reads_the_scan_keys_and_wants_a_finite_range(toy, tmp_path):
    sc = corridor_as(tmp_path, TOY)
    spec = sc.sensors[0]
    assert spec.kind == TOY and spec.n_beams == 120 and spec.range_model is not None
    assert spec.range_model.sigma_hit == 0.03
    assert scan_sensors(sc.sensors) == ("laser",)
    with pytest.raises(ScenarioError, match=r"sensors\[0\]\.max_range.*toy_laser"):
        corridor_as(tmp_path, TOY, max_range="inf")


def test_a_toy_scan_is_simulated_and_filtered_as_the_range_finder(toy, tmp_path):
    ref, sc = corridor_as(tmp_path, "range_finder"), corridor_as(tmp_path, TOY)
    sims = Simulation(ref), Simulation(sc)
    for _ in range(50):
        a, b = (s.step() for s in sims)
        assert [m.kind for m in b.measurements] == [TOY] * len(a.measurements)
        for ma, mb in zip(a.measurements, b.measurements, strict=True):
            np.testing.assert_array_equal(ma.z, mb.z)
    # the corridor filter reads the toy scans: the same estimates as from the range finder
    runs = [api.run(s, ["corridor", "dead_reckoning"], seed=5, duration=20.0) for s in (ref, sc)]
    for name in ("corridor", "dead_reckoning"):
        np.testing.assert_array_equal(runs[0].estimates[name], runs[1].estimates[name])
    lost = runs[1].errors("corridor")[-1]
    assert np.all(np.isfinite(lost))
    # the Gaussian filters have no slots for a scan of either kind
    assert SlotPacker(sc.world, sc.sensors).M == 0 == SlotPacker(ref.world, ref.sensors).M


def test_a_toy_scan_has_the_scans_information(toy, tmp_path):
    ref, sc = corridor_as(tmp_path, "range_finder"), corridor_as(tmp_path, TOY)
    poses = np.array([[1.5, 0.5, 0.0], [5.0, 0.4, 1.0]])
    J_ref = measurement_information(ref.sensors[0], poses, ref.world.beacon_xy, ref.world)
    J = measurement_information(sc.sensors[0], poses, sc.world.beacon_xy, sc.world)
    np.testing.assert_array_equal(J, J_ref)
    assert np.all(np.linalg.eigvalsh(J)[:, -1] > 0)   # the walls say something
