"""Filters shown together have distinct colours (a repeated kind, ``ekf'``, keeps its colour
with another line style): slam_bearing_only's two filters, the comparison it exists for,
shared sky blue; so did mcl and ekf_slam, fastslam and corridor."""

from __future__ import annotations

import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting.loading import filter_names
from beacon_sim.runs.styles import KIND_STYLES, filter_styles


@pytest.mark.parametrize("names", [
    filter_names(list(load_scenario("slam_bearing_only").default_filters)),
    ["mcl", "ekf_slam", "pf"], ["fastslam", "corridor"], ["ekf", "Mine", "mcl", "Yours"],
])
def test_different_kinds_shown_together_have_different_colours(names):
    styles = filter_styles(names)
    assert len(names) >= 2
    assert len({c for c, _ in styles.values()}) == len(names), styles


def test_the_usual_kinds_keep_their_own_colours():
    names = ["kf", "ekf", "ukf", "pf", "histogram", "dead_reckoning", "ekf'"]
    styles = filter_styles(names)
    for n in names[:-1]:
        assert styles[n] == KIND_STYLES[n]
    assert styles["ekf'"][0] == styles["ekf"][0] and styles["ekf'"][1] != styles["ekf"][1]
