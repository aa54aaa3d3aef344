"""SLAM where a user looks. ``check`` judges a SLAM filter's
``landmarks()``; ``run --json`` gives each SLAM filter's ATE, map GOSPA and final joint NEES;
the HUD says "no IDs" under unknown correspondence and does not call unlabelled beacons
missed."""

from __future__ import annotations

import textwrap
from types import SimpleNamespace

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting import conformance
from beacon_sim.hosting.conformance import landmark_map_problems
from beacon_sim.hosting.loading import load_filter_class

GOOD_COV = np.array([[[0.04, 0.01], [0.01, 0.09]]] * 2)


def lmap(ids=None, means=None, covs=None):
    return SimpleNamespace(ids=ids, means=np.zeros((2, 2)) if means is None else means,
                           covs=GOOD_COV if covs is None else covs)


# -- 1. check: landmarks() --------------------------------------------------------------
def test_a_well_formed_map_has_no_problem():
    assert landmark_map_problems(lmap()) == []
    assert landmark_map_problems(lmap(ids=np.array([3, 7]))) == []
    assert landmark_map_problems(lmap(means=np.zeros((0, 2)), covs=np.zeros((0, 2, 2)))) == []


@pytest.mark.parametrize(("bad", "words"), [
    (None, "expected a LandmarkMap"),
    (lmap(means=np.zeros((2, 3))), "means of shape (2, 3)"),
    (lmap(covs=np.zeros((2, 3, 3))), "covs of shape (2, 3, 3)"),
    (lmap(covs=GOOD_COV[:1]), "2 means but 1 covs"),
    (lmap(ids=np.array([1, 2, 3])), "3 ids but 2 means"),
    (lmap(ids=np.array([1.0, 2.0])), "expected (M,) integers or None"),
    (lmap(means=np.array([[0.0, np.nan], [1.0, 1.0]])), "NaN or infinity"),
    (lmap(covs=np.array([GOOD_COV[0], [[0.04, 0.02], [0.0, 0.09]]])), "landmark 1 not symmetric"),
    (lmap(covs=np.array([[[1.0, 0.0], [0.0, -0.5]], GOOD_COV[0]])), "landmark 0 not positive semi-definite"),
])
def test_each_fault_of_a_map_has_its_message(bad, words):
    problems = landmark_map_problems(bad)
    assert len(problems) == 1 and words in problems[0], problems


def _by_name(results):
    return {r.name: r for r in results}


def test_check_judges_the_built_in_slam_filters_map_on_slam_loop():
    for spec in ("ekf_slam", "fastslam"):
        res = _by_name(conformance.run_checks(spec, load_scenario("default"), isolated=False))
        lm = res["landmarks"]
        assert lm.passed, lm.message
        assert "on slam_loop" in lm.message  # the default scenario's map is known
        assert int(lm.message.rsplit("up to ", 1)[1].split()[0]) >= 1  # it did map something
    plain = _by_name(conformance.run_checks("ekf", load_scenario("default"), isolated=False))
    assert "landmarks" not in plain  # a localization filter is not asked for a map


BROKEN = '''
import numpy as np
from beacon_sim.filters.base import LandmarkMap
from beacon_sim.filters.slam.ekf_slam import EKFSLAM

class SkewMap(EKFSLAM):
    """EKF-SLAM reporting non-symmetric landmark covariances once it has a landmark."""
    def landmarks(self):
        lm = super().landmarks()
        covs = lm.covs.copy()
        covs[:, 0, 1] += 1.0
        return LandmarkMap(lm.ids, lm.means, covs)

class ShortIds(EKFSLAM):
    def landmarks(self):
        lm = super().landmarks()
        return LandmarkMap(np.arange(len(lm.means) + 1), lm.means, lm.covs)
'''


@pytest.mark.parametrize(("cls", "words"), [("SkewMap", "not symmetric"), ("ShortIds", "ids but")])
def test_check_fails_a_broken_map_with_a_clear_message(tmp_path, cls, words):
    path = tmp_path / "broken_slam.py"
    path.write_text(textwrap.dedent(BROKEN))
    res = _by_name(conformance.run_checks(f"{path}:{cls}", load_scenario("slam_loop"), isolated=False))
    lm = res["landmarks"]
    assert not lm.passed and words in lm.message and lm.message.startswith("step ")
    assert "LandmarkMap(ids, means, covs)" in lm.advice
    assert res["runs"].passed  # one fault, one FAIL: the pose checks are untouched


def test_the_slam_template_passes_the_map_check(tmp_path, capsys):
    from beacon_sim.cli.main import main

    path = tmp_path / "my_slam.py"
    assert main(["new-filter", str(path), "--slam"]) == 0
    capsys.readouterr()
    assert callable(getattr(load_filter_class(f"{path}:MySlam"), "landmarks", None))
    res = _by_name(conformance.run_checks(f"{path}:MySlam", load_scenario("slam_loop"), isolated=False))
    assert res["landmarks"].passed, res["landmarks"].message
    assert all(r.passed for r in res.values()), [r.message for r in res.values() if not r.passed]


# -- 2. run --json: the SLAM figures -----------------------------------------------------
DIES = '''
from beacon_sim.filters.slam.ekf_slam import EKFSLAM

class Dies(EKFSLAM):
    """EKF-SLAM that raises on its 60th update (3 s)."""
    n = 0
    def update(self, measurements):
        self.n += 1
        if self.n == 60:
            raise RuntimeError("boom")
        super().update(measurements)
'''


@pytest.fixture
def slam_json(tmp_path, capsys):
    from beacon_sim.cli.main import main

    path = tmp_path / "dies.py"
    path.write_text(textwrap.dedent(DIES))

    def run(*extra):
        args = ["run", "slam_loop", "--filter", "ekf_slam", "--filter", "fastslam",
                "--filter", f"{path}:Dies", "--filter", "ekf", "--duration", "20",
                "--set", "fastslam.n_particles=20", *extra]
        assert main(args) == 0
        return capsys.readouterr().out
    return run


def test_run_json_gives_each_slam_filter_its_map_and_path_figures(slam_json):
    import json

    out = slam_json("--json")
    d = json.loads(out.splitlines()[0])
    rows = d["filters"]
    sc = load_scenario("slam_loop")
    n_beacons = len(sc.world.beacons) - len(sc.anchor_ids)
    for name in ("ekf_slam", "fastslam"):
        s = rows[name]["slam"]
        assert s["ate_m"] == pytest.approx(rows[name]["pos_rmse_m"], rel=1e-12)  # two roads, one RMS
        assert 0 < s["map_landmarks"] <= n_beacons
        paired = s["map_landmarks"] - s["map_false"]
        assert paired + s["map_missed"] == n_beacons
        # GOSPA (c = 1 m, p = 2) is at most sqrt(c^2 / 2 * (missed + false) + c^2 * paired)
        assert 0 < s["map_gospa_m"] <= np.sqrt(0.5 * (s["map_missed"] + s["map_false"]) + paired)
    ekf_slam = rows["ekf_slam"]["slam"]
    assert ekf_slam["joint_dof"] == 3 + 2 * ekf_slam["map_landmarks"]  # no tentative ones with IDs
    assert np.isfinite(ekf_slam["joint_nees"]) and ekf_slam["joint_nees"] > 0
    fastslam = rows["fastslam"]["slam"]  # joint(): the particles' means, the linearised covariance
    assert fastslam["joint_dof"] == 3 + 2 * fastslam["map_landmarks"]
    assert np.isfinite(fastslam["joint_nees"]) and fastslam["joint_nees"] > 0
    assert rows["Dies"]["failed"] and rows["Dies"]["slam"] is None  # a failed filter: no score
    assert "slam" not in rows["ekf"]  # a localization filter has no map to score


def test_run_json_slam_figures_follow_the_map_not_a_constant(slam_json):
    import json

    a = json.loads(slam_json("--json").splitlines()[0])["filters"]["ekf_slam"]["slam"]
    b = json.loads(slam_json("--json").splitlines()[0])["filters"]["ekf_slam"]["slam"]
    assert a == b  # same seed, same figures
    c = json.loads(slam_json("--json", "--seed", "7").splitlines()[0])["filters"]["ekf_slam"]["slam"]
    assert c["map_gospa_m"] != a["map_gospa_m"] and c["ate_m"] != a["ate_m"]


def test_run_text_prints_the_slam_table(slam_json):
    out = slam_json()
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("SLAM filter"))
    assert "GOSPA m" in lines[head] and "joint NEES" in lines[head]
    body = {ln.split()[0]: ln for ln in lines[head + 1:head + 4]}
    assert set(body) == {"ekf_slam", "fastslam", "Dies"}
    assert "FAILED: no score" in body["Dies"] and "n/a" not in body["fastslam"]
    assert len(body["fastslam"].split()) == 8
    assert len(body["ekf_slam"].split()) == 8  # every figure, the joint NEES and its dof


# -- 3. the HUD under unknown correspondence ----------------------------------------------
def test_ids_text_says_no_ids_instead_of_minus_one():
    from beacon_sim.app.hud import ids_text

    assert ids_text([1, 4], 0) == "  IDs 1, 4"
    assert ids_text([], 3) == "  no IDs (3 readings)"
    assert ids_text([], 1) == "  no IDs (1 reading)"
    assert ids_text([2], 2) == "  IDs 2; no IDs (2 readings)"
    assert ids_text([], 0) == "  IDs none"


def panel_texts(session, monkeypatch, png=None):
    """Every text the side panel drew for ``session`` in a 1280x800 window (never shown)."""
    import pygame

    from beacon_sim.app.hud import Hud
    from beacon_sim.app.main import App

    drawn = []
    real = Hud._blit

    def spy(self, surf, text, font, colour, at, bg=None):
        drawn.append(text)
        return real(self, surf, text, font, colour, at, bg)

    monkeypatch.setattr(Hud, "_blit", spy)
    app = App(session, (1280, 800), scripted=True)
    try:
        app.draw()
        if png is not None:
            pygame.image.save(app.screen, str(png))
    finally:
        app.close()
    return drawn


def test_the_panel_on_lookalike_beacons_says_no_ids_and_misses_none_it_saw(monkeypatch, tmp_path):
    from beacon_sim.app import association_layer
    from beacon_sim.runs.live import Session

    s = Session(load_scenario("lookalike_beacons"), ["ekf"])
    s.toggle_autopilot()
    for _ in range(40):
        s.tick()
    while not any(len(m) for m in s.readings()):  # a tick whose readings are on show
        s.tick()
    truth = association_layer.seen_by_truth(s)
    assert truth and s.seen_ids() <= {-1}  # readings without IDs, from real beacons
    texts = panel_texts(s, monkeypatch, tmp_path / "panel.png")
    assert (tmp_path / "panel.png").stat().st_size > 0
    assert not any("IDs -1" in t or "-1" in t.split("IDs", 1)[-1] for t in texts if "IDs" in t)
    rows = sum(int(np.count_nonzero(np.asarray(m.beacon_ids) == -1)) for m in s.readings())
    assert f"  no IDs ({rows} reading{'s' if rows != 1 else ''})" in texts
    assert f"beacons in view: {len(truth)}" in texts
    missed = [t for t in texts if "missed in range" in t]
    listed = {int(v) for t in missed for v in t.split(":", 1)[1].split(",")}
    assert not listed & truth  # a beacon seen without its ID is not "missed"


def test_the_panel_with_ids_still_lists_them(monkeypatch):
    from beacon_sim.runs.live import Session

    s = Session(load_scenario("default"), ["ekf"])
    s.toggle_autopilot()
    while not s.seen_ids():
        s.tick()
    texts = panel_texts(s, monkeypatch)
    assert "  IDs " + ", ".join(map(str, sorted(s.seen_ids()))) in texts
    assert not any("no IDs" in t for t in texts)


def test_a_slam_file_in_a_process_of_its_own_has_its_map_judged(tmp_path, capsys):
    from beacon_sim.cli.main import main

    path = tmp_path / "my_slam.py"
    assert main(["new-filter", str(path), "--slam"]) == 0
    assert main(["new-filter", str(tmp_path / "plain.py")]) == 0
    capsys.readouterr()
    res = _by_name(conformance.run_checks(f"{path}:MySlam", load_scenario("slam_loop")))
    # The map comes back over the pipe with each estimate and is judged here
    assert res["landmarks"].passed and "on every step" in res["landmarks"].message
    assert "--sandbox none" not in res["landmarks"].message
    plain = _by_name(conformance.run_checks(str(tmp_path / "plain.py"), load_scenario("default")))
    assert "landmarks" not in plain


def test_the_team_panel_does_not_show_minus_one_as_a_beacon(monkeypatch):
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.runs.live import Session

    team = load_team_scenario("team_sparse")
    s = Session(team, list(team.default_filters))
    for _ in range(5):
        s.tick()
    seen = {0: {-1, 3}, 1: {-1}}  # robot 0: a beacon with its ID and one without; robot 1: without
    monkeypatch.setattr(Session, "seen_ids", lambda self, i=None: seen.get(i, set()))
    texts = panel_texts(s, monkeypatch)
    assert "beacons 3; beacons without IDs" in texts and "beacons without IDs" in texts
    assert not any("-1" in t for t in texts if t.startswith("beacons"))


def test_joint_nees_without_ids_pairs_the_landmarks_as_the_ids_would():
    from beacon_sim.evaluation.slam_run import slam_figures
    from beacon_sim.runs.headless import run_headless

    res = run_headless(load_scenario("slam_loop"), ["ekf_slam"], seed=5, duration=30.0)
    told = slam_figures(res)["ekf_slam"]
    flt = res.runner.tracks["ekf_slam"].filter
    mean, cov, ids = flt.joint()
    assert len(ids) >= 4
    flt.joint = lambda: (mean, cov, tuple(-1 for _ in ids))  # the same map, its IDs hidden
    blind = slam_figures(res)["ekf_slam"]
    assert blind["joint_dof"] == told["joint_dof"] == 3 + 2 * len(ids)
    assert blind["joint_nees"] == pytest.approx(told["joint_nees"], rel=1e-9)
    # one landmark pushed beyond the cut-off from every beacon: it is marginalised out
    far = mean.copy()
    far[3:5] += 50.0
    flt.joint = lambda: (far, cov, tuple(-1 for _ in ids))
    assert slam_figures(res)["ekf_slam"]["joint_dof"] == 3 + 2 * (len(ids) - 1)


def test_run_on_slam_without_ids_gives_a_joint_nees(tmp_path, capsys):
    import json

    from beacon_sim.cli.main import main
    from beacon_sim.core.resources import scenario_dir

    text = (scenario_dir() / "slam_loop.toml").read_text()
    assert 'kind = "range_bearing"\n' in text
    path = tmp_path / "slam_noids.toml"
    path.write_text(text.replace('kind = "range_bearing"\n',
                                 'kind = "range_bearing"\ncorrespondence = "unknown"\n'))
    assert main(["run", str(path), "--filter", "ekf_slam", "--duration", "30", "--json"]) == 0
    s = json.loads(capsys.readouterr().out.splitlines()[0])["filters"]["ekf_slam"]["slam"]
    assert s["joint_nees"] is not None and s["joint_nees"] > 0
    assert s["joint_dof"] % 2 == 1 and 5 <= s["joint_dof"] <= 3 + 2 * 12
