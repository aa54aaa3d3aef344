"""The shipped font and icon: present, loaded from assets/, and drawing something."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import pygame
import pytest

from beacon_sim.app import assets
from beacon_sim.core.resources import asset_path

SAMPLE = "0.12 m"


@pytest.fixture(autouse=True)
def _font():
    pygame.font.init()
    yield


def _ink(surf: pygame.Surface) -> int:
    """Pixels of a rendered text surface that are not transparent."""
    w, h = surf.get_size()
    return sum(surf.get_at((x, y)).a > 0 for x in range(w) for y in range(h))


@pytest.mark.parametrize("name", [assets.REGULAR, assets.BOLD, "OFL.txt", assets.ICON])
def test_asset_files_ship(name):
    p = asset_path(name)
    assert p.is_file() and p.stat().st_size > 0
    if name.endswith(".ttf"):
        assert p.read_bytes()[:4] == b"\x00\x01\x00\x00"  # a TrueType font
    if name == "OFL.txt":
        assert "SIL OPEN FONT LICENSE Version 1.1" in p.read_text()


@pytest.mark.parametrize("height", [600, 800, 1440])
def test_every_font_is_the_shipped_ttf(height):
    fonts = assets.load_fonts(height)
    assert set(fonts) == {"title", "hud", "small", "label", "banner"}
    for name, size in assets.font_sizes(height).items():
        f = fonts[name]
        ttf = pygame.font.Font(str(asset_path(assets.FONT_FILES[name])), size)
        default = pygame.font.Font(None, size)
        assert f.metrics(SAMPLE) == ttf.metrics(SAMPLE)
        assert f.get_linesize() == ttf.get_linesize()
        assert f.metrics(SAMPLE) != default.metrics(SAMPLE)
        img = f.render(SAMPLE, True, (0, 0, 0))
        assert img.get_width() > 0 and _ink(img) > 0


def test_text_is_tall_enough_for_a_projector_and_grows_with_the_window():
    """Digits at least 13 px tall (the small panel text) in an 800 px window, the headings
    larger, and every font twice as tall in a 1600 px window (within a pixel)."""
    at800, at1600 = assets.load_fonts(800), assets.load_fonts(1600)
    height = {name: f.metrics("0")[0][3] for name, f in at800.items()}
    assert height["small"] >= 13 and height["hud"] >= 16
    assert height["title"] > height["hud"] > height["small"] and height["banner"] > height["title"]
    for name, f in at1600.items():
        assert abs(f.metrics("0")[0][3] - 2 * height[name]) <= 2, name


def test_fonts_grow_with_the_window_but_not_below_800_px():
    assert assets.font_sizes(500) == assets.font_sizes(800)
    small, big = assets.font_sizes(800), assets.font_sizes(1600)
    assert all(big[k] > small[k] for k in small)


def test_window_icon_loads_at_64_px_with_alpha():
    icon = assets.window_icon()
    assert icon.get_size() == (64, 64)
    assert icon.get_flags() & pygame.SRCALPHA
    # A picture, not a blank square: several distinct colours.
    colours = {tuple(icon.get_at((x, y))) for x in range(0, 64, 4) for y in range(0, 64, 4)}
    assert len(colours) > 5
