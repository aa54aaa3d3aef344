"""The conformance checker: every built-in filter passes; broken filters are caught."""

import importlib.util

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting.conformance import run_checks
from beacon_sim.hosting.loading import BUILTIN_FILTERS

BUILTINS = [n for n, t in BUILTIN_FILTERS.items() if importlib.util.find_spec(t.split(":")[0])]

GOOD = '''
import numpy as np
from beacon_sim.core.motion import move
from beacon_sim.filters.base import FilterBase

class {name}(FilterBase):
    def reset(self, initial):
        self.mean = np.array([5.0, 5.0, 0.0]) if initial is None else np.array(initial.mean)
        self.cov = np.eye(3) * 0.01
    def predict(self, control, dt):
        self.mean = move(self.mean, control.v, control.omega, dt)
        {extra_predict}
    def update(self, measurements):
        {extra_update}
    def estimate(self):
        return {estimate}
'''


def write_filter(tmp_path, name="Student", extra_predict="pass", extra_update="pass",
                 estimate="self.mean.copy(), self.cov.copy()"):
    path = tmp_path / f"{name.lower()}.py"
    path.write_text(GOOD.format(name=name, extra_predict=extra_predict, extra_update=extra_update,
                                estimate=estimate))
    return f"{path}:{name}"


def failed(results):
    return {r.name for r in results if not r.passed}


@pytest.fixture(scope="module")
def default():
    return load_scenario("default")


@pytest.mark.parametrize("spec", BUILTINS)
def test_every_builtin_filter_passes(spec, default):
    results = run_checks(spec, default)
    assert not failed(results), [(r.name, r.message) for r in results if not r.passed]


def test_kf_is_checked_on_a_scenario_with_a_pose_fix(default):
    results = run_checks("kf", default)
    note = [r for r in results if r.name == "scenario"]
    assert note and "assignment_kf" in note[0].message


def test_a_correct_student_filter_passes(tmp_path, default):
    assert not failed(run_checks(write_filter(tmp_path), default))


def test_global_np_random_is_rejected(tmp_path, default):
    spec = write_filter(tmp_path, "Noisy",
                        extra_update="self.mean = self.mean + np.random.normal(0, 1e-3, 3)")
    results = run_checks(spec, default)
    bad = failed(results)
    assert "no global RNG" in bad and "deterministic" in bad
    advice = next(r.advice for r in results if r.name == "no global RNG")
    assert "ctx.rng" in advice


def test_global_draw_without_effect_is_still_rejected(tmp_path, default):
    spec = write_filter(tmp_path, "Sneaky", extra_update="np.random.random()")
    assert failed(run_checks(spec, default)) == {"no global RNG"}


def test_ctx_rng_is_allowed(tmp_path, default):
    # (the heading wrapped again after the draw: check's runs are a grade's, 60 s long, and
    # pass by +-pi, where a draw would leave it just outside [-pi, pi))
    spec = write_filter(tmp_path, "Honest",
                        extra_update="self.mean = self.mean + self.ctx.rng.normal(0, 1e-6, 3)\n"
                                     "        self.mean[2] = (self.mean[2] + np.pi) % (2 * np.pi) - np.pi")
    assert not failed(run_checks(spec, default))


def test_unwrapped_heading_and_bad_covariance_are_reported(tmp_path, default):
    spec = write_filter(tmp_path, "Spinner", extra_predict="self.mean[2] += 0.5; self.cov[0, 1] = 1.0")
    bad = failed(run_checks(spec, default))
    assert {"heading wrapped", "symmetric covariance"} <= bad


def test_wrong_shapes_and_nan_are_reported(tmp_path, default):
    assert "shapes" in failed(run_checks(write_filter(tmp_path, "Flat", estimate="self.mean[:2], self.cov"),
                                         default))
    spec = write_filter(tmp_path, "Nan", extra_update="self.cov = self.cov * np.nan")
    assert "finite" in failed(run_checks(spec, default))


def test_crashing_update_is_reported_with_advice(tmp_path, default):
    spec = write_filter(tmp_path, "Crash", extra_update="raise RuntimeError('boom')")
    results = run_checks(spec, default)
    r = next(r for r in results if r.name == "runs")
    assert not r.passed and "boom" in r.message and r.advice


def test_global_rng_state_is_restored(default):
    np.random.seed(99)
    before = np.random.get_state()[1].copy()
    run_checks("ekf", default)
    assert np.array_equal(np.random.get_state()[1], before)


def test_cli_check_exit_status(tmp_path, capsys):
    assert main(["check", "ekf"]) == 0
    out = capsys.readouterr().out
    assert "PASS" in out and "deterministic" in out
    spec = write_filter(tmp_path, "Noisy", extra_update="np.random.random()")
    assert main(["check", spec]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "what to fix" in out


FAULTS = {  # one injected fault -> the one check that must fail
    "nan": (dict(extra_update="self.mean = self.mean * np.nan if self.cov[0, 0] > 0.011 else self.mean\n"
                 "        self.cov = self.cov + 0.0001"), "finite"),
    "raise": (dict(extra_update="self.k = getattr(self, 'k', 0) + 1\n"
                   "        if self.k == 5: raise KeyError('k')"), "runs"),
    "notpsd": (dict(estimate="self.mean.copy(), np.diag([0.1, -0.2, 0.1])"),
               "positive semi-definite covariance"),
    "asym": (dict(estimate="self.mean.copy(), self.cov + np.triu(np.full((3, 3), 0.001), 1)"),
             "symmetric covariance"),
    "shape": (dict(estimate="self.mean[:2].copy(), self.cov.copy()"), "shapes"),
    "heading": (dict(extra_predict="self.mean[2] += 7.0"), "heading wrapped"),
    "rng": (dict(extra_predict="self.mean[0] += 0.001 * np.random.normal()"), None),
    "empty": (dict(extra_update="if not measurements: raise IndexError('empty')"), "empty update"),
    "loop": (dict(extra_update="self.k = getattr(self, 'k', 0) + 1\n"
                  "        while self.k == 3: pass"), "runs"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_one_injected_fault_gives_exactly_one_fail(fault, tmp_path, default, monkeypatch):
    from beacon_sim.hosting import conformance

    monkeypatch.setattr(conformance, "RUN_LIMIT_S", 0.5)
    kwargs, check = FAULTS[fault]
    results = run_checks(write_filter(tmp_path, **kwargs), default)
    bad = failed(results)
    if fault == "rng":  # the global RNG: drawing from it is the fault; it also changes the
        assert bad == {"deterministic", "no global RNG"}  # estimates with the seed: two views
    else:
        assert bad == {check}, [(r.name, r.message) for r in results if not r.passed]
    if fault == "empty":
        assert bad == {"empty update"}


def test_non_symmetric_negative_definite_fails_the_psd_check_too(tmp_path, default):
    spec = write_filter(tmp_path, estimate="self.mean.copy(), -np.eye(3) + np.triu(np.ones((3, 3)), 1)")
    assert failed(run_checks(spec, default)) == {"symmetric covariance",
                                                   "positive semi-definite covariance"}


def test_check_prints_the_cost_beside_the_ekf(tmp_path, capsys):
    assert main(["check", write_filter(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "cost" in out and "us per step" in out and "the built-in ekf" in out


# The small checks, each asked on its own (hosting/check_verdicts.py; run_checks is the list of
# them in order).

def _pair(theta=0.0, cov=None):
    return np.array([1.0, 2.0, theta]), np.eye(3) * 0.01 if cov is None else cov


def test_value_checks_each_answer_their_own_question():
    from beacon_sim.hosting import check_verdicts as c

    ests = [_pair(), _pair(theta=4.0), _pair(cov=np.diag([0.1, -0.2, 0.1])), _pair()]
    problems = c.estimate_problems([], ests)
    verdicts = {r.name: r.passed for r in (c.check_shapes(problems), c.check_finite(problems),
                                           c.check_covariance_symmetric(problems),
                                           c.check_covariance_psd(problems),
                                           c.check_heading_wrapped(problems))}
    assert verdicts == {"shapes": True, "finite": True, "symmetric covariance": True,
                        "positive semi-definite covariance": False, "heading wrapped": False}
    heading = c.check_heading_wrapped(problems)
    assert heading.message.startswith("step 2:") and "angles.wrap" in heading.advice
    assert c.check_covariance_psd(problems).message.startswith("step 3:")
    assert c.check_finite(problems).advice == ""  # advice only for a failure


def test_a_bad_estimate_after_reset_is_named_so():
    from beacon_sim.hosting import check_verdicts as c

    flat = (np.zeros(2), np.eye(3))
    assert c.check_shapes(c.estimate_problems([flat], [_pair()])).message.startswith("after reset:")
    assert c.check_shapes(c.estimate_problems([], [_pair(), flat])).message.startswith("step 2:")


def test_determinism_and_global_rng_checks_read_one_trial():
    from beacon_sim.hosting import check_verdicts as c

    same = c.FedSteps([_pair(), _pair()], None, 0)
    moved = c.FedSteps([_pair(), _pair(theta=0.1)], None, 0)
    assert c.check_determinism(c.RngTrial(same, same, False, False)).passed
    r = c.check_determinism(c.RngTrial(same, moved, False, False))
    assert not r.passed and "from step 2" in r.message
    short = c.FedSteps([_pair()], (2, "KeyError: 'k'"), 0)
    assert "from step 2" in c.check_determinism(c.RngTrial(same, short, False, False)).message
    assert c.check_global_rng(c.RngTrial(same, same, False, False)).passed
    py_only = c.check_global_rng(c.RngTrial(same, same, False, True))
    assert not py_only.passed and py_only.message.endswith("global random generator")
    assert "np.random" in c.check_global_rng(c.RngTrial(same, same, True, False)).message


def test_empty_update_check_tells_spoilt_from_moved_from_raised():
    from beacon_sim.hosting import check_verdicts as c

    nan = (np.full(3, np.nan), np.eye(3))
    assert not c.check_empty_update(c.EmptyTrial(_pair(), nan, None, None)).passed
    moved = c.check_empty_update(c.EmptyTrial(_pair(), _pair(theta=0.2), None, None))
    assert moved.passed and moved.message == "accepted; the mean moved"
    raised = c.check_empty_update(c.EmptyTrial(_pair(), None, "IndexError: empty", None))
    assert not raised.passed and raised.message == "IndexError: empty"
    assert c.check_empty_update(c.EmptyTrial(None, None, None, "RuntimeError: x")).passed


def test_run_checks_gives_the_checks_in_their_order(default):
    names = [r.name for r in run_checks("ekf", default)]
    assert names == ["loads", "interface", "constructs", "runs", "shapes", "finite",
                     "symmetric covariance", "positive semi-definite covariance",
                     "heading wrapped", "belief", "empty update", "deterministic",
                     "no global RNG", "cost"]


def test_a_filter_that_never_ran_a_step_is_not_said_to_pass_anything_it_was_not_asked(tmp_path, default,
                                                                                       capsys):
    """``check`` used to print 13 of 14 PASS and "cost 0.0 us" for a filter whose every
    step raised: the checks after "runs" had nothing to judge. Now each says so and is
    marked SKIP, the cost is a NOTE with no figure, and the tally counts neither as passed."""
    spec = write_filter(tmp_path, "Dead", extra_predict="raise KeyError('x')")
    results = {r.name: r for r in run_checks(spec, default, seeds=[1])}
    assert not results["runs"].passed and "KeyError" in results["runs"].message
    after = ("shapes", "finite", "symmetric covariance", "positive semi-definite covariance",
             "heading wrapped", "belief", "empty update", "deterministic", "no global RNG")
    for name in after:
        assert results[name].message.startswith("not judged"), (name, results[name].message)
        assert results[name].mark == "SKIP", name
    assert results["cost"].message == "no step ran: no cost to report" and results["cost"].mark == "NOTE"
    assert main(["check", spec]) == 1
    out = capsys.readouterr().out
    assert "PASS  " + "shapes" not in out and "0.0 us" not in out
    marks = [line.split()[0] for line in out.splitlines()[1:15]]
    assert marks.count("PASS") == 3  # loads, interface, constructs
    assert f"3 of 13 checks passed; {len(after)} not judged" in out


def test_a_slam_filters_cost_is_set_beside_a_slam_filter_not_the_ekf():
    """A SLAM filter maps as it goes: its cost is not that of a localization EKF's task, so
    check sets it beside the built-in EKF-SLAM's on the same steps, not the ekf's ("67.3x")."""
    results = {r.name: r for r in run_checks("ekf_slam", load_scenario("slam_loop"), isolated=False,
                                             seeds=[1])}
    cost = results["cost"].message
    assert "us per step" in cost and "the built-in ekf_slam:" in cost and "the built-in ekf:" not in cost


def test_the_cost_peer_is_of_the_filters_own_kind():
    from beacon_sim.hosting.check_verdicts import cost_peer

    assert cost_peer(load_scenario("default")) == "ekf"
    assert cost_peer(load_scenario("default"), mapping=True) == "ekf_slam"
    assert cost_peer(load_scenario("slam_loop")) == "ekf_slam"
    assert cost_peer(load_scenario("corridor")) == "mcl"


