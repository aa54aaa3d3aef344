"""``run --smooth``, ``eval --smooth`` and ``replay FILE --smooth``: the figures in the JSON
and the table, the smoothed layer drawn in the replay window."""

from __future__ import annotations

import json
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.recording import load_recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.smoothing import smooth_recording


def test_run_smooth_reports_filtered_and_smoothed_against_their_bounds(capsys):
    assert main(["run", "default", "--duration", "20", "--seed", "4", "--filter", "ekf",
                 "--filter", "dead_reckoning", "--smooth", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    fig = d["filters"]["ekf"]["smoothing"]
    assert "smoothing" not in d["filters"]["dead_reckoning"]
    f, s = fig["filtered"], fig["smoothed"]
    assert f["pos_rmse_m"] == pytest.approx(d["filters"]["ekf"]["pos_rmse_m"], rel=1e-12)
    assert s["pos_rmse_m"] < f["pos_rmse_m"]
    assert s["bound_pos_rmse_m"] < f["bound_pos_rmse_m"]
    assert main(["run", "default", "--duration", "5", "--filter", "ekf", "--smooth"]) == 0
    out = capsys.readouterr().out
    assert "smoothed" in out and "RMSE/bound" in out


def test_eval_smooth_adds_intervals_over_runs(capsys):
    assert main(["eval", "default", "--filter", "ekf", "--runs", "3", "--duration", "10",
                 "--smooth", "--json", "--jobs", "1"]) == 0
    d = json.loads(capsys.readouterr().out)
    s = d["smoothing"]["ekf"]
    assert s["runs"] == 3
    lo, hi = s["smoothed"]["pos_rmse_m_ci"]
    assert lo <= s["smoothed"]["pos_rmse_m"] <= hi


def test_replay_smooth_draws_the_smoothed_layer(tmp_path):
    path = tmp_path / "drive.jsonl"
    sc = load_scenario("default")
    live = Session(sc, ["ekf"], 3, {}, Recorder(path, sc, 3, ["ekf"], {}))
    for k in ("w", "w", "w", "a"):
        live.drive(k)
    for _ in range(200):
        live.tick()
    live.close()
    tracks = smooth_recording(load_recording(path), ["ekf"])
    tr = tracks["ekf"]
    assert tr.ticks[-1] == 200 and np.isfinite(tr.smoothed_covs).all()
    plain, smooth = tmp_path / "plain.png", tmp_path / "smooth.png"
    assert main(["replay", str(path), "--filter", "ekf", "--frames", "30", "--screenshot", str(plain)]) == 0
    assert main(["replay", str(path), "--filter", "ekf", "--smooth", "--frames", "30",
                 "--screenshot", str(smooth)]) == 0
    import pygame

    a = pygame.surfarray.array3d(pygame.image.load(str(plain))).astype(int)
    b = pygame.surfarray.array3d(pygame.image.load(str(smooth))).astype(int)
    assert a.shape == b.shape and (np.abs(a - b).sum(axis=2) > 0).sum() > 200  # the layer and its legend


def test_replay_smooth_headless_is_a_usage_error(tmp_path, capsys):
    path = tmp_path / "drive.jsonl"
    sc = load_scenario("default")
    live = Session(sc, ["ekf"], 3, {}, Recorder(path, sc, 3, ["ekf"], {}))
    live.tick()
    live.close()
    assert main(["replay", str(path), "--headless", "--smooth"]) == 2
    assert "--smooth draws in the window" in capsys.readouterr().err
