"""F12: screenshots under screenshots/, a new name each press (two in one second do not
overwrite), and no banner in the picture (a quick second press does not capture the first
press's "saved" banner)."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from beacon_sim.app.window import App  # noqa: E402
from beacon_sim.core.scenario import load_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402


def test_two_quick_presses_make_two_files_without_the_banner(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    app = App(Session(load_scenario("default"), ["ekf"]), (1024, 768), scripted=True)
    try:
        app.run(5)
        app.act_pause()
        app.act("screenshot")
        assert app.now < app.banner_until  # the window says it saved
        app.run(app.frames + 1)  # the banner is on the screen now
        app.act("screenshot")
        files = sorted((tmp_path / "screenshots").glob("*.png"))
        assert len(files) == 2 and all(f.name.startswith("default_") for f in files)
        world = pygame.Rect(app.view.area)  # (the panel's FPS figure changes from frame to frame)
        a, b = (pygame.image.load(str(f)).subsurface(world) for f in files)
        assert pygame.image.tobytes(a, "RGB") == pygame.image.tobytes(b, "RGB")
        app.draw()  # the banner, which the pictures do not have
        shown = app.screen.subsurface(world)
        assert pygame.image.tobytes(shown, "RGB") != pygame.image.tobytes(a, "RGB")
    finally:
        app.close()
