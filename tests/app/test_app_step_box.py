"""The step view's box (paused, V; with B the bound's line) never covers the robot: at
1920x1080 it does not fit under most rooms and sat on a robot at the room's bottom left."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from beacon_sim.app.window import App  # noqa: E402
from beacon_sim.core.scenario import load_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
@pytest.mark.parametrize("corner", ["bottom_left", "top_left"])
def test_the_step_box_does_not_cover_the_robot(size, corner):
    sc = load_scenario("ulps_circle")  # its room fills the world's area: the box is over it
    x0, y0, _, y1 = sc.world.bounds
    y = y0 + 0.3 if corner == "bottom_left" else y1 - 0.3
    app = App(Session(sc, ["dead_reckoning"]), size, scripted=True)
    try:
        app.session.command({"kind": "kidnap", "pose": [x0 + 0.3, y, 0.0]})
        app.run(3)
        app.act("pause")
        app.act("bound")
        app.act("step")
        app.run(app.frames + 2)
        app.draw()
        box = app.hud.step_box
        assert not box.colliderect(app.robot_box()), (box, app.robot_box())
        assert pygame.Rect(app.view.area).contains(box)
    finally:
        app.close()
