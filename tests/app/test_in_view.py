"""The beacons in view are worked out once per true pose (a ray cast per beacon in a world
with walls), and a new pose, world or sensor list gets its own answer."""

from __future__ import annotations

import numpy as np

from beacon_sim.app import in_view
from beacon_sim.core.scenario import load_scenario


def test_the_beacons_in_view_are_cast_once_per_pose_and_follow_the_pose(monkeypatch):
    sc = load_scenario("two_rooms")
    calls = []
    real = in_view.visible_beacons
    monkeypatch.setattr(in_view, "visible_beacons", lambda *a: calls.append(1) or real(*a))
    ids = {b.id for b in sc.world.beacons}
    here = np.array([2.0, 2.0, 0.0])
    there = np.array([sc.world.width - 2.0, sc.world.height - 2.0, np.pi])
    a = in_view.missed_ids(sc.sensors, sc.world, here, set())
    n = len(calls)
    assert in_view.missed_ids(sc.sensors, sc.world, here.copy(), set()) == a and len(calls) == n
    b = in_view.missed_ids(sc.sensors, sc.world, there, set())
    assert len(calls) > n and a != b  # the other room: other beacons in view
    for pose, want in ((here, a), (there, b)):
        mask = np.zeros(len(ids), bool)
        for spec in sc.sensors:
            mask |= real(spec, pose, sc.world)
        assert want == {bb.id for bb, m in zip(sc.world.beacons, mask, strict=True) if m}
    assert in_view.missed_ids(sc.sensors, sc.world, here, {min(a)}) == a - {min(a)}
