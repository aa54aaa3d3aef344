"""Unknown correspondence wired in: the scenario keys and their errors, the
simulation hiding IDs (truth kept aside, other streams untouched), each filter's association
hook (a no-op with known IDs, the known update when the answer is forced), the metrics, and
the look-alike lesson: on ``lookalike_beacons`` the EKF locks one door off, the particle filter
keeps both places and ends at the right one."""

import math
from dataclasses import replace

import numpy as np
import pytest
from helpers import make_scenario
from portable_checksums import TICKS, documented_checksums

from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.evaluation.association_metrics import (
    AssociationScore,
    association_scores,
    format_scores,
    with_known_correspondence,
)
from beacon_sim.filters import association as assoc
from beacon_sim.filters.base import FilterError
from beacon_sim.hosting.loading import build_filter

UNKNOWN_SENSOR = {"name": "rb", "kind": "range_bearing", "max_range": 6.0, "range_std": 0.1,
                  "bearing_std": 0.05, "correspondence": "unknown", "clutter_rate": 0.5}

# Truth and readings checksums of the shipped scenarios with known IDs after 300 ticks (the
# table of docs/portability.md): a sensor's new keys (with their defaults) must not move a
# single draw.
SHIPPED_CHECKSUMS = {name: sums for name, sums in documented_checksums().items()
                     if name in ("assignment_kf", "default", "global_kidnap", "krejsa_bearing_only",
                                 "sparse_kidnap", "ulps_circle")}
assert TICKS == 300 and len(SHIPPED_CHECKSUMS) == 6


def unknown_scenario(**sensor):
    return make_scenario(sensors=[{**UNKNOWN_SENSOR, **sensor}])


# -- the scenario keys -----------------------------------------------------------------------
def test_the_keys_default_to_known_and_no_clutter():
    s = make_scenario().sensors[0]
    assert (s.correspondence, s.clutter_rate) == ("known", 0.0)
    u = unknown_scenario().sensors[0]
    assert (u.correspondence, u.clutter_rate) == ("unknown", 0.5)
    # the filters are told the same (their sensors are the model's)
    assert unknown_scenario().model_sensors[0].correspondence == "unknown"


@pytest.mark.parametrize(("sensor", "message"), [
    ({"correspondence": "maybe"},
     r"sensors\[0\]\.correspondence = 'maybe': expected one of 'known', 'unknown'"),
    ({"correspondence": "known", "clutter_rate": 0.5},
     r"sensors\[0\]\.clutter_rate = 0\.5: expected 0 unless"),
    ({"clutter_rate": -1.0}, r"sensors\[0\]\.clutter_rate = -1\.0: expected a number in \[0, 5\]"),
    ({"clutter_rate": "lots"}, r"sensors\[0\]\.clutter_rate = 'lots': expected a number"),
    ({"max_range": math.inf},
     r"sensors\[0\]\.max_range = inf: expected a finite range when clutter_rate > 0"),
    ({"kind": "pose"}, r"sensors\[0\]\.correspondence = 'unknown': expected 'known' for a pose fix"),
    ({"corespondence": "unknown", "correspondence": "known", "clutter_rate": 0.0},
     r"unknown key 'sensors\[0\]\.corespondence' \(did you mean 'sensors\[0\]\.correspondence'\?\)"),
])
def test_bad_values_name_the_file_the_key_and_what_was_expected(sensor, message):
    with pytest.raises(ScenarioError, match=r"^<test>: " + message):
        unknown_scenario(**sensor)


def test_a_bad_key_in_a_file_exits_2_with_one_line(tmp_path, capsys):
    from beacon_sim.cli.main import main

    text = load_scenario("lookalike_beacons").source
    bad = tmp_path / "bad.toml"
    bad.write_text(open(text).read().replace('correspondence = "unknown"', 'correspondence = "unkown"'))
    assert main(["run", str(bad), "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.toml" in err and "correspondence = 'unkown'" in err \
        and "did you mean 'unknown'" in err


# -- the simulation ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SHIPPED_CHECKSUMS))
def test_shipped_scenarios_keep_their_truth_and_readings(name):
    sim = Simulation(load_scenario(name))
    for _ in range(300):
        step = sim.step()
        assert step.true_ids == {}  # known correspondence: nothing kept aside
    assert (sim.truth_checksum, sim.readings_checksum) == SHIPPED_CHECKSUMS[name]


def test_hidden_ids_keep_the_truth_aside_and_move_no_other_stream():
    sc = unknown_scenario()
    known = with_known_correspondence(sc)
    a, b = Simulation(sc, 5), Simulation(known, 5)
    clutter = rows = 0
    for _ in range(200):
        sa, sb = a.step(), b.step()
        np.testing.assert_array_equal(sa.true_pose, sb.true_pose)
        (ma,), (mb,) = sa.measurements, sb.measurements
        assert np.all(ma.beacon_ids == UNKNOWN_ID)
        truth = sa.true_ids["rb"]
        assert truth.shape == (len(ma),)
        # the rows that came from a beacon are the known run's readings, in another order
        real = truth >= 0
        order = np.argsort(truth[real])
        np.testing.assert_array_equal(truth[real][order], np.sort(mb.beacon_ids))
        np.testing.assert_array_equal(ma.z[real][order], mb.z[np.argsort(mb.beacon_ids)])
        z = ma.z[~real]
        assert np.all((z[:, 0] >= 0) & (z[:, 0] <= 6.0)) and np.all(np.abs(z[:, 1]) <= math.pi)
        clutter += int(np.sum(~real))
        rows += len(ma)
    assert a.truth_checksum == b.truth_checksum
    assert 60 < clutter < 140  # Poisson(0.5) per reading over 200 readings: 100 +- 10
    again = Simulation(sc, 5)
    for _ in range(200):
        again.step()
    assert again.readings_checksum == a.readings_checksum  # same seed, same run bit for bit


def test_the_filters_never_see_the_truth_of_hidden_readings():
    step = Simulation(unknown_scenario(), 1).step()
    assert step.true_ids and all(np.all(m.beacon_ids == UNKNOWN_ID) for m in step.measurements)


# -- the filters --------------------------------------------------------------------------------
def run_filter(flt, sim, ticks):
    out = []
    for _ in range(ticks):
        step = sim.step()
        flt.predict(step.control, step.dt)
        flt.update(step.measurements)
        out.append(np.concatenate([flt.estimate()[0], flt.estimate()[1].ravel()]))
    return np.array(out)


@pytest.mark.parametrize("name", ["ekf", "ukf", "pf", "histogram"])
def test_known_correspondence_is_bit_for_bit_what_it_was_without_the_hooks(name, monkeypatch):
    sc = load_scenario("default")
    params = {"n_particles": 300} if name == "pf" else {"cell": 0.4} if name == "histogram" else None
    with_hooks = run_filter(build_filter(name, sc, 3, params=params), Simulation(sc, 3), 80)
    monkeypatch.setattr(assoc, "associate_gaussian", lambda flt, ms: ms)
    monkeypatch.setattr(assoc, "is_unlabeled", lambda m: False)
    monkeypatch.setattr(assoc, "particle_start", lambda flt: None)
    monkeypatch.setattr(assoc, "grid_mixture", lambda flt, ms, c, s: (list(ms), None))
    without = run_filter(build_filter(name, sc, 3, params=params), Simulation(sc, 3), 80)
    np.testing.assert_array_equal(with_hooks, without)


def one_beacon(sc):
    """``sc`` with only its first beacon: an unlabeled reading can only be that one."""
    return replace(sc, world=World(sc.world.bounds, sc.world.beacons[:1]))


@pytest.mark.parametrize("name", ["ekf", "ukf"])
@pytest.mark.parametrize("method", ["nn", "jcbb"])
def test_gaussian_filters_with_one_beacon_update_exactly_as_with_its_id(name, method):
    sc = one_beacon(unknown_scenario(clutter_rate=0.0))
    # a gate that passes every true reading (at 0.99 one in a hundred is dropped as clutter)
    u = build_filter(name, sc, 0, params={"association": method, "association_prob": 1 - 1e-12})
    k = build_filter(name, with_known_correspondence(sc), 0)
    a, b = Simulation(sc, 0), Simulation(with_known_correspondence(sc), 0)
    for _ in range(60):
        sa, sb = a.step(), b.step()
        for f, s in ((u, sa), (k, sb)):
            f.predict(s.control, s.dt)
            f.update(s.measurements)
        np.testing.assert_array_equal(u.estimate()[0], k.estimate()[0])
        np.testing.assert_array_equal(u.estimate()[1], k.estimate()[1])
        if sa.measurements:
            assert u.associations() == {"rb": (1,)}


def test_the_histogram_mixture_with_one_beacon_is_the_known_update_up_to_clutter():
    sc = one_beacon(unknown_scenario(clutter_rate=0.0))
    params = {"cell": 0.5, "heading_bins": 18}
    u = build_filter("histogram", sc, 0, params=params)
    k = build_filter("histogram", with_known_correspondence(sc), 0, params=params)
    a, b = Simulation(sc, 0), Simulation(with_known_correspondence(sc), 0)
    for _ in range(40):
        sa, sb = a.step(), b.step()
        for f, s in ((u, sa), (k, sb)):
            f.predict(s.control, s.dt)
            f.update(s.measurements)
    # the only difference is the 1 % clutter share of the mixture, 40 times
    assert np.max(np.abs(u.grid - k.grid)) < 0.05 * np.max(k.grid)
    assert np.linalg.norm(u.estimate()[0][:2] - k.estimate()[0][:2]) < 0.02
    assert u.associations() == {"rb": (1,)}


def test_a_gaussian_reading_outside_every_gate_is_dropped_as_clutter():
    sc = unknown_scenario(clutter_rate=0.0)
    f = build_filter("ekf", sc, 0)
    mean0, cov0 = f.estimate()
    far = Measurement("rb", "range_bearing", np.array([[0.3, 2.0]]), np.array([UNKNOWN_ID]))
    f.update([far])  # no beacon is 0.3 m away: nothing to update with
    assert f.associations() == {"rb": (None,)}
    np.testing.assert_array_equal(f.estimate()[0], mean0)
    np.testing.assert_array_equal(f.estimate()[1], cov0)


def test_a_bad_association_parameter_is_one_line():
    with pytest.raises(FilterError, match="association = 'hungarian': expected one of 'nn', 'jcbb'"):
        build_filter("ekf", unknown_scenario(), 0, params={"association": "hungarian"})
    with pytest.raises(FilterError, match=r"association_prob = 1\.5"):
        build_filter("ukf", unknown_scenario(), 0, params={"association_prob": 1.5})


def test_bad_ambiguity_and_inflation_parameters_are_one_line():
    with pytest.raises(FilterError, match=r"unambiguous_share = 1\.0: expected a share in \[0, 1\)"):
        build_filter("ekf", unknown_scenario(), 0, params={"unambiguous_share": 1.0})
    with pytest.raises(FilterError, match=r"association_inflation = 0\.5: expected a number >= 1"):
        build_filter("ukf", unknown_scenario(), 0, params={"association_inflation": 0.5})


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_an_ambiguous_reading_is_refused_with_a_share_and_given_the_nearest_without(name):
    """The belief's heading uncertain by 0.3 rad; a reading whose bearing lies between two
    beacons 0.4 rad apart (distinguishable by the sensor's 0.02 rad bearing, but both in the
    gate): with ``unambiguous_share`` it is dropped (the estimate unchanged), without it the
    nearest takes it. A reading one beacon alone fits is kept either way."""
    from beacon_sim.core.sensors import SensorNoise
    from beacon_sim.core.types import Beacon

    sc = unknown_scenario(clutter_rate=0.0)
    x0, y0, th0 = sc.initial_pose
    beacons = tuple(Beacon(i + 1, x0 + 4 * math.cos(th0 + a), y0 + 4 * math.sin(th0 + a))
                    for i, a in enumerate((0.2, -0.2, 1.8)))
    sensors = tuple(replace(s, noise=SensorNoise(range_std=0.3, bearing_std=0.02)) for s in sc.sensors)
    sc = replace(sc, world=World(sc.world.bounds, beacons), sensors=sensors, model_sensors=sensors,
                 initial_belief=replace(sc.initial_belief, std=(0.05, 0.05, 0.3)))
    between = Measurement("rb", "range_bearing", np.array([[4.0, 0.01]]), np.array([UNKNOWN_ID]))
    alone = Measurement("rb", "range_bearing", np.array([[4.0, 1.75]]), np.array([UNKNOWN_ID]))
    for share, want in ((0.8, (None,)), (0.0, (1,))):
        f = build_filter(name, sc, 0, params={"unambiguous_share": share})
        mean0 = f.estimate()[0].copy()
        f.update([between])
        assert f.associations() == {"rb": want}, share
        assert np.array_equal(f.estimate()[0], mean0) == (want == (None,))
        f = build_filter(name, sc, 0, params={"unambiguous_share": share})
        f.update([alone])
        assert f.associations() == {"rb": (3,)}


def test_unknown_correspondence_is_not_batched():
    f = build_filter("ekf", unknown_scenario(), 0)
    assert "unknown correspondence" in f.batch_blocker
    assert build_filter("ekf", make_scenario(), 0).batch_blocker is None


def test_the_particle_report_is_the_weighted_vote_of_the_particles():
    sc = unknown_scenario(clutter_rate=0.0)
    f = build_filter("pf", sc, 0, params={"n_particles": 400})
    step = Simulation(sc, 0).step()
    f.predict(step.control, step.dt)
    f.update(step.measurements)
    choices = f._association.choices["rb"]
    w = f.weights()
    report = f.associations()["rb"]
    for i, given in enumerate(report):
        votes = {int(j): float(w[choices[:, i] == j].sum()) for j in np.unique(choices[:, i])}
        best = max(votes, key=votes.get)
        assert given == (None if best < 0 else int(sc.world.beacon_ids[best]))
    # and near the truth the particles agree with it
    assert list(report) == step.true_ids["rb"].tolist()



def test_the_particle_report_names_every_unlabeled_sensor_of_the_update():
    """Two sensors with hidden IDs read in one update: the report holds both, each row
    given a beacon or clutter (the filter keeps one wiring for the whole update)."""
    sc = make_scenario(sensors=[{**UNKNOWN_SENSOR, "clutter_rate": 0.0},
                                {**UNKNOWN_SENSOR, "name": "rb2", "clutter_rate": 0.0}])
    f = build_filter("pf", sc, 0, params={"n_particles": 400})
    step = Simulation(sc, 0).step()
    assert {m.sensor for m in step.measurements} == {"rb", "rb2"}
    f.predict(step.control, step.dt)
    f.update(step.measurements)
    report = f.associations()
    assert set(report) == {"rb", "rb2"}
    for sensor in ("rb", "rb2"):
        assert list(report[sensor]) == step.true_ids[sensor].tolist()


# -- metrics ------------------------------------------------------------------------------------
def test_a_score_counts_correct_false_and_missed_rows():
    s = AssociationScore()
    s.add((3, None, 4, None, 5), np.array([3, -1, 5, 2, -1]))
    assert (s.readings, s.correct, s.false, s.missed, s.clutter) == (5, 2, 2, 1, 2)
    assert s.fraction_correct == pytest.approx(0.4)


def test_metrics_on_a_benign_scenario_ekf_and_pf_associate_almost_everything():
    sc = unknown_scenario(clutter_rate=0.3)
    scores = association_scores(sc, ["ekf", "pf"], seed=2, duration=15.0,
                                params={"pf": {"n_particles": 500}})
    for name, s in scores.items():
        assert s.failed is None and s.readings > 300, name
        assert s.fraction_correct > 0.95, (name, s)
        assert s.clutter > 20
        assert abs(s.rmse_cost) < 0.05, (name, s)  # association costs almost nothing here
    assert "ekf" in format_scores(scores)


# -- the look-alike lesson ---------------------------------------------------------------------
@pytest.mark.slow
def test_lookalike_beacons_the_ekf_locks_one_door_off_the_pf_keeps_both_and_ends_right():
    sc = load_scenario("lookalike_beacons")
    ekf = build_filter("ekf", sc, sc.seed)
    pf = build_filter("pf", sc, sc.seed)
    sim = Simulation(sc, sc.seed)
    bimodal_at = []
    for _ in range(round(sc.duration / sc.dt)):
        step = sim.step()
        for f in (ekf, pf):
            f.predict(step.control, step.dt)
            f.update(step.measurements)
        x = step.true_pose[0]
        if step.time < 19.0:  # before the odd beacon comes into range
            b = pf.belief()
            near = b.weights[np.abs(b.poses[:, 0] - x) < 0.7].sum()
            door_off = b.weights[np.abs(b.poses[:, 0] - (x + 2.0)) < 0.7].sum()
            bimodal_at.append(near > 0.05 and door_off > 0.05)
            # the EKF is one door (2 m) ahead from the first seconds on, and sure of it
            if step.time > 3.0:
                mean, cov = ekf.estimate()
                assert abs(mean[0] - x - 2.0) < 0.3 and math.sqrt(cov[0, 0]) < 0.1
    assert np.mean(bimodal_at) > 0.9  # both places kept, nearly all the time
    mean, cov = ekf.estimate()
    assert abs(mean[0] - step.true_pose[0] - 2.0) < 0.3  # still one door off at the end
    mean, _ = pf.estimate()
    assert np.hypot(*(mean[:2] - step.true_pose[:2])) < 0.2  # the odd beacon told them apart


def test_run_associations_prints_the_table_or_puts_it_in_the_json(capsys):
    import json

    from beacon_sim.cli.main import main

    assert main(["run", "lookalike_beacons", "--filter", "ekf", "--duration", "5", "--associations"]) == 0
    out = capsys.readouterr().out
    header = next(line for line in out.splitlines() if line.startswith("association"))
    assert header.split()[1:4] == ["readings", "correct", "false"]
    assert main(["run", "lookalike_beacons", "--filter", "ekf", "--duration", "5", "--associations",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    ekf = data["associations"]["ekf"]
    assert ekf["readings"] == ekf["correct"] + ekf["false"] + ekf["missed"] > 0
    assert ekf["rmse_cost_m"] > 1.0  # one door off
    assert main(["run", "default", "--filter", "ekf", "--duration", "1", "--associations"]) == 0
    assert "nothing to score" in capsys.readouterr().out
