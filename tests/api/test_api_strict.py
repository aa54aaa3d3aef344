"""The Python API is as strict as the command line: each misuse raises the
project's error (a ``BeaconSimError``, still a ``ValueError``) with the message the command
line prints for the same mistake, from the same checking code."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import beacon_sim as bs
from beacon_sim.cli.main import main

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "python_api.ipynb"


def _cli_error(argv, capsys) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("beacon-sim: ") and "\n" not in err
    return err.removeprefix("beacon-sim: ")


def _reason(message: str) -> str:
    """The message after the argument's name (``--seed -1: ...`` / ``seed=-1: ...``)."""
    return message.split(": ", 1)[1]


@pytest.mark.parametrize("kwargs, argv", [
    ({"seed": -1}, ["--seed", "-1"]),
    ({"seed": 2**63}, ["--seed", str(2**63)]),
    ({"duration": -5}, ["--duration", "-5"]),
    ({"duration": 0}, ["--duration", "0"]),
    ({"duration": float("inf")}, ["--duration", "inf"]),
    ({"duration": 0.01}, ["--duration", "0.01"]),            # shorter than one tick of 0.05 s
    ({"duration": 1e9}, ["--duration", "1e9"]),              # over the tick limit
])
def test_bad_seed_or_duration_is_the_clis_error(kwargs, argv, capsys):
    cli = _cli_error(["run", "default", "--filter", "ekf", *argv], capsys)
    with pytest.raises(bs.UsageError) as got:
        bs.run("default", ["ekf"], **kwargs)
    assert _reason(str(got.value)) == _reason(cli)
    key, value = next(iter(kwargs.items()))
    assert str(got.value).startswith(f"{key}={value!r}:")


@pytest.mark.parametrize("seed", ["3", 3.0, True, 2.5])
def test_a_seed_must_be_a_whole_number(seed):
    with pytest.raises(bs.UsageError, match="expected a seed from 0 to 2\\^63 - 1"):
        bs.run("default", ["ekf"], seed=seed, duration=1)


def test_params_for_a_filter_that_does_not_run_is_the_clis_error(capsys):
    cli = _cli_error(["run", "default", "--filter", "ekf", "--set", "pf.n_particles=300"], capsys)
    with pytest.raises(bs.FilterLoadError) as got:
        bs.run("default", ["ekf"], params={"pf": {"n_particles": 300}}, duration=1)
    assert str(got.value) == cli
    with pytest.raises(bs.FilterLoadError, match="no filter 'pf'"):  # default: ekf, dead_reckoning
        bs.run("default", params={"pf": {"n_particles": 300}}, duration=1)
    with pytest.raises(bs.UsageError, match="expected \\{filter name"):
        bs.run("default", ["ekf"], params={"ekf": 3}, duration=1)


def test_team_runs_check_the_same(capsys):
    with pytest.raises(bs.UsageError, match="duration=-1: expected a positive number"):
        bs.run_team("team_sparse", ["independent"], duration=-1)
    with pytest.raises(bs.UsageError, match="seed='1'"):
        bs.run_team("team_sparse", ["independent"], seed="1", duration=1)


@pytest.mark.parametrize("change, message", [
    ({"dt": 0}, "dt=0: expected a tick from 0.001 to 10 s"),
    ({"duration": -5}, "duration=-5: expected a positive number of seconds"),
    ({"seed": -1}, "seed=-1: expected a seed from 0 to 2^63 - 1"),
    ({"dt": 1.0, "duration": 0.2}, "duration=0.2: shorter than one tick of 1 s"),
])
def test_scenario_with_changes_checks_what_a_file_would(change, message):
    sc = bs.load_scenario("default")
    with pytest.raises(bs.ScenarioError) as got:
        sc.with_changes(**change)
    assert str(got.value) == message
    assert sc.with_changes(seed=4).seed == 4 and sc.with_changes(description="x").description == "x"


def test_export_names_every_format(tmp_path):
    r = bs.run("default", ["ekf"], seed=1, duration=1)
    with pytest.raises(bs.UsageError, match=r"expected a \.npz, \.csv or \.mcap file name"):
        r.export(tmp_path / "x.parquet")


def test_errors_share_one_base_and_stay_value_errors():
    kinds = [bs.ScenarioError, bs.FilterError, bs.FilterLoadError, bs.RecordingError, bs.ReplayMismatch,
             bs.MrclamError, bs.GradeError, bs.UsageError]
    for kind in kinds:
        assert issubclass(kind, bs.BeaconSimError) and issubclass(kind, ValueError)
    try:  # code written before 0.3.0 keeps catching them
        bs.run("default", ["ekf"], seed=-1)
    except ValueError as exc:
        assert isinstance(exc, bs.BeaconSimError)
    with pytest.raises(bs.ScenarioError):
        bs.load_scenario("no_such_scenario")


def test_a_filter_author_needs_only_public_names():
    """The models, the angles, the base class and the beliefs are public; the notebook's
    own filter imports nothing but ``beacon_sim``."""
    import numpy as np

    pose = np.array([1.0, 2.0, 0.5])
    assert bs.motion.move(pose, 1.0, 0.0, 1.0)[0] == pytest.approx(1.0 + np.cos(0.5))
    assert bs.measurement_models.range_bearing(pose, np.array([4.0, 6.0]))[0][0] == pytest.approx(5.0)
    assert bs.angles.wrap(3 * np.pi) == pytest.approx(-np.pi)
    assert issubclass(bs.FilterBase, object) and bs.GaussianBelief and bs.ParticleBelief and bs.GridBelief
    nb = json.loads(NOTEBOOK.read_text())
    code = "\n".join("".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code")
    imports = [ln.strip() for ln in code.splitlines() if ln.strip().startswith(("import ", "from "))]
    assert imports and all("beacon_sim." not in ln for ln in imports), imports
    assert "bs.motion" in code and "bs.measurement_models" in code


def test_replay_checks_params_as_replay_set(tmp_path, capsys):
    from recording_helpers import SCENARIO, live_run

    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    rec = tmp_path / "run.jsonl"
    live_run(p, rec, ticks=20)
    cli = _cli_error(["replay", str(rec), "--headless", "--set", "pf.n_particles=10"], capsys)
    with pytest.raises(bs.FilterLoadError) as got:
        bs.replay(rec, params={"pf": {"n_particles": 10}})
    assert str(got.value) == cli
