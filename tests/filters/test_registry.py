"""One record per built-in filter (filters/registry.py): adding a built-in filter
is its module and one record. A toy filter registered in a fixture is listed, loads by
name, has its parameter ranges checked, its drawing style and its MRCLAM defaults; every
shipped record agrees with its class (ranges beside real defaults, batched form)."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest
from mrclam_helpers import make_folder

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters import registry
from beacon_sim.filters.base import Batchable, BatchedFilter, FilterError
from beacon_sim.filters.param_ranges import check_resources
from beacon_sim.filters.params import Param, Range
from beacon_sim.filters.registry import COLOUR_NAMES, DASH_NAMES, RECORDS, FilterRecord
from beacon_sim.filters.team import TEAM_FILTERS
from beacon_sim.hosting.loading import BUILTIN_FILTERS, available_filters, build_filter, load_filter_class
from beacon_sim.io.mrclam import load_mrclam
from beacon_sim.runs import styles
from beacon_sim.runs.mrclam import MRCLAM_PARAMS, run_mrclam

TOY = '''
import numpy as np
from beacon_sim.filters.base import FilterBase


class ToyFilter(FilterBase):
    """Dead reckoning that remembers its parameters (for the registry's test)."""

    defaults = {"gain": 0.5, "steps": 3}

    def reset(self, initial):
        self.mean = np.zeros(3) if initial is None else np.array(initial.mean, dtype=float)

    def predict(self, control, dt):
        v, w = control
        self.mean = self.mean + dt * np.array([v * np.cos(self.mean[2]), v * np.sin(self.mean[2]), w])
        self.mean[2] = (self.mean[2] + np.pi) % (2 * np.pi) - np.pi

    def update(self, measurements):
        pass

    def estimate(self):
        return self.mean.copy(), np.eye(3) * self.params["gain"]
'''


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """The toy filter's module (in a temporary folder on ``sys.path``) and its one record."""
    (tmp_path / "toy_filter.py").write_text(textwrap.dedent(TOY), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    record = FilterRecord("toy", "toy_filter:ToyFilter", ("sky blue", "dashed"),
                          ranges={"gain": Range(0.0, 1.0, "the covariance's scale")},
                          mrclam={"gain": 0.25})
    monkeypatch.setitem(RECORDS, "toy", record)
    return record


def test_a_toy_filter_is_listed_and_loads_by_name(toy, capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    filters = out.split("\nfilters:\n", 1)[1].split("team filters:", 1)[0].split()
    assert filters[-1] == "toy" and "ekf" in filters
    assert "toy" in available_filters() and BUILTIN_FILTERS["toy"] == "toy_filter:ToyFilter"
    assert load_filter_class("toy").__name__ == "ToyFilter"
    assert main(["run", "default", "--filter", "toy", "--duration", "2", "--json"]) == 0
    assert "pos_rmse_m" in json.loads(capsys.readouterr().out)["filters"]["toy"]


def test_a_toy_filters_ranges_are_checked(toy):
    sc = load_scenario("default")
    assert build_filter("toy", sc, seed=1, params={"gain": 1.0}).params["gain"] == 1.0
    in_range = r"^ToyFilter: parameter gain = 1\.5: expected a number in \[0, 1\]$"
    with pytest.raises(FilterError, match=in_range):
        build_filter("toy", sc, seed=1, params={"gain": 1.5})
    with pytest.raises(FilterError, match="gain = nan: expected a finite number"):
        build_filter("toy", sc, seed=1, params={"gain": float("nan")})
    with pytest.raises(FilterError, match=r"steps = 2\.5: expected an integer like 3"):
        build_filter("toy", sc, seed=1, params={"steps": 2.5})
    assert toy.params() == {"gain": Param(0.5, 0.0, 1.0, "the covariance's scale"), "steps": Param(3)}


def test_a_toy_filter_has_its_style(toy):
    want = (styles.COLOURS["sky blue"], styles.DASHES["dashed"])
    assert styles.KIND_STYLES["toy"] == want
    got = styles.filter_styles(["ekf", "toy", "toy'"])
    assert got["toy"] == want and got["toy'"][0] == want[0] and got["toy'"][1] != want[1]
    assert got["ekf"] == styles.KIND_STYLES["ekf"]


def test_a_toy_filter_gets_its_mrclam_defaults(toy, tmp_path):
    assert MRCLAM_PARAMS["toy"] == {"gain": 0.25}
    make_folder(tmp_path / "set", seconds=6.0)
    run = run_mrclam(load_mrclam(tmp_path / "set", 1), ["toy"])
    assert run.tracks["toy"].filter.params["gain"] == 0.25
    run = run_mrclam(load_mrclam(tmp_path / "set", 1), ["toy"], params={"toy": {"gain": 0.75}})
    assert run.tracks["toy"].filter.params["gain"] == 0.75   # the caller's value wins


@pytest.mark.parametrize("name", list(RECORDS))
def test_every_record_agrees_with_its_class(name):
    """Ranges name real parameters and hold their defaults; styles and MRCLAM parameters
    are known names; the batched form is what the filter's ``batched`` returns."""
    record = RECORDS[name]
    assert record.style[0] in COLOUR_NAMES and record.style[1] in DASH_NAMES
    defaults = getattr(record.load(), "defaults", {})
    assert set(record.ranges) <= set(defaults), name
    for key, param in record.params().items():
        param.check(name, key, param.default)   # every default inside its own range
    for key, value in record.mrclam.items():
        record.params()[key].check(name, key, value)
    if record.team:
        assert TEAM_FILTERS[name] is record.load()
        return
    flt = build_filter(name, load_scenario("default"), seed=1)
    if record.batched is None:
        assert not isinstance(flt, Batchable), f"{name} has a batched form its record does not name"
    else:
        assert isinstance(flt, Batchable)
        form = flt.batched(2)
        assert type(form) is record.load_batched() and isinstance(form, BatchedFilter)
        assert form.mean.shape == (2, 3) and form.cov.shape == (2, 3, 3)


def test_the_records_are_the_only_tables():
    """The tables the rest of the program reads are the records' (same names, same order)."""
    single = [r.name for r in registry.single_records()]
    assert list(BUILTIN_FILTERS) == single == list(styles.KIND_STYLES)
    assert list(TEAM_FILTERS) == [r.name for r in registry.team_records()] == list(styles.TEAM_STYLES)
    assert set(MRCLAM_PARAMS) == {n for n in single if RECORDS[n].mrclam}
    # the team and single-robot tables do not mix: one colour and dash pair per team filter
    assert len(set(styles.TEAM_STYLES.values())) == len(styles.TEAM_STYLES)


def test_memory_bounds_come_from_the_records():
    sc = load_scenario("default")
    too_many = r"^ParticleFilter: 2,000,000 particles: expected at most 1,000,000$"
    with pytest.raises(FilterError, match=too_many):
        check_resources(RECORDS["pf"].load(), {"n_max": 2_000_000, "n_particles": 10}, sc.world)
    with pytest.raises(FilterError, match=r"HistogramFilter: cell = 0\.001 m gives a grid of"):
        build_filter("histogram", sc, seed=1, params={"cell": 0.001})


def test_param_check_messages_are_one_line():
    p = Param(10, 1, 100, "particles")
    p.check("pf", "n", 50)
    for bad in (0, 101, 2.0, float("inf")):
        with pytest.raises(FilterError) as err:
            p.check("pf", "n", bad)
        assert "\n" not in str(err.value) and str(err.value).startswith("pf: parameter n = ")
    Param(np.pi).check("x", "y", 1e300)   # no range: any finite number
    with pytest.raises(FilterError, match="expected a finite number"):
        Param(1.0).check("x", "y", 10**400)
