"""The window in map worlds: the likelihood field on L, and a panel that says what
the range finder senses instead of warning about beacons a walls-only world does not have."""

from __future__ import annotations

import numpy as np
import pygame
import pytest

from beacon_sim.app import controls, map_view, palette
from beacon_sim.app.in_view import scan_in_view
from beacon_sim.app.window import App
from beacon_sim.core.beam_model import distance_transform
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def make_app(name: str, filters=("dead_reckoning",), size=(1000, 700)) -> App:
    return App(Session(load_scenario(name), list(filters), 3), size, scripted=True)


def press(k) -> None:
    for t in (pygame.KEYDOWN, pygame.KEYUP):
        pygame.event.post(pygame.event.Event(t, key=k, mod=0, unicode="", scancode=0))


def test_l_is_the_field_key_in_the_play_and_replay_tables():
    for mode in ("play", "replay"):
        b = controls.binding_for_key(pygame.K_l, mode)
        assert b is not None and b.action == "field"
        assert ("L", b.description) in [(k, d) for _, k, d in controls.help_lines(mode)]
    assert "| `L` |" in controls.markdown_table("play")


def test_the_field_fades_with_the_distance_to_the_nearest_wall():
    a = map_view.field_alpha(np.array([0.0, 0.25, 0.5, 1.0, 1.99, 2.0, 5.0]))
    assert a[0] == map_view.FIELD_ALPHA
    assert np.all(np.diff(a.astype(int)) <= 0) and a[3] > 0
    assert a[5] == 0 and a[6] == 0


def test_the_field_image_is_the_distance_transform_of_the_map():
    grid = load_scenario("symmetric_room").world.grid
    img = map_view.field_image(grid)
    rows, cols = grid.shape
    assert img.get_size() == (cols, rows)
    alpha = pygame.surfarray.array_alpha(img).T[::-1]          # back to (rows, cols), row 0 bottom
    d = distance_transform(grid.occupied) * grid.resolution
    want = map_view.field_alpha(d)
    want[grid.cells != 0] = 0
    assert np.array_equal(alpha, want)
    free = grid.cells == 0
    far = np.unravel_index(np.argmax(np.where(free, d, -1)), d.shape)
    assert alpha[1, 1] > 150 and alpha[far] < alpha[1, 1] / 2   # hot by the walls, cool away


def test_l_draws_the_field_and_l_again_takes_it_away():
    app = make_app("symmetric_room")
    try:
        app.run(app.frames + 2)
        off = pygame.surfarray.array3d(app.screen).copy()
        assert not app.show.field                              # off by default
        press(pygame.K_l)
        app.run(app.frames + 1)
        assert app.show.field
        on = pygame.surfarray.array3d(app.screen).copy()
        world = app.view.to_px(np.array([[1.0, 3.0], [3.0, 3.5]]))   # free floor, no robot
        (x0, y0), (x1, y1) = np.round(world).astype(int)
        patch_off, patch_on = off[x0:x1, y1:y0], on[x0:x1, y1:y0]
        changed = np.any(patch_off != patch_on, axis=2).mean()
        assert changed > 0.5, changed
        # The field's tint: more red than blue where it was grey floor.
        assert (patch_on[..., 0].astype(int) - patch_on[..., 2]).mean() > \
            (patch_off[..., 0].astype(int) - patch_off[..., 2]).mean() + 20
        press(pygame.K_l)
        app.run(app.frames + 1)
        again = pygame.surfarray.array3d(app.screen)
        assert np.any(again[x0:x1, y1:y0] != patch_on, axis=2).mean() > 0.5
    finally:
        app.close()


def _panel_lines(app, monkeypatch) -> list[tuple[str, tuple]]:
    drawn: list[tuple[str, tuple]] = []
    real = app.hud._blit

    def blit(surf, text, font, colour, at, bg=None):
        drawn.append((text, tuple(colour)))
        return real(surf, text, font, colour, at, bg)

    monkeypatch.setattr(app.hud, "_blit", blit)
    app.run(app.frames + 1)
    monkeypatch.setattr(app.hud, "_blit", real)
    return drawn


def test_the_corridor_panel_tells_the_scan_not_missing_beacons(monkeypatch):
    app = make_app("corridor")
    try:
        app.run(app.frames + 20)            # a scan or more has been read
        beams, hits = scan_in_view(app.session)
        spec = next(s for s in app.session.scenario.sensors if s.kind == "range_finder")
        assert beams == spec.n_beams and 0 < hits <= beams
        drawn = _panel_lines(app, monkeypatch)
        texts = [t for t, _ in drawn]
        assert not any(t.startswith("beacons in view") for t in texts), texts
        line = next((t, c) for t, c in drawn if t.startswith("scan:"))
        assert line[1] != palette.WARN
        _, n_hit, _, n_beams, _, _ = line[0].split()
        beams, hits = scan_in_view(app.session)
        assert (int(n_hit), int(n_beams)) == (hits, beams)
    finally:
        app.close()


@pytest.mark.parametrize("name", ["default"])
def test_a_beacon_world_keeps_its_beacon_line(name, monkeypatch):
    app = make_app(name)
    try:
        app.run(app.frames + 5)
        texts = [t for t, _ in _panel_lines(app, monkeypatch)]
        assert any(t.startswith("beacons in view") for t in texts)
        assert not any(t.startswith("scan:") for t in texts)
    finally:
        app.close()
