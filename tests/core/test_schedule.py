"""One tick schedule (core/schedule.py): the simulation, the batched simulation,
the team simulation (per robot), the offline PCRB and the live bound read the same object, so the
readings the simulation makes are exactly the ones the bound counts."""

from __future__ import annotations

import numpy as np
from helpers import make_scenario

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.schedule import period_ticks, tick_schedule
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.evaluation.pcrb import pcrb

SENSORS = [{"name": "fast", "kind": "range_bearing", "max_range": 20.0, "range_std": 0.1,
            "bearing_std": 0.05},
           {"name": "slow", "kind": "bearing", "period": 0.3, "max_range": 20.0, "bearing_std": 0.05}]
EVENTS = [{"kind": "blackout", "time": 1.0, "duration": 0.5, "sensors": ["slow"]},
          {"kind": "blackout", "time": 2.0, "duration": 0.3},
          {"kind": "noise_burst", "time": 0.5, "duration": 0.4, "v_std": 0.3}]


def test_periods_in_ticks():
    assert period_ticks(0.3, 0.1) == 3   # 2.9999999999999996 rounds to 3
    assert period_ticks(0.1, 0.1) == 1 and period_ticks(0.02, 0.1) == 1   # at least every tick
    assert period_ticks(1.0, 0.05) == 20


def test_the_schedule_is_what_the_simulation_does():
    sc = make_scenario(sensors=SENSORS, events=EVENTS)
    sched = tick_schedule(sc)
    assert dict(sched.every) == {"fast": 1, "slow": 3}
    assert sorted(sched.blackouts) == [*range(10, 15), 20, 21, 22]
    assert sorted(sched.bursts) == list(range(5, 9))
    steps = Simulation(sc, seed=4).run(3.0)
    for s in steps:   # every sensor sees a beacon on every tick it reads: the set is the schedule's
        got = {m.sensor for m in s.measurements}
        assert got == {n for n in ("fast", "slow") if sched.reads(n, s.tick)}, s.tick
    assert sum(not sched.reads("slow", k) and sched.due("slow", k) for k in range(1, 31)) == 2   # 12, 21
    batch = BatchSimulation(sc, [4, 5])
    assert batch.schedule == sched


def test_the_bounds_count_the_scheduled_readings_only():
    """The live bound equals the offline PCRB tick by tick on a scenario with blackouts and
    a burst (both build their steps from the same schedule)."""
    sc = make_scenario(sensors=SENSORS, events=EVENTS)
    steps = Simulation(sc, seed=4).run(3.0)
    truths = np.array([sc.initial_pose] + [s.true_pose for s in steps])[None]
    controls = np.array([[s.control.v, s.control.omega] for s in steps])[None]
    offline = pcrb(sc, truths, controls)[0]
    live = LiveBound(sc)
    for k, s in enumerate(steps):
        live.feed(s)
        np.testing.assert_allclose(live.P, offline[k], rtol=1e-12, atol=1e-15)
    # a blacked-out tick adds no information: the bound grows through the full blackout
    # (ticks 20-22), and drops on tick 23 when the readings are back
    growth = np.diff([np.trace(offline[k - 1][:2, :2]) for k in (19, 20, 21, 22, 23)])
    assert np.all(growth[:3] > 0) and growth[3] < 0

