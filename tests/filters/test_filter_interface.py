"""The filter interface: loading by name, module path and file path; the runner; the JSON run."""

import json

import numpy as np
import pytest
from helpers import make_scenario

from beacon_sim.cli.main import main
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.base import Filter, FilterError
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.gaussian.ukf import UnscentedKalmanFilter
from beacon_sim.hosting.loading import FilterLoadError, build_filter, load_filter_class
from beacon_sim.hosting.runner import FilterRunner

FILE_FILTER = '''
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

class MyEKF(ExtendedKalmanFilter):
    """An EKF under another name, loaded from a file."""
'''


def test_builtin_module_and_file_names_resolve(tmp_path):
    assert load_filter_class("ekf") is ExtendedKalmanFilter
    assert load_filter_class("beacon_sim.filters.gaussian.ukf:UnscentedKalmanFilter") is UnscentedKalmanFilter
    path = tmp_path / "my_filter.py"
    path.write_text(FILE_FILTER)
    cls = load_filter_class(f"{path}:MyEKF")
    assert issubclass(cls, ExtendedKalmanFilter) and cls.__name__ == "MyEKF"


@pytest.mark.parametrize("spec, words", [
    ("ekff", "unknown filter"),
    ("beacon_sim.filters.nothing:X", "cannot import"),
    ("beacon_sim.filters.gaussian.ekf:Nope", "no class 'Nope'"),
    ("missing_file.py:X", "no such filter file"),
])
def test_bad_names_give_one_line_errors(spec, words):
    with pytest.raises(FilterLoadError) as exc:
        load_filter_class(spec)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_parameters_merge_and_unknown_ones_are_refused():
    sc = make_scenario(filters={"ukf": {"alpha": 0.5}})
    f = build_filter("ukf", sc, 0, params={"kappa": 1.0})
    assert f.params == {"alpha": 0.5, "beta": 2.0, "kappa": 1.0, "scaled": True, "gate_chi2": 0.0,
                        "association": "nn", "association_prob": 0.99, "association_inflation": 1.0,
                        "unambiguous_share": 0.0}
    with pytest.raises(FilterError, match="did you mean 'gate_chi2'"):
        build_filter("ekf", sc, 0, params={"gate_chi": 3.0})


def test_filters_satisfy_the_protocol():
    sc = make_scenario()
    for spec in ("kf", "ekf", "ukf", "dead_reckoning"):
        assert isinstance(build_filter(spec, sc, 0), Filter)


def test_runner_feeds_the_same_steps_to_every_filter(tmp_path):
    """Two EKFs (one loaded from a file) and a UKF side by side: the two EKFs must keep
    bit-identical histories, the UKF its own, every one a step per tick."""
    sc = make_scenario()
    path = tmp_path / "my_filter.py"
    path.write_text(FILE_FILTER)
    filters = {"ekf": build_filter("ekf", sc, 0), "mine": build_filter(f"{path}:MyEKF", sc, 0),
               "ukf": build_filter("ukf", sc, 0)}
    runner = FilterRunner(filters)
    sim = Simulation(sc, 0)
    for _ in range(50):
        runner.feed(sim.step())
    t = runner.tracks
    assert [len(t[n].means) for n in t] == [50, 50, 50]
    assert t["ekf"].ticks == list(range(1, 51))
    assert np.array_equal(np.array(t["ekf"].means), np.array(t["mine"].means))
    assert np.array_equal(np.array(t["ekf"].covs), np.array(t["mine"].covs))
    assert np.max(np.abs(np.array(t["ekf"].means) - np.array(t["ukf"].means))) < 0.05


class Broken(ExtendedKalmanFilter):
    def update(self, measurements):
        if measurements:
            raise RuntimeError("broken on purpose")


def test_a_failing_filter_is_switched_off_and_the_others_go_on():
    sc = make_scenario()
    from beacon_sim.filters.base import FilterContext

    ctx = FilterContext("broken", sc.world, sc.dt, sc.model_motion_noise, sc.model_sensors)
    runner = FilterRunner({"ekf": build_filter("ekf", sc, 0), "broken": Broken(ctx)})
    sim = Simulation(sc, 0)
    for _ in range(20):
        runner.feed(sim.step())
    assert "broken on purpose" in runner.tracks["broken"].failed
    assert len(runner.tracks["ekf"].means) == 20


def test_run_json_has_the_design_shape(capsys):
    assert main(["run", "default", "--filter", "ekf", "--filter", "ukf", "--duration", "5", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for key in ("scenario", "seed", "steps", "truth_checksum", "filters"):
        assert key in d
    assert set(d["filters"]) == {"ekf", "ukf"}
    for row in d["filters"].values():
        for key in ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees",
                    "us_per_step"):
            assert np.isfinite(row[key]), key
        assert row["pos_rmse_m"] < 0.3


def test_a_file_spec_that_is_not_python_source_is_a_one_line_error(tmp_path):
    """``path/to/my_filter:Cls`` without ``.py``: Python finds no loader for the file."""
    path = tmp_path / "my_filter"
    path.write_text(FILE_FILTER)
    with pytest.raises(FilterLoadError) as exc:
        load_filter_class(f"{path}:MyEKF")
    assert "not a Python source file" in str(exc.value) and "\n" not in str(exc.value)
