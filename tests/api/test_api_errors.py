"""One error vocabulary: the Python API and the Gymnasium env check their arguments and raise
the project's errors (a BeaconSimError, which is a ValueError; a wrong type also a
TypeError), each naming the parameter in one line; step() before reset() is Gymnasium's
ResetNeeded too. Bounded work is refused the same way from Python as from the command line."""

from __future__ import annotations

import gymnasium
import pytest

import beacon_sim as bs
from beacon_sim.core.scenario import ScenarioError
from beacon_sim.errors import ArgumentTypeError, BeaconSimError, UsageError, short_repr
from beacon_sim.gym import BeaconEnv


@pytest.fixture(scope="module")
def short_run():
    return bs.run("default", ["ekf"], duration=1.0)


@pytest.mark.parametrize("call, error, words", [
    (lambda: bs.load_scenario("default", changes=[1]), ArgumentTypeError, "changes=[1]: expected a dict"),
    (lambda: bs.load_scenario("default", changes={"sensors.x.max_range": 1}), ScenarioError,
     "changes: sensors.x.max_range: sensors is an array of 1 entries: expected an index from 0 to 0, "
     "got 'x'"),
    (lambda: bs.load_scenario("default", changes={"sensors.99.max_range": 1}), ScenarioError,
     "got '99'"),
    (lambda: bs.load_scenario("default", changes={"duration.x": 1}), ScenarioError,
     "changes: duration.x: duration is a value (120.0), not a table"),
    (lambda: bs.load_scenario("default", changes={5: 1}), ScenarioError,
     "changes: key 5: expected a dotted key"),
    (lambda: bs.load_scenario(5), ArgumentTypeError, "name_or_path=5: expected a name or a path"),
    (lambda: bs.run(scenario=5), ArgumentTypeError, "scenario=5: expected a name or a path"),
    (lambda: bs.run("default", 5, duration=1), ArgumentTypeError, "filters=5: expected a list"),
    (lambda: bs.replay(5), ArgumentTypeError, "recording=5: expected a name or a path"),
    (lambda: bs.load_scenario("lookalike_beacons", changes={"sensors.0.clutter_rate": 100}), ScenarioError,
     "clutter_rate = 100: expected a number in [0, 5]"),
])
def test_the_api_raises_its_own_errors_naming_the_parameter(call, error, words):
    with pytest.raises(error) as info:
        call()
    assert isinstance(info.value, BeaconSimError) and isinstance(info.value, ValueError)
    assert words in str(info.value) and "\n" not in str(info.value)
    if error is ArgumentTypeError:
        assert isinstance(info.value, TypeError)


def test_errors_of_an_unknown_filter_names_the_filters(short_run):
    with pytest.raises(UsageError, match=r"name='bogus': not a filter of this run \(its filters: ekf\)"):
        short_run.errors("bogus")
    assert short_run.errors("ekf").shape == (20, 3)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"render_mode": "bogus"}, UsageError, "render_mode='bogus': expected None or one of"),
    ({"filters": []}, UsageError, "filters=[]: expected at least one filter"),
    ({"filters": "ekf"}, ArgumentTypeError, "filters='ekf': expected a list of filter names"),
    ({"ticks_per_step": 0}, UsageError, "ticks_per_step=0: expected a whole number from 1 to 10,000"),
    ({"ticks_per_step": -3}, UsageError, "ticks_per_step=-3"),
    ({"ticks_per_step": 10**9}, UsageError, "ticks_per_step=1000000000"),
    ({"ticks_per_step": 2.5}, ArgumentTypeError, "ticks_per_step=2.5"),
    ({"max_steps": 0}, UsageError, "max_steps=0"),
    ({"scenario": 5}, ArgumentTypeError, "scenario=5: expected a Scenario, a name or a path"),
])
def test_the_gym_env_checks_its_arguments(kwargs, error, words):
    with pytest.raises(error) as info:
        BeaconEnv(**kwargs)
    assert words in str(info.value)


def test_the_gym_env_checks_reset_and_step():
    env = BeaconEnv()
    with pytest.raises(gymnasium.error.ResetNeeded) as info:
        env.step([0.0, 0.0])
    assert isinstance(info.value, UsageError) and "step() before reset()" in str(info.value)
    with pytest.raises(UsageError, match=r"seed=-1: expected a seed from 0 to 2\^63 - 1"):
        env.reset(seed=-1)
    with pytest.raises(ArgumentTypeError, match=r"options=5"):
        env.reset(seed=1, options=5)
    env.reset(seed=1)
    with pytest.raises(UsageError, match=r"action \[<a 1329-bit int>|action \[1000"):
        env.step([10**400, 0])
    obs, *_ = env.step([0.1, 0.0])  # a bad action changes nothing: the episode goes on
    assert env.steps_taken == 1 and obs.shape == env.observation_space.shape


def test_short_repr_keeps_messages_one_short_line():
    assert short_repr(10**400) == "<a 1329-bit int>"
    assert len(short_repr("x" * 1000)) == 60
    assert short_repr(True) == "True"
