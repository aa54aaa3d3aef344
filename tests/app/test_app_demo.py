"""A demo that never surprises: what a class sees in the window is true, visible
from the back row, fits a projector's 1024x768, and replays.

Each test is one bullet of the issue (the motion model's are in tests/core/test_motion_slip.py).
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import subprocess
import sys
from pathlib import Path

import numpy as np
import pygame
import pytest

from beacon_sim.app import palette
from beacon_sim.app.estimate_layer import ellipse_diameter
from beacon_sim.app.help_overlay import split_columns
from beacon_sim.app.hud import Hud
from beacon_sim.app.in_view import missed_ids
from beacon_sim.app.pace import DeliveredSpeed
from beacon_sim.app.render import View, WorldRenderer
from beacon_sim.app.strip import StripChart
from beacon_sim.app.text import fit_text
from beacon_sim.app.view import world_rect
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.cli.main import main
from beacon_sim.cli.play import MIN_SIZE, parse_size
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.types import Control
from beacon_sim.errors import UsageError
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.styles import KIND_STYLES, OTHER_STYLES, TEAM_STYLES

PROJECTOR = (1024, 768)


def make_app(scenario="assignment_kf", filters=None, size=PROJECTOR, autopilot=True, **kw):
    sc = load_scenario(scenario)
    s = Session(sc, list(filters or sc.default_filters))
    if autopilot:
        s.toggle_autopilot()
    return App(s, size, scripted=True, **kw)


def run_to(app, t):
    """Tick the session to simulated time ``t`` [s] (feeding the chart), then draw a frame."""
    s = app.session
    while s.time < t - 1e-9:
        app.after_tick(s.tick())
    app.run(app.frames + 1)


def spy_blits(monkeypatch):
    drawn = []
    real = Hud._blit

    def spy(self, surf, text, font, colour, at, bg=None):
        r = real(self, surf, text, font, colour, at, bg)
        drawn.append((text, r))
        return r

    monkeypatch.setattr(Hud, "_blit", spy)
    return drawn


# --- DISPLAY pointing at no server ----------------------------------------------------------
@pytest.mark.parametrize("command", ["play", "replay"])
def test_a_display_with_no_server_is_one_line_and_exit_2(tmp_path, command):
    sock = Path("/tmp/.X11-unix")
    free = next(n for n in range(99, 400) if not (sock / f"X{n}").exists())
    env = {k: v for k, v in os.environ.items() if k not in ("SDL_VIDEODRIVER", "WAYLAND_DISPLAY")}
    runtime = tmp_path / "xdg"  # as in a desktop session (else SDL itself complains of it)
    runtime.mkdir(mode=0o700)
    env.update(DISPLAY=f":{free}", PYTHONPATH=os.pathsep.join(sys.path), SDL_AUDIODRIVER="dummy",
               PYGAME_HIDE_SUPPORT_PROMPT="1", XDG_RUNTIME_DIR=str(runtime))
    args = ["play", "default", "--frames", "5", "--filter", "dead_reckoning"]
    if command == "replay":
        sc = load_scenario("default")
        with Recorder(tmp_path / "r.jsonl", sc, sc.seed, ["dead_reckoning"], {}) as rec:
            for k in range(1, 11):
                rec.record_tick(k, Control(0.3, 0.1), [])
        args = ["replay", str(tmp_path / "r.jsonl"), "--frames", "5"]
    done = subprocess.run([sys.executable, "-m", "beacon_sim", *args], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and f":{free}" in lines[0] and "SDL_VIDEODRIVER=dummy" in lines[0]
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "recordings").exists()  # nothing recorded invisibly


# --- the small ellipse: a magnifier with a scale bar, ellipses above the wedges -------------
def test_three_beacons_the_kf_ellipse_is_magnified_with_its_size():
    app = make_app()
    try:
        run_to(app, 52.9)  # three beacons in view, the KF's sigma 0.02 m (docs/window.md)
        s = app.session
        assert len(s.seen_ids()) == 3
        _, cov = s.estimate("kf")
        across = ellipse_diameter(cov)
        assert across * app.view.scale < 2 * s.scenario.robot_radius * app.view.scale + 30
        mag = app.renderer.last_magnifier
        assert mag is not None and mag["across_px"]["kf"] >= 6.0
        assert mag["across_px"]["kf"] == pytest.approx(across * mag["scale"])
        # the ellipse is on the screen in the inset, in the KF's colour
        arr = pygame.surfarray.array3d(app.screen)
        r = mag["rect"]
        inset = arr[r.left:r.right, r.top:r.bottom]
        assert np.all(inset == app.colours["kf"], axis=2).sum() > 50
        assert not mag["rect"].collidepoint(*app.view.to_px(s.true_pose[:2]))
    finally:
        app.close()


def test_ellipses_are_drawn_after_every_wedge(monkeypatch):
    calls = []
    real = WorldRenderer.uncertainty

    def spy(self, surf, view, mean, cov, colour, dash, radius, width=None, wedge=True, ellipse=True):
        calls.append((wedge, ellipse))
        return real(self, surf, view, mean, cov, colour, dash, radius, width, wedge, ellipse)

    monkeypatch.setattr(WorldRenderer, "uncertainty", spy)
    app = make_app("default")
    try:
        run_to(app, 1.0)
        calls.clear()
        app.draw()  # one frame
        wedges = [i for i, (w, e) in enumerate(calls) if w and not e]
        ellipses = [i for i, (w, e) in enumerate(calls) if e and not w]
        assert len(wedges) == 2 and len(ellipses) >= 2  # ekf and dead reckoning (and a magnifier)
        assert max(wedges) < min(ellipses)
    finally:
        app.close()


# --- the strip chart is not scaled by dead reckoning ----------------------------------------
def test_the_strip_chart_scale_leaves_dead_reckoning_out():
    class Scene:
        def __init__(self):
            self.time, self.status = 0.0, {}

        def seen_ids(self):
            return set()

    class St:
        failed = None

        def __init__(self, err, sigma):
            self.pos_err, self.pos_sigma = err, sigma

    chart = StripChart(["kf", "dead_reckoning"], 0.05)
    scene = Scene()
    for k in range(100):
        scene.time = k * 0.05
        scene.status = {"kf": St(0.05, 0.1 + 0.002 * k), "dead_reckoning": St(3.0 + k, 5.0 + k)}
        chart.record(scene)
    assert chart.y_range(["kf", "dead_reckoning"]) == pytest.approx(2 * (0.1 + 0.002 * 99))
    assert chart.y_range(["dead_reckoning"]) == pytest.approx(2 * (5.0 + 99))


# --- particles: at least 2 px, 3:1 against the floor ----------------------------------------
@pytest.mark.parametrize("colour", sorted({c for c, _ in [*KIND_STYLES.values(), *OTHER_STYLES,
                                                          *TEAM_STYLES.values()]}))
def test_particle_colours_have_the_contrast_of_a_projector(colour):
    heavy, light = palette.particle_colours(colour)
    for floor in palette.FLOORS:
        assert palette.contrast_ratio(heavy, floor) >= 4.5
        assert palette.contrast_ratio(light, floor) >= 3.0
    assert palette.contrast_ratio((0, 0, 0), (255, 255, 255)) == pytest.approx(21.0)
    assert palette.contrast_ratio((250, 250, 247), (250, 250, 247)) == pytest.approx(1.0)


@pytest.mark.parametrize("n", [500, 100_000])
def test_particles_are_at_least_2_px_at_1024x768(n):
    pygame.display.init()
    surf = pygame.Surface(PROJECTOR)
    surf.fill(palette.BACKGROUND)
    v = View((0.0, 0.0, 12.0, 8.0), (0, 0, 750, 768))
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(0, 12, n), rng.uniform(0, 8, n), np.zeros(n)])
    colour = KIND_STYLES["pf"][0]
    WorldRenderer({}).particles(surf, v, poses, colour)
    heavy = palette.particle_colours(colour)[0]
    arr = pygame.surfarray.array3d(surf)
    mask = np.all(arr == heavy, axis=2)
    x, y = (int(c) for c in v.to_px(poses[0, :2]))
    assert mask[x:x + 2, y:y + 2].all()  # a 2x2 block at least


# --- 1024x768 layouts -------------------------------------------------------------------------
@pytest.mark.parametrize("size", [PROJECTOR, MIN_SIZE])
def test_the_panel_fits_with_a_recording_and_a_hidden_filter(size, monkeypatch):
    drawn = spy_blits(monkeypatch)
    rec = Path("recordings/assignment_kf_20261201-172233.jsonl")
    app = make_app(size=size, recording=rec)
    try:
        app.session.command({"kind": "toggle", "filter": "dead_reckoning"})
        run_to(app, 2.0)
        drawn.clear()
        app.draw()
        panel = app.panel_rect
        texts = [(t, r) for t, r in drawn if r.left >= panel.left]
        for text, r in texts:
            assert r.right <= panel.right - 4, (text, r)
        assert any(t.startswith("REC assignment") for t, _ in texts)
        assert any("dead_reckoning" in t and ("(hidden)" in t or "(off)" in t) for t, _ in texts)
    finally:
        app.close()
    assert fit_text(app.fonts["small"], "x" * 300, 100).count("...") == 1


@pytest.mark.parametrize("size", [PROJECTOR, MIN_SIZE, (1920, 1080)])
def test_the_help_overlay_fits_and_nothing_overlaps(size):
    app = make_app(size=size)
    try:
        app.help = True
        app.run(1)
        hud = app.hud
        box = hud.help_box
        assert pygame.Rect((0, 0), size).contains(box)
        rects = hud.help_rects
        assert len(hud.help_drawn) > 20
        for i, a in enumerate(rects):
            assert box.contains(a), (size, a, box)
            for b in rects[i + 1:]:  # (a line's box is 1 px taller than the line spacing)
                assert not a.inflate(0, -2).colliderect(b.inflate(0, -2)), (size, a, b)
    finally:
        app.close()
    assert split_columns([3, 3, 3, 3], 2) == ([0, 0, 1, 1], 6.0)


def test_beacon_labels_keep_off_the_axis_labels_in_krejsa_bearing_only():
    app = make_app("krejsa_bearing_only", size=PROJECTOR)
    try:
        run_to(app, 0.5)
        r = app.renderer
        assert r.axis_rects and r.beacon_rects
        labels = r.beacon_rects[len(app.session.scenario.world.beacons):]
        for lab in labels:
            assert lab.collidelist(r.axis_rects) < 0
    finally:
        app.close()


def test_robot_names_keep_off_the_beacon_labels_in_team_sparse():
    from beacon_sim.app.window import App
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.runs.live import Session

    team = load_team_scenario("team_sparse")
    app = App(Session(team, list(team.default_filters)), PROJECTOR, scripted=True)
    try:
        for n in (30, 200):
            app.run(n)
            tags = app.renderer.tags
            assert len(tags) == len(team.robots)
            covered = sum(t.collidelist(app.renderer.beacon_rects) >= 0 for t in tags)
            assert covered == 0, (n, tags)
    finally:
        app.close()


def test_the_step_view_box_covers_no_axis_label():
    app = make_app(size=PROJECTOR)
    try:
        app.act("chart")  # the chart leaves less room under the world
        run_to(app, 24.0)
        app.clock.toggle_pause()
        app.act("bound")
        app.clock.single_step()
        app.run(app.frames + 2)
        box = app.hud.step_box
        assert box.collidelist(app.renderer.axis_rects) < 0
        assert pygame.Rect(app.view.area).contains(box)
    finally:
        app.close()


def test_size_has_a_stated_minimum(capsys):
    assert parse_size("1024x768") == (1024, 768)
    assert parse_size(f"{MIN_SIZE[0]}x{MIN_SIZE[1]}") == MIN_SIZE
    for bad in ("10x10", "400x300", "799x600", "800x599"):
        with pytest.raises(UsageError, match=r"at least 800x600"):
            parse_size(bad)
    assert main(["play", "default", "--size", "400x300", "--frames", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at least 800x600" in err[0]


# --- missed detections ------------------------------------------------------------------------
def test_beacons_in_the_sensor_disc_that_were_missed_are_marked(monkeypatch):
    sc = load_scenario("assignment_kf")
    world = sc.world
    spec = sc.sensors[0]
    pose = np.array([*world.beacon_xy[0], 0.0])  # on beacon 1: inside the disc
    ids = missed_ids(sc.sensors, world, pose, seen=set())
    assert world.beacons[0].id in ids
    far = {b.id for b, xy in zip(world.beacons, world.beacon_xy, strict=True)
           if np.hypot(*(xy - pose[:2])) > spec.max_range}
    assert not ids & far
    assert missed_ids(sc.sensors, world, pose, seen=ids) == set()
    # in the window: the panel lists them and the map rings them in the warning colour
    drawn = spy_blits(monkeypatch)
    app = make_app(autopilot=False)
    try:
        s = app.session
        run_to(app, 1.0)
        for seen in s._readings:  # as if every beacon in range had been missed
            seen.clear()
        drawn.clear()
        app.draw()
        missed = missed_ids(sc.sensors, world, s.true_pose, set())
        assert missed
        assert any(t.startswith("  missed in range:") for t, _ in drawn)
        arr = pygame.surfarray.array3d(app.screen)
        i = next(k for k, b in enumerate(world.beacons) if b.id in missed)
        x, y = (int(c) for c in app.view.to_px(world.beacon_xy[i]))
        ring = arr[x - 20:x + 21, y - 20:y + 21]
        assert np.all(ring == palette.WARN, axis=2).sum() > 20
    finally:
        app.close()


# --- no black first second; global_kidnap's first frame before it localizes ----------------
def test_the_first_frame_is_drawn_before_any_tick_with_the_particles_spread():
    app = make_app("global_kidnap", size=PROJECTOR)
    try:
        app.run(0)  # the loop's first picture, no frame run
        assert app.session.tick_count == 0
        arr = pygame.surfarray.array3d(app.screen)
        assert arr.max() > 0  # not black
        heavy = palette.particle_colours(app.colours["pf"])[0]
        mask = np.all(arr == heavy, axis=2)
        wr = world_rect(app.view)
        xs = (slice(wr.left, wr.centerx), slice(wr.centerx, wr.right))
        ys = (slice(wr.top, wr.centery), slice(wr.centery, wr.bottom))
        quads = [mask[x, y] for x in xs for y in ys]
        assert all(q.sum() > 500 for q in quads)  # the ring of possible positions: everywhere
    finally:
        app.close()


# --- the speed actually delivered -------------------------------------------------------------
def test_delivered_speed_is_measured_and_shown_when_short(monkeypatch):
    d = DeliveredSpeed()
    for k in range(200):
        d.sample(k / 60, k / 60 * 0.5, 1.0, False)
    assert d.factor == pytest.approx(0.5)
    d.sample(200 / 60, 1.0, 2.0, False)  # a new speed: measured afresh
    assert d.factor is None
    drawn = spy_blits(monkeypatch)
    app = make_app("default", filters=["dead_reckoning"])
    try:
        app.clock.set_speed(8.0)
        app.clock.max_steps_per_frame = 1  # the machine keeps up with x3 only (1 tick a frame)
        for _ in range(200):
            app.frame(SCRIPTED_FRAME_S)
        assert app.pace.factor == pytest.approx(0.05 * 60, rel=0.02)
        assert any(t.startswith("delivering only x3") for t, _ in drawn)
        drawn.clear()
        app.clock.max_steps_per_frame = 8
        for _ in range(200):
            app.frame(SCRIPTED_FRAME_S)
        assert app.pace.factor == pytest.approx(8.0, rel=0.02)
        drawn.clear()
        app.draw()
        assert not any(t.startswith("delivering") for t, _ in drawn)
    finally:
        app.close()


# --- taking over from the autopilot -----------------------------------------------------------
def test_taking_over_from_the_autopilot_rounds_to_the_keyboards_steps():
    sc = load_scenario("default")
    s = Session(sc, ["dead_reckoning"])
    s.toggle_autopilot()
    fractional = False
    for _ in range(400):
        s.tick()
        c = s.controls[-1]
        fractional |= abs(c.omega / sc.keyboard.omega_step - round(c.omega / sc.keyboard.omega_step)) > 1e-6
    assert fractional, "the autopilot steers with fractional omega"
    s.toggle_autopilot()
    lim = sc.keyboard
    for value, step in ((s.keyboard.v, lim.v_step), (s.keyboard.omega, lim.omega_step)):
        assert value / step == pytest.approx(round(value / step), abs=1e-9)
    last = s.controls[-1]
    assert abs(s.keyboard.v - last.v) <= lim.v_step / 2 + 1e-9
    assert abs(s.keyboard.omega - last.omega) <= lim.omega_step / 2 + 1e-9
    # after letting go of A/D (A then D), the robot goes straight: omega exactly 0
    s.keyboard.omega = 0.0
    s.drive("a")
    s.drive("d")
    assert s.next_control() == Control(s.keyboard.v, 0.0)


# --- G on a Gaussian filter says what it did -------------------------------------------------
def test_g_says_which_filters_cannot_take_a_global_belief():
    app = make_app("default", filters=["ekf", "pf", "dead_reckoning"])
    try:
        app.act("global_reset")
        text = app.banner_text
        assert "pf spread over the room" in text
        assert "ekf" in text and "dead_reckoning" in text and "cannot" in text
    finally:
        app.close()


# --- replay --size; GIF at the window's size ---------------------------------------------------
def test_replay_opens_at_the_size_asked(tmp_path):
    sc = load_scenario("default")
    path = tmp_path / "r.jsonl"
    with Recorder(path, sc, sc.seed, ["dead_reckoning"], {}) as rec:
        for k in range(1, 41):
            rec.record_tick(k, Control(0.3, 0.1), [])
    shot = tmp_path / "replay.png"
    assert main(["replay", str(path), "--size", "1024x768", "--frames", "3",
                 "--screenshot", str(shot)]) == 0
    assert pygame.image.load(str(shot)).get_size() == (1024, 768)
    assert main(["replay", str(path), "--size", "10x10", "--frames", "3"]) == 2


def test_a_gif_can_be_as_wide_as_the_window(tmp_path, monkeypatch):
    from PIL import Image

    monkeypatch.chdir(tmp_path)
    gif = tmp_path / "demo.gif"
    assert main(["play", "default", "--filter", "dead_reckoning", "--size", "1024x768",
                 "--frames", "13", "--no-record", "--gif", str(gif), "--gif-width", "window"]) == 0
    assert Image.open(gif).size == (1024, 768)
    assert main(["play", "default", "--frames", "1", "--gif", str(gif), "--gif-width", "9"]) == 2
