"""Animated GIFs for slides: ``play --gif`` and ``replay --gif`` with
``--start`` / ``--end`` write a GIF with one frame per 6 window frames, 640 px wide, read
back with Pillow; and the command line options that start the window paused or slower."""

from __future__ import annotations

import math
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import pytest

from beacon_sim.app import gif as gif_mod
from beacon_sim.cli.main import main

Image = pytest.importorskip("PIL.Image")


def gif_frames(path) -> tuple[int, tuple[int, int], list[int]]:
    """(number of frames, size, duration of each frame [ms]) of a GIF read back."""
    with Image.open(path) as im:
        durations = []
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info.get("duration"))
        return im.n_frames, im.size, durations


def test_play_gif_has_one_frame_per_six_window_frames(tmp_path, capsys):
    out = tmp_path / "slide.gif"
    assert main(["play", "default", "--autopilot", "--frames", "120", "--no-record",
                 "--gif", str(out)]) == 0
    n, size, durations = gif_frames(out)
    assert n == math.ceil(120 / gif_mod.EVERY) == 20
    assert size == (640, 400)  # 1280x800 scaled down, aspect kept
    assert set(durations) == {100}  # 6 frames of 1/60 s: real time
    assert f"wrote {out}: 20 frames" in capsys.readouterr().err
    assert out.stat().st_size < 400_000


def test_replay_gif_between_start_and_end(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["play", "default", "--autopilot", "--frames", "300"]) == 0  # 5 s recorded
    (rec,) = (tmp_path / "recordings").glob("*.jsonl")
    out = tmp_path / "part.gif"
    assert main(["replay", str(rec), "--gif", str(out), "--start", "1", "--end", "3"]) == 0
    n, size, _ = gif_frames(out)
    assert n == math.ceil(2.0 * 60 / gif_mod.EVERY) == 20  # 2 s of window frames at x1
    assert size[0] == 640
    err = capsys.readouterr().err
    assert "stopped at tick 60 of 100" in err
    # bad spans and names are one-line usage errors
    assert main(["replay", str(rec), "--gif", str(out), "--start", "4", "--end", "2"]) == 2
    assert main(["replay", str(rec), "--gif", str(tmp_path / "x.png")]) == 2
    assert main(["replay", str(rec), "--gif", str(out), "--start", "99"]) == 2


def test_gif_recorder_keeps_colours_and_merges_nothing_that_moved(tmp_path):
    import pygame

    pygame.display.init()
    surf = pygame.Surface((1280, 800))
    rec = gif_mod.GifRecorder(tmp_path / "a.gif", every=1)
    for k in range(5):
        surf.fill((250, 250, 247))
        pygame.draw.rect(surf, (213, 94, 0), (100 + 40 * k, 100, 60, 60))
        rec.offer(surf)
    assert rec.save() == 5
    with Image.open(tmp_path / "a.gif") as im:
        assert im.n_frames == 5
        im.seek(4)
        rgb = im.convert("RGB")
        assert rgb.getpixel((int((100 + 160 + 30) / 2), 65)) == (213, 94, 0)  # exact hue
        assert rgb.getpixel((5, 5)) == (250, 250, 247)
