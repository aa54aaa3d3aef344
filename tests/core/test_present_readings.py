"""The batched readings cost what the readings present cost: with R runs' slots
(``SlotPacker``), ``StackedReadings.linearise`` and ``predict`` can compute only the slots
that hold a reading (they do when few do, ``PRESENT_FRACTION``), and that gives, bit for
bit, the whole-map computation with the empty slots at 0 (H = 0, innovation 0, prediction
0)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.resources import scenario_dir, shipped_scenarios
from beacon_sim.core.scenario import load_scenario, parse_scenario
from beacon_sim.filters.gaussian.measurements import FIX_KINDS, SlotPacker
from beacon_sim.filters.gaussian.measurements import KINDS as SLOT_KINDS


def _mixed_map():
    """A 40-beacon map with few in view, range-bearing, a bearing compass with outliers and a
    position fix, all in one scenario."""
    data = tomllib.loads((scenario_dir() / "default.toml").read_text())
    rng = np.random.default_rng(4)
    data["world"]["beacons"] = [{"id": 3 * i + 2, "x": float(x), "y": float(y)} for i, (x, y) in
                                enumerate(zip(rng.uniform(0.5, 11.5, 40), rng.uniform(0.5, 7.5, 40),
                                              strict=True))]
    data["sensors"].append({"name": "compass", "kind": "bearing", "period": 0.1, "bearing_std": 0.05,
                            "max_range": 4.0, "outlier_rate": 0.2, "detection_prob": 0.7})
    data["sensors"].append({"name": "gps", "kind": "position", "period": 0.5, "position_std": 0.3})
    return parse_scenario(data, "test", name="mixed")


#: The shipped scenarios with beacon readings (a range finder's scans have no Gaussian slots).
WITH_BEACON_READINGS = [n for n in shipped_scenarios()
                        if any(s.kind != "range_finder" for s in load_scenario(n).sensors)
                        and all(s.kind in SLOT_KINDS for s in load_scenario(n).sensors)]


@pytest.mark.parametrize("name", [*WITH_BEACON_READINGS, "mixed"])
def test_present_readings_are_the_whole_map_computation_bit_for_bit(name):
    sc = _mixed_map() if name == "mixed" else load_scenario(name)
    R = 5
    bs = BatchSimulation(sc, list(range(R)), readings_checksums=False)
    packer = SlotPacker(sc.world, sc.model_sensors)
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(round(min(sc.duration, 20.0) / sc.dt)):
        tick = bs.advance()
        st = packer.pack_tick(tick)
        if st is None:
            continue
        mean = tick.pose + rng.normal(0.0, [0.3, 0.3, 0.2], (R, 3))
        mean[0, 2] = np.pi - 1e-12                     # near the wrap
        for s in (st, st.only(FIX_KINDS)):
            if s is None:
                continue
            H0, nu0, r0 = s._linearise_all(mean)
            for H, nu, r in (s.linearise(mean), s._linearise_present(mean)):
                assert H.tobytes() == H0.tobytes() and nu.tobytes() == nu0.tobytes() and r is r0
            poses = (mean[:, None, :] + rng.normal(0.0, 0.2, (R, 7, 3))).reshape(-1, 3)
            rows = np.repeat(s.valid, 7, axis=0)
            for wrap in (False, True):
                want = np.where(rows, s._predict_all(poses, wrap=wrap), 0.0)
                for got in (s.predict(poses, wrap=wrap), s._predict_present(poses, wrap)):
                    assert got.tobytes() == want.tobytes()
            checked += 1
    assert checked > 10
