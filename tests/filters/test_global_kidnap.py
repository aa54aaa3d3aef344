"""The harder global-localization scenario: ``global_kidnap`` (3.5 m range,
detection probability 0.5). The particle and grid filters recover from a random kidnap
within 15 s in at least 90 % of 20 seeded trials, with the scenario's own filter settings.

Each trial is short: tracking from a known start, one random kidnap at 5 s, then 20 s (the
15 s allowed plus the 5 s hold of the recovery definition, ``evaluation.metrics``).
"""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.events import Kidnap
from beacon_sim.core.scenario import InitialBelief, load_scenario
from beacon_sim.evaluation.metrics import recovery_times
from beacon_sim.evaluation.summary import Thresholds
from beacon_sim.runs.headless import run_headless

KIDNAP_S = 5.0     # [s] when the robot is carried off
ALLOWED_S = 15.0   # [s] the issue's recovery target
TRIALS = 20


def recovery_after_a_random_kidnap(filter_name: str, seed: int, params=None) -> float:
    """Recovery time [s] (inf if none) of ``filter_name`` on ``global_kidnap`` with one
    random kidnap at ``KIDNAP_S``, starting localised (std 0.1 m, 0.1 m, 0.05 rad)."""
    base = load_scenario("global_kidnap")
    sc = base.with_changes(
        events=(Kidnap(time=KIDNAP_S, random=True),),
        initial_belief=InitialBelief(mean=base.initial_pose, std=(0.1, 0.1, 0.05)))
    th = Thresholds()
    r = run_headless(sc, [filter_name], seed=seed,
                     duration=KIDNAP_S + ALLOWED_S + th.recovery_hold_s,
                     params={filter_name: params} if params else None)
    tr = r.runner.tracks[filter_name]
    assert tr.failed is None, tr.failed
    err = np.hypot(*(np.array(tr.means)[:, :2] - r.truth[:, :2]).T)
    kidnaps = [i for i, s in enumerate(r.steps) if s.kidnapped]
    assert len(kidnaps) == 1
    times = np.array([s.time for s in r.steps])
    return recovery_times(err, times, kidnaps, th.recovery_m, th.recovery_hold_s)[0]


def test_the_scenario_is_the_issues_harder_one():
    sc = load_scenario("global_kidnap")
    (sensor,) = sc.sensors
    assert sensor.kind == "range_bearing"
    assert sensor.max_range == 3.5 and sensor.detection_prob == 0.5
    assert sc.initial_belief.global_
    assert [e.random for e in sc.events] == [True, True]


@pytest.mark.parametrize("filter_name", ["pf", "histogram"])
def test_recovers_from_a_random_kidnap_within_15_s_in_90_percent_of_20_trials(filter_name):
    times = [recovery_after_a_random_kidnap(filter_name, 1000 + i) for i in range(TRIALS)]
    recovered = sum(t <= ALLOWED_S for t in times)
    # Measured: pf 20 / 20, histogram 20 / 20 (pf with the library defaults, 2,000 fixed
    # particles and no roughening: 16 / 20 here, 56 / 60 on seeds 2000-2059; without
    # augmented MCL 1 / 20).
    assert recovered >= 0.9 * TRIALS, (recovered, [round(t, 1) for t in times])
