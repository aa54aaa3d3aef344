"""The motion model's slip: slip that scales with the command, and a bumped turn that replays.

- At v = omega = 0 the truth does not move (the "scaled" slip model); the filters' process
  noise, the batched simulation and the PCRB follow the same gain.
- A robot that turns into a wall is recorded with the command the truth executed, so its
  recording replays "verified".
- A recording without the "slip_model" header key (made before 0.3.0) replays with the
  legacy model, to the same truth it was recorded with.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from beacon_sim.core import motion
from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.scenario import load_scenario, team_of_one
from beacon_sim.core.simulation import Simulation, scenario_with_slip
from beacon_sim.core.team import TeamSimulation
from beacon_sim.core.types import Control
from beacon_sim.io.recording import RecordingError, load_recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import replay_recording

NOT_RECORDED = ("not verified: the filter settings and estimates (not recorded); truth and "
                "readings verified")

NOISE = motion.MotionNoise(v_std=0.02, v_frac=0.3, omega_std=0.1, omega_frac=0.1,
                           pose_std=(0.015, 0.015, 0.01))


def test_slip_gain_is_zero_at_standstill_and_one_once_moving():
    assert NOISE.slip_gain(0.0, 0.0) == 0.0
    assert NOISE.slip_gain(0.1, 0.0) == 1.0 and NOISE.slip_gain(0.0, -0.2) == 1.0
    assert NOISE.slip_gain(0.01, 0.0) == pytest.approx(0.01 / motion.FULL_SLIP_V)
    assert motion.with_slip(NOISE, "legacy").slip_gain(0.0, 0.0) == 1.0
    sv, sw = NOISE.control_std(0.0, 0.0)
    assert sv == 0.0 and sw == 0.0 and not NOISE.pose_std_at(0.0, 0.0).any()
    with pytest.raises(ValueError, match="slip model"):
        motion.with_slip(NOISE, "icy")


def test_process_cov_is_zero_at_standstill_and_unchanged_while_moving():
    pose = np.array([1.0, 2.0, 0.3])
    assert not NOISE.process_cov(pose, 0.0, 0.0, 0.05).any()
    legacy = motion.with_slip(NOISE, "legacy")
    for v, w in [(0.4, 0.0), (0.0, 0.6), (-0.3, 1.0)]:
        assert np.array_equal(NOISE.process_cov(pose, v, w, 0.05), legacy.process_cov(pose, v, w, 0.05))


def test_process_cov_matches_the_spread_of_the_sampled_truth_at_a_slow_command():
    """Monte Carlo: the truth's one-step spread at a command below full slip equals Q."""
    sc = scenario_with_slip(load_scenario("default"), "scaled")
    sc = replace(sc, motion_noise=NOISE)
    v, w = 0.02, 0.03   # gain 0.7
    n = 4000
    end = np.empty((n, 3))
    for i in range(n):
        sim = Simulation(sc, seed=i)
        sim.pose = np.array([3.0, 3.0, 0.4])
        end[i] = sim.step(Control(v, w)).true_pose
    Q = NOISE.process_cov(np.array([3.0, 3.0, 0.4]), v, w, sc.dt)
    emp = np.cov(end.T)
    assert np.allclose(np.diag(emp), np.diag(Q), rtol=0.12)


@pytest.mark.parametrize("name", ["assignment_kf", "default", "krejsa_bearing_only"])
def test_a_stopped_robot_stays_within_a_centimetre_over_a_minute(name):
    sc = replace(load_scenario(name), events=())   # no kidnap: the robot is left alone
    sim = Simulation(sc)
    start = sim.pose.copy()
    for _ in range(round(60.0 / sc.dt)):
        sim.step(Control(0.0, 0.0))
    assert np.hypot(*(sim.pose[:2] - start[:2])) < 0.01
    # the legacy model (what the class saw before 0.3.0) creeps past the bound
    old = Simulation(scenario_with_slip(sc, "legacy"))
    for _ in range(round(60.0 / sc.dt)):
        old.step(Control(0.0, 0.0))
    if any(sc.motion_noise.pose_std[:2]) or sc.motion_noise.v_std:
        assert np.hypot(*(old.pose[:2] - start[:2])) > 0.01


def test_the_batched_simulation_follows_the_single_one_at_standstill_and_slow():
    sc = load_scenario("assignment_kf")
    batch = BatchSimulation(sc, [1, 2])
    singles = [Simulation(sc, 1), Simulation(sc, 2)]
    # drive the batch through its own commands; give the singles the same commands
    for _ in range(200):
        cv, cw = batch._commands(batch.time, batch.pose)
        steps = batch.step()
        for s, st, v, w in zip(singles, steps, cv.tolist(), cw.tolist(), strict=True):
            assert np.array_equal(s.step(Control(v, w)).true_pose, st.true_pose)
    assert batch.truth_checksums() == [s.truth_checksum for s in singles]


def test_dead_reckoning_covariance_stops_growing_at_standstill():
    from beacon_sim.hosting.loading import build_filters

    sc = load_scenario("assignment_kf")
    built, broken = build_filters(["dead_reckoning", "kf"], sc, sc.seed, {})
    assert not broken
    for flt in built.values():
        flt.predict(Control(0.0, 0.0), sc.dt)
        before = flt.estimate()[1].copy()
        for _ in range(100):
            flt.predict(Control(0.0, 0.0), sc.dt)
        assert np.allclose(flt.estimate()[1], before, atol=1e-12)
        flt.predict(Control(0.5, 0.0), sc.dt)
        assert np.trace(flt.estimate()[1]) > np.trace(before)


def _drive_into_a_wall_turning(path, scenario="assignment_kf", ticks=900):
    """The issue's key script: W x10, then A once, until well past the first bump."""
    sc = load_scenario(scenario)
    rec = Recorder(path, sc, sc.seed, ["kf"], {})
    s = Session(sc, ["kf"], recorder=rec)
    for _ in range(10):
        s.drive("w")
    s.drive("a")
    bumps = 0
    for _ in range(ticks):
        step = s.tick().steps[0]
        bumps += sum(e.kind == "bump" for e in step.events)
        if step.events and any(e.kind == "bump" for e in step.events):
            s.drive("w")  # the driver keeps pushing into the wall, still turning
    s.close()
    return s, bumps


def test_a_turning_wall_hit_replays_verified(tmp_path):
    path = tmp_path / "turn_into_wall.jsonl"
    s, bumps = _drive_into_a_wall_turning(path)
    assert bumps >= 2
    rec = load_recording(path)
    assert rec.header["slip_model"] == "scaled"
    res = replay_recording(rec)
    assert res.extra["replay"]["checksum_status"].startswith("verified")
    assert res.truth_checksum == s.sim.truth_checksum


def test_an_old_recording_replays_with_the_legacy_model(tmp_path):
    """A file without "slip_model" was made with the legacy slip: it replays to its truth,
    standstill included (the scaled model would stop the creeping robot and differ)."""
    sc = scenario_with_slip(load_scenario("assignment_kf"), "legacy")
    path = tmp_path / "old.jsonl"
    rec = Recorder(path, load_scenario("assignment_kf"), sc.seed, ["kf"], {})
    rec.shadow = TeamSimulation(team_of_one(sc), sc.seed)   # a recorder from before 0.3.0
    for k in range(1, 201):
        rec.record_tick(k, Control(0.0, 0.0) if k > 50 else Control(0.3, 0.2), [])
    rec.close()
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    del header["slip_model"]
    path.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    res = replay_recording(load_recording(path))
    assert res.truth_checksum == rec.truth_checksum
    header["slip_model"] = "scaled"
    path.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    with pytest.raises(RecordingError, match=r"differs|tick"):
        replay_recording(load_recording(path))
    header["slip_model"] = "icy"
    path.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    with pytest.raises(RecordingError, match="slip_model"):
        load_recording(path)


def _pushing(v, omega, slip="scaled"):
    """assignment_kf without events, its driver pushing (v, omega) from near the left wall
    towards it (heading pi)."""
    from beacon_sim.core.drivers import ConstantSpec

    sc = replace(load_scenario("assignment_kf"), events=(), driver=ConstantSpec(v, omega),
                 initial_pose=(0.6, 4.0, np.pi))
    return scenario_with_slip(sc, slip)


def _bumped_turns(sc, ticks=200):
    """(number of bumps, the largest change of pose on a bumped tick)."""
    sim = Simulation(sc)
    before, bumps, moved = sim.pose.copy(), 0, 0.0
    for _ in range(ticks):
        step = sim.step()
        if any(e.kind == "bump" for e in step.events):
            bumps += 1
            assert step.control.v == 0.0
            moved = max(moved, float(np.max(np.abs(step.true_pose - before))))
        before = step.true_pose.copy()
    return bumps, moved


def test_a_robot_pushed_straight_into_a_wall_does_not_turn_on_a_bump():
    bumps, moved = _bumped_turns(_pushing(0.5, 0.0))
    assert bumps > 20 and moved == 0.0  # told (0, 0): neither moves nor turns
    bumps, moved = _bumped_turns(_pushing(0.5, 0.0, "legacy"))
    assert bumps > 20 and moved > 0.0   # the legacy model jittered the heading at the wall


@pytest.mark.parametrize("omega", [0.0, 0.05, 0.3])
def test_the_batched_simulation_bumps_as_the_single_one(omega):
    sc = _pushing(0.6, omega)
    batch = BatchSimulation(sc, [3, 4])
    singles = [Simulation(sc, 3), Simulation(sc, 4)]
    bumps = 0
    for _ in range(300):
        for s, st in zip(singles, batch.step(), strict=True):
            mine = s.step()
            bumps += sum(e.kind == "bump" for e in mine.events)
            assert np.array_equal(mine.true_pose, st.true_pose)
            assert mine.control == st.control
    assert bumps > 10
    assert batch.truth_checksums() == [s.truth_checksum for s in singles]


def test_a_team_robot_turning_into_a_wall_replays_verified(tmp_path):
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.runs.live import Session

    team = load_team_scenario("team_sparse")
    path = tmp_path / "team_wall.jsonl"
    rec = Recorder(path, team, team.seed, ["independent"], {})
    s = Session(team, ["independent"], recorder=rec)
    for _ in range(10):
        s.drive("w")
    s.drive("a")
    bumps = 0
    for _ in range(600):
        step = s.tick()
        if any(e.kind == "bump" for e in step.steps[s.driven].events):
            bumps += 1
            s.drive("w")
    s.close()
    assert bumps >= 2
    out = replay_recording(load_recording(path))
    assert out.extra["replay"]["checksum_status"] in ("verified", NOT_RECORDED)
    assert out.truth_checksum == s.sim.truth_checksum


def test_an_old_team_recording_replays_with_the_legacy_model(tmp_path):
    """A team file without "slip_model": every robot replays with the legacy slip."""
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.core.team import TeamSimulation, team_with_slip

    team = load_team_scenario("team_sparse")
    path = tmp_path / "old_team.jsonl"
    rec = Recorder(path, team, team.seed, ["independent"], {})
    rec.shadow = TeamSimulation(team_with_slip(team, "legacy"), team.seed)  # before 0.3.0
    for k in range(1, 121):
        rec.record_tick(k, 0, Control(0.0, 0.0) if k > 40 else Control(0.3, 0.2))
    rec.close()
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    del header["slip_model"]
    path.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    out = replay_recording(load_recording(path))
    assert out.extra["replay"]["checksum_status"] == NOT_RECORDED
    assert out.truth_checksum == rec.truth_checksum
    header["slip_model"] = "scaled"  # the same file read under the new model differs
    path.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    with pytest.raises(RecordingError):
        replay_recording(load_recording(path))
