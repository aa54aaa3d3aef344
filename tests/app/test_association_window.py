"""The window's association layer: which lines it draws, and that a wrong pairing
shows as dark red pixels (drawn in a dummy-video window, never shown)."""

import numpy as np
import pygame

from beacon_sim.app import association_layer as layer
from beacon_sim.app.assets import load_fonts
from beacon_sim.app.palette import filter_colours
from beacon_sim.app.render import ShowOptions, View, WorldRenderer
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def test_lines_go_from_the_estimate_to_the_beacon_given_and_wrong_ones_are_marked():
    world = load_scenario("lookalike_beacons").world
    mean = np.array([6.0, 3.0, 0.0])
    given = {"doors": (4, None, 5, 20)}
    truth = {"doors": np.array([3, -1, 5, -1])}  # 4 for 3: wrong; clutter left out: right
    lines = layer.association_lines(mean, given, truth, world)
    assert [(tuple(b), w) for _, b, w in lines] == [((7.0, 1.0), True), ((9.0, 1.0), False),
                                                     ((15.0, 5.0), True)]
    assert all(np.array_equal(a, mean[:2]) for a, _, _ in lines)
    # without the truth (or rows that do not match it) nothing is called wrong
    assert not any(w for _, _, w in layer.association_lines(mean, given, {}, world))
    assert not any(w for _, _, w in layer.association_lines(mean, given, {"doors": np.array([1])}, world))


def dark_red_pixels(session: Session) -> int:
    pygame.font.init()
    renderer = WorldRenderer(load_fonts(600, 1200))
    surf = pygame.Surface((1200, 600))
    view = View(session.scenario.world.bounds, (0, 0, 1200, 600))
    renderer.draw(surf, view, session, filter_colours(session.names), ShowOptions(particles=False))
    px = pygame.surfarray.array3d(surf).reshape(-1, 3)
    return int(np.sum(np.all(px == np.array(layer.WRONG), axis=1)))


def test_the_ekf_one_door_off_draws_wrong_lines_the_pf_at_the_end_does_not():
    ekf = Session(load_scenario("lookalike_beacons"), ["ekf"])
    ekf.toggle_autopilot()
    for _ in range(60):  # 6 s: the EKF has locked one door off
        ekf.tick()
    assert dark_red_pixels(ekf) > 200
    pf = Session(load_scenario("lookalike_beacons"), ["pf"], params={"pf": {"n_particles": 10000}})
    pf.toggle_autopilot()
    for _ in range(300):  # 30 s: the odd beacon has told the places apart
        pf.tick()
    assert dark_red_pixels(pf) == 0
    # the beacons the latest reading really came from are drawn as seen (its IDs are all -1)
    seen = layer.seen_by_truth(pf)
    assert seen and seen <= set(pf.scenario.world.beacon_ids.tolist()) and pf.seen_ids() <= {-1}
