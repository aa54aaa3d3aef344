"""The Python API: the same runs as the ``beacon-sim`` command, from a notebook or a script.

A facade over :mod:`beacon_sim.runs` (headless runs, replays), :mod:`beacon_sim.io` (export,
MCAP) and :mod:`beacon_sim.evaluation` (metrics' curves, plots); docs/python-api.md is the
guide. The names in ``beacon_sim.__all__`` are the public API; everything else may change.

Frames and units as everywhere: world frame, metres, radians, seconds; a pose is
``[x, y, theta]``, theta counter-clockwise from +x.
"""

from __future__ import annotations

import importlib
import sys
import types
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core import angles, measurement_models, motion
from beacon_sim.core.angles import wrap
from beacon_sim.core.arguments import check_duration, check_seed
from beacon_sim.core.beam_model import LikelihoodField, RangeModelParams
from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.optional import install_hint
from beacon_sim.core.scenario import (
    MAX_TICKS,
    Scenario,
    ScenarioError,
    TeamScenario,
    parse_scenario,
    read_toml,
    resolve_scenario_path,
)
from beacon_sim.core.scenario import load_scenario as _load_scenario
from beacon_sim.core.scenario import load_team_scenario as _load_team_scenario
from beacon_sim.core.types import Control, Measurement
from beacon_sim.errors import ArgumentTypeError, BeaconSimError, UsageError, short_repr
from beacon_sim.evaluation import plots
from beacon_sim.evaluation.mc_tables import monte_carlo_tables
from beacon_sim.evaluation.montecarlo import RunOutput, finish_filter, run_monte_carlo
from beacon_sim.evaluation.summary import evaluate as summarise
from beacon_sim.filters.base import (
    Filter,
    FilterBase,
    FilterContext,
    FilterError,
    GaussianBelief,
    GridBelief,
    LandmarkMap,
    ParticleBelief,
    broad_gaussian,
)
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.graph import FactorGraph, GraphSolver, StepReport
from beacon_sim.filters.resampling import systematic
from beacon_sim.hosting.loading import FilterLoadError, check_param_names
from beacon_sim.hosting.team_specs import check_team_specs
from beacon_sim.io.export import filter_arrays, load_export, step_arrays, trace_arrays, write_export
from beacon_sim.io.mrclam import MrclamError
from beacon_sim.io.recording import Recording, RecordingError, load_recording
from beacon_sim.io.tables import TABLES, metrics_table, prefixed, reading_matrix, tables
from beacon_sim.runs.headless import RunResult, run_headless
from beacon_sim.runs.replay import ReplayMismatch, recorded_filter_specs, replay_recording

#: The public API. Functions and results; what a filter author needs (the filter base and
#: protocol, the beliefs, the readings' and controls' types, and the models as modules:
#: ``motion``, ``measurement_models``, ``angles``, and ``wrap``, ``broad_gaussian``,
#: ``LandmarkMap``, ``LikelihoodField``, ``RangeModelParams``, ``systematic``, and the built-in
#: ``ExtendedKalmanFilter`` to build on: what the examples and the ``new-filter`` templates
#: import); the errors, all ``BeaconSimError``.
#: ``GradeError`` comes from the module's ``__getattr__`` (the grading module loads on first use).
__all__ = ["BeaconSimError", "Control", "Evaluation", "ExtendedKalmanFilter", "FactorGraph", "Filter",
           "FilterBase", "FilterContext", "FilterError",
           "FilterLoadError", "GaussianBelief", "GradeError",  # noqa: F822
           "GraphSolver", "GridBelief", "LandmarkMap", "LikelihoodField", "Measurement", "MrclamError",
           "ParticleBelief", "RangeModelParams", "RecordingError", "ReplayMismatch", "Run", "ScenarioError",
           "StepReport", "TeamRun", "UsageError", "angles", "broad_gaussian", "evaluate", "load_scenario",
           "load_tables",
           "load_team_scenario", "measurement_models", "motion", "replay", "run", "run_team", "systematic",
           "wrap"]
#: The export formats of :meth:`Run.export`.
EXPORT_SUFFIXES = (".npz", ".csv", ".mcap")

#: Filter classes handed to :func:`run` as objects are reached through this module, so they
#: go the same way as a filter named ``pkg.mod:Class`` (the same construction, seeding and
#: names as ``beacon-sim run``).
_CLASS_MODULE = "beacon_sim._api_filter_classes"


def load_scenario(name_or_path: str | Path, changes: Mapping[str, Any] | None = None) -> Scenario:
    """A shipped scenario by name (``"default"``) or a ``.toml`` file by path, with
    ``changes`` applied to its keys before it is validated.

    ``changes`` maps a dotted key of the scenario file (docs/scenarios.md) to a value:
    ``{"duration": 30, "robot.motion_noise.v_frac": 0.1, "sensors.0.max_range": 5.0}``
    (an integer picks an entry of an array of tables). A bad key or value raises
    :class:`~beacon_sim.core.scenario.ScenarioError` naming it, as for a file.
    """
    _check_path_like(name_or_path, "name_or_path=")
    if changes is not None and not isinstance(changes, Mapping):
        raise ArgumentTypeError(f"changes={short_repr(changes)}: expected a dict of dotted scenario keys "
                                "to values, e.g. {'duration': 30}")
    if not changes:
        return _load_scenario(name_or_path)
    import copy

    path = resolve_scenario_path(name_or_path)
    data = copy.deepcopy(read_toml(path))  # the one reader's checks; a copy, as it is changed
    for key, value in changes.items():
        _set_key(data, key, value)
    return parse_scenario(data, f"{path} (changed in code)", name=path.stem, base_dir=path.parent)


def _check_path_like(value: Any, label: str) -> None:
    """A scenario or file argument: a name or path (``str`` or ``Path``), else ArgumentTypeError."""
    if not isinstance(value, str | Path):
        raise ArgumentTypeError(f"{label}{short_repr(value)}: expected a name or a path (str or Path)")


def _set_key(data: dict, key: Any, value: Any) -> None:
    """``data`` with the dotted ``key`` set to ``value`` (an integer part picks an entry of
    an array of tables); ScenarioError naming the key for one that does not fit."""
    if not isinstance(key, str) or not key:
        raise ScenarioError(f"changes: key {short_repr(key)}: expected a dotted key such as "
                            "'sensors.0.max_range'")
    parts = key.split(".")
    node: Any = data
    for i, part in enumerate(parts):
        where = ".".join(parts[:i]) or "the scenario"
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ScenarioError(f"changes: {key}: {where} is an array of {len(node)} entries: "
                                    f"expected an index from 0 to {len(node) - 1}, got {part!r}")
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise ScenarioError(f"changes: {key}: {where} is a value ({short_repr(node)}), not a table")


def _spec(f: str | type) -> str:
    """A filter spec for a name / path, or for a class defined in the caller's code."""
    if isinstance(f, str):
        return f
    if not isinstance(f, type):
        raise FilterLoadError(f"filter {f!r}: expected a name (e.g. 'ekf') or a class")
    mod = sys.modules.get(_CLASS_MODULE)
    if mod is None:
        mod = sys.modules[_CLASS_MODULE] = types.ModuleType(_CLASS_MODULE)
    setattr(mod, f.__name__, f)
    return f"{_CLASS_MODULE}:{f.__name__}"


def _specs(filters: Sequence[str | type] | None) -> list[str] | None:
    if filters is None:
        return None
    if isinstance(filters, str | type):
        filters = [filters]
    if not isinstance(filters, list | tuple):
        raise ArgumentTypeError(f"filters={short_repr(filters)}: expected a list of filter names or classes, "
                                "e.g. ['ekf', 'pf']")
    classes = [f for f in filters if isinstance(f, type)]
    names = [c.__name__ for c in classes]
    for c in classes:
        if names.count(c.__name__) > 1 and classes.count(c) != names.count(c.__name__):
            raise FilterLoadError(f"two different filter classes named {c.__name__!r}: rename one")
    return [_spec(f) for f in filters]


def run(scenario: Scenario | str | Path, filters: Sequence[str | type] | None = None, *,
        seed: int | None = None, duration: float | None = None,
        params: Mapping[str, Mapping[str, Any]] | None = None) -> Run:
    """One headless run, exactly as ``beacon-sim run SCENARIO --filter ... --seed ...``.

    ``filters``: built-in names (``"ekf"``, ``"pf"``, ...), ``"pkg.mod:Class"``,
    ``"file.py:Class"``, or filter classes (e.g. one defined in a notebook); None runs the
    scenario's ``default_filters``. ``params``: ``{filter name: {key: value}}`` like
    ``--set NAME.KEY=VALUE``. ``seed`` / ``duration`` [s]: default the scenario's.
    Same scenario and seed give the same run, bit for bit.
    """
    if not isinstance(scenario, Scenario):
        _check_path_like(scenario, "scenario=")
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    seed, duration = _check_run(sc, seed, duration)
    specs = _specs(filters)
    plain = _plain_params(params)
    check_param_names(plain, list(sc.default_filters if specs is None else specs))  # as --set
    return Run(run_headless(sc, specs, seed=seed, duration=duration, params=plain))


def _check_run(sc: Scenario, seed: Any, duration: Any) -> tuple[int | None, float | None]:
    """``seed`` and ``duration`` checked as ``--seed`` and ``--duration`` are (the same code,
    :mod:`beacon_sim.core.arguments`); a bad one raises :class:`UsageError`."""
    return check_seed(seed, "seed="), check_duration(duration, sc.dt, MAX_TICKS, "duration=")


def _plain_params(params: Mapping[str, Mapping[str, Any]] | None) -> dict[str, dict[str, Any]]:
    if params is None:
        return {}
    if not isinstance(params, Mapping) or not all(isinstance(v, Mapping) for v in params.values()):
        raise UsageError(f"params={params!r}: expected {{filter name: {{key: value}}}}, "
                         "e.g. {'pf': {'n_particles': 500}}")
    return {str(k): dict(v) for k, v in params.items()}


def replay(recording: str | Path | Recording, filters: Sequence[str | type] | None = None, *,
           params: Mapping[str, Mapping[str, Any]] | None = None) -> Run | TeamRun:
    """A recording (``beacon-sim play`` writes them) replayed bit for bit, like
    ``beacon-sim replay FILE --headless``; ``filters`` None runs the recorded built-in ones.
    A team's recording gives a :class:`TeamRun`."""
    if not isinstance(recording, Recording):
        _check_path_like(recording, "recording=")
    rec = recording if isinstance(recording, Recording) else load_recording(recording)
    specs = _specs(filters)
    plain = _plain_params(params)
    if not rec.is_team:
        check_param_names(plain, recorded_filter_specs(rec, specs)[0])  # as replay --set
    out = replay_recording(rec, specs, plain)
    return TeamRun(out) if rec.is_team else Run(out, rec)


def load_tables(path: str | Path) -> dict[str, Any]:
    """The tidy tables of an export (``run.npz``, or the ``run.csv`` files) as pandas
    DataFrames: ``truth``, ``readings``, ``events`` and, when filters ran, ``estimates``
    (columns as :meth:`Run.tables`). Older files, with the old column names, load
    too. Needs pandas (``pip install pandas``)."""
    pd = _pandas()
    try:
        tabs = load_export(path)
    except (ValueError, KeyError) as exc:
        why = str(exc) if isinstance(exc, ValueError) else f"{path}: no column {exc}"
        raise RecordingError(why) from None
    return {name: pd.DataFrame(cols) for name, cols in tabs.items()}


def _pandas():
    try:
        return importlib.import_module("pandas")
    except ImportError as exc:
        raise ImportError(install_hint("pandas")) from exc


def __getattr__(name: str):
    if name == "GradeError":  # the grading module loads on first use (it is heavy)
        return importlib.import_module("beacon_sim.evaluation.grading").GradeError
    raise AttributeError(f"module 'beacon_sim.api' has no attribute {name!r}")


class Columns(dict):
    """A table's columns (name -> 1-D array, all the same length): ``pd.DataFrame(cols)``
    takes it as it is. The old names (``time``, ``z``, ``pose_before``,
    ``pose_after``) still work, with a ``DeprecationWarning``."""

    def __missing__(self, key: str) -> np.ndarray:
        if key == "time" and "time_s" in self:
            value = self["time_s"]
        elif key == "z" and "kind" in self and "bearing_rad" in self:
            value = reading_matrix(self)
        elif key in ("pose_before", "pose_after") and f"x_{key[5:]}_m" in self:
            w = key[5:]
            value = np.column_stack([self[f"x_{w}_m"], self[f"y_{w}_m"], self[f"theta_{w}_rad"]])
        else:
            raise KeyError(key)
        warnings.warn(f"{key!r} is an old name: see Run.readings / Run.events (docs/python-api.md)",
                      DeprecationWarning, stacklevel=2)
        return value


class Run:
    """The result of :func:`run` or :func:`replay`: arrays, metrics, plots and exports.

    Arrays have one row per tick; ``T`` ticks after the start. ``truth`` and ``time`` have
    ``T + 1`` rows (row 0 is the start); a filter's ``estimates`` / ``covariances`` have ``T``
    rows (row ``k - 1`` is tick ``k``), NaN after the filter was switched off.
    """

    def __init__(self, result: RunResult, recording: Recording | None = None):
        self.result = result
        self.recording = recording
        if recording is not None:
            arrays = trace_arrays(recording, result.steps, result.runner.tracks)
        else:
            arrays = step_arrays(result.scenario, result.steps)
            arrays.update(filter_arrays(result.runner.tracks, len(result.steps)))
        self._arrays = arrays

    def __repr__(self) -> str:
        return (f"<Run {self.scenario.name} seed={self.seed} ticks={len(self.controls)} "
                f"filters={self.filter_names}>")

    @property
    def scenario(self) -> Scenario:
        return self.result.scenario

    @property
    def seed(self) -> int:
        return self.result.seed

    @property
    def filter_names(self) -> list[str]:
        """The filters' names in this run (``ekf``, a class's name, ``ekf'`` for a repeat)."""
        return list(self.result.runner.tracks)

    @property
    def time(self) -> np.ndarray:
        """(T + 1,) simulated time of each row of :attr:`truth` [s]."""
        return self._arrays["truth_time_s"]

    @property
    def truth(self) -> np.ndarray:
        """(T + 1, 3) true pose [m, m, rad]; row 0 is the initial pose."""
        return self._arrays["truth"]

    @property
    def controls(self) -> np.ndarray:
        """(T, 2) the command of ticks 1..T: v [m/s], omega [rad/s]."""
        return self._arrays["control"]

    @property
    def estimates(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, 3) estimated pose [m, m, rad] after each tick."""
        return {n: self._arrays["est_mean"][i] for i, n in enumerate(self.filter_names)}

    @property
    def covariances(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, 3, 3) covariance of the estimate [m^2, m^2 rad, rad^2]."""
        return {n: self._arrays["est_cov"][i] for i, n in enumerate(self.filter_names)}

    def errors(self, name: str) -> np.ndarray:
        """(T, 3) estimate - truth of filter ``name`` [m, m, rad], heading wrapped."""
        estimates = self.estimates
        if not isinstance(name, str) or name not in estimates:
            raise UsageError(f"name={short_repr(name)}: not a filter of this run (its filters: "
                             f"{', '.join(estimates) or 'none'})")
        return pose_errors(estimates[name], self.truth[1:])

    @property
    def readings(self) -> Columns:
        """The ``readings`` table (one row per reading, M rows): ``tick``, ``time_s``,
        ``sensor``, ``kind``, ``beacon_id`` (-1 for a fix), ``range_m``, ``bearing_rad``,
        ``x_m``, ``y_m``, ``theta_rad`` (NaN where the kind has no such number), ``hdop``."""
        return Columns(prefixed(self._arrays, "readings"))

    @property
    def events(self) -> Columns:
        """The ``events`` table (one row per event): ``tick``, ``time_s``, ``kind``,
        ``detail``, ``x_before_m`` .. ``theta_after_rad`` (a kidnap's poses; NaN otherwise)."""
        return Columns(prefixed(self._arrays, "events"))

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything above as the flat arrays ``beacon-sim export`` writes (docs/replay.md)."""
        return dict(self._arrays)

    def columns(self, table: str = "estimates") -> Columns:
        """One tidy table as columns of numpy arrays (no pandas needed): ``truth``,
        ``estimates``, ``readings``, ``events`` or ``metrics`` (docs/python-api.md)."""
        if table == "metrics":
            return Columns(metrics_table(self.metrics()))
        if table not in TABLES:
            raise UsageError(f"table {table!r}: expected one of {', '.join((*TABLES, 'metrics'))}")
        return Columns(tables(self._arrays)[table])

    def to_frame(self, table: str = "estimates"):
        """One tidy table as a pandas ``DataFrame`` (long form: ``df.plot`` and seaborn take
        it directly, e.g. ``sns.lineplot(run.to_frame(), x="time_s", y="err_pos_m",
        hue="filter")``). Needs pandas (``pip install pandas``)."""
        return _pandas().DataFrame(self.columns(table))

    def tables(self) -> dict[str, Any]:
        """Every tidy table as a DataFrame: ``{"truth": ..., "estimates": ..., "readings": ...,
        "events": ..., "metrics": ...}``."""
        return {name: self.to_frame(name) for name in (*TABLES, "metrics")}

    def metrics(self) -> dict[str, Any]:
        """What ``beacon-sim run --json`` prints for this run (RMSE, ANEES, counts, checksum;
        ``steps_per_s`` and ``us_per_step`` are wall-clock timings, the rest is exact)."""
        return self.result.as_json()

    def curves(self) -> dict[str, Any]:
        """The per-tick curves the evaluation's plots draw (this run as a one-run evaluation,
        with the posterior Cramer-Rao bound of its trajectory)."""
        res = self.result
        out = RunOutput(0, res.seed, self.truth, self.controls,
                        np.array([s.kidnapped for s in res.steps], dtype=bool), res.truth_checksum)
        for i, (name, tr) in enumerate(res.runner.tracks.items()):
            out.filters[name] = finish_filter(
                self._arrays["est_mean"][i].copy(), self._arrays["est_cov"][i].copy(), self.truth,
                tr.steps, tr.failed, 0.0, 0, tr.step_ns, keep_means=True)
        return summarise(self.scenario, [out])[1]

    def plot_trajectories(self):
        """The true path, each filter's estimate and the beacons: a matplotlib ``Figure``."""
        return plots.trajectories_figure(self.scenario, self.curves())

    def plot_errors(self):
        """x, y, heading error against time with +-3 sigma: a matplotlib ``Figure``."""
        return plots.errors_figure(self.scenario, self.curves())

    def plot_nees(self):
        """NEES against time with the 95 % band: a matplotlib ``Figure``."""
        return plots.nees_figure(self.scenario, self.curves(), 1)

    def export(self, path: str | Path) -> list[Path]:
        """Write the run to ``.npz``, ``.csv`` (several files) or ``.mcap`` (Foxglove; needs
        the ``mcap`` extra); returns the files written."""
        path = Path(path)
        if path.suffix not in EXPORT_SUFFIXES:
            raise UsageError(f"{path}: expected a .npz, .csv or .mcap file name")
        if path.suffix == ".mcap":
            from beacon_sim.io.mcap import write_mcap

            return [write_mcap(path, self.scenario, self._arrays,
                               {"seed": str(self.seed), "truth_checksum": self.result.truth_checksum})]
        return write_export(self._arrays, path)


class Evaluation:
    """The result of :func:`evaluate`: Monte Carlo runs as two tidy tables
    (:mod:`beacon_sim.evaluation.mc_tables`).

    ``columns("ticks")``: one row per run, filter and tick (error, sigma, NEES, the PCRB's
    sigma, ``in_model``); ``columns("runs")``: one row per run and filter (RMSE, MSE, ANEES,
    cost, failure). Each a dict of numpy arrays; ``to_frame(table)`` a pandas DataFrame,
    ``to_pandas()`` both. ``outputs`` holds the runs themselves.
    """

    TABLES = ("ticks", "runs")

    def __init__(self, scenario: Scenario, outputs: list[RunOutput]):
        self.scenario = scenario
        self.outputs = outputs
        self._tables = monte_carlo_tables(scenario, outputs)

    def __repr__(self) -> str:
        names = list(self.outputs[0].filters) if self.outputs else []
        return f"<Evaluation {self.scenario.name!r}: {len(self.outputs)} runs of {', '.join(names)}>"

    def columns(self, table: str = "ticks") -> Columns:
        """One table as columns of numpy arrays: ``"ticks"`` or ``"runs"``."""
        if table not in self.TABLES:
            raise UsageError(f"table {table!r}: expected one of {', '.join(self.TABLES)}")
        return Columns({k: v.copy() for k, v in self._tables[table].items()})

    def to_frame(self, table: str = "ticks"):
        """One table as a pandas DataFrame, long form: ``sns.lineplot(ev.to_frame(),
        x="time_s", y="err_pos_m", hue="filter")`` draws each filter's mean error and its
        95 % band over the runs. Needs pandas."""
        return _pandas().DataFrame(self.columns(table))

    def to_pandas(self) -> dict[str, Any]:
        """``{"ticks": DataFrame, "runs": DataFrame}``. Needs pandas."""
        return {t: self.to_frame(t) for t in self.TABLES}


def evaluate(scenario: Scenario | str | Path, filters: Sequence[str | type] | None = None, *,
             runs: int = 20, seed: int = 0, duration: float | None = None,
             params: Mapping[str, Mapping[str, Any]] | None = None, jobs: int | None = 1) -> Evaluation:
    """Monte Carlo, as ``beacon-sim eval``: ``runs`` runs with seeds ``seed, seed + 1, ...``
    (the same runs as ``eval --runs N --seed S``), returned as tidy tables
    (:class:`Evaluation`). ``jobs``: processes (1: this one; None: every core)."""
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise UsageError(f"runs={runs!r}: expected a whole number >= 1")
    seed_checked, duration = _check_run(sc, seed, duration)
    specs = _specs(filters)
    plain = _plain_params(params)
    names = list(sc.default_filters if specs is None else specs)
    check_param_names(plain, names)
    outputs = run_monte_carlo(sc, names, runs, seed=int(seed_checked or 0), duration=duration,
                              jobs=jobs, params=plain, progress=False)
    return Evaluation(sc, outputs)


def load_team_scenario(name_or_path: str | Path) -> TeamScenario:
    """A shipped team scenario by name (``"team_sparse"``) or a team ``.toml`` by path
    (docs/multi-robot.md); a bad file raises ``ScenarioError`` naming the file and the key."""
    return _load_team_scenario(name_or_path)


def run_team(scenario: TeamScenario | str | Path, filters: Sequence[str | type] | None = None, *,
             seed: int | None = None, duration: float | None = None,
             params: Mapping[str, Mapping[str, Any]] | None = None) -> TeamRun:
    """One headless team run, exactly as ``beacon-sim run TEAM_SCENARIO --filter ...`` (the
    same :func:`~beacon_sim.runs.headless.run_headless` as :func:`run`, over N robots).

    ``filters``: team filter names (``"independent"``, ``"centralised"``,
    ``"decentralised"``, ``"ci"``, ``"naive"``), ``"independent:F"`` (single-robot filter F
    on every robot), ``"file.py:Class"`` or a class (your own team filter: ``reset``,
    ``predict``, ``update``, ``estimates``); None runs the scenario's ``default_filters``.
    """
    team = scenario if isinstance(scenario, TeamScenario) else load_team_scenario(scenario)
    seed, duration = _check_run(team.robots[0].scenario, seed, duration)
    specs = _specs(filters)
    names = list(team.default_filters if specs is None else specs)
    plain = _plain_params(params)
    check_team_specs(names, team, plain)
    return TeamRun(run_headless(team, names, seed=seed, duration=duration, params=plain))


class TeamRun:
    """The result of :func:`run_team`: one row per tick (``T`` ticks), robots in the
    scenario's order; a filter switched off has NaN rows after it failed. ``result`` is the
    one :class:`~beacon_sim.runs.headless.RunResult`, as :class:`Run`'s."""

    def __init__(self, result: RunResult):
        self.result = result

    def __repr__(self) -> str:
        return (f"<TeamRun {self.result.team.name} seed={self.result.seed} "
                f"ticks={len(self.result.team_steps)} "
                f"robots={self.robots} filters={self.filter_names}>")

    @property
    def robots(self) -> list[str]:
        return [r.name for r in self.result.team.robots]

    @property
    def filter_names(self) -> list[str]:
        return self.result.names

    @property
    def time(self) -> np.ndarray:
        """(T,) simulated time after each tick [s]."""
        return np.array([s.time for s in self.result.team_steps])

    @property
    def truth(self) -> np.ndarray:
        """(T, N, 3) true poses after each tick [m, m, rad]."""
        return self.result.true_poses

    def _rows(self, name: str, which: int) -> np.ndarray:
        """Filter ``name``'s means (``which`` 1) or covariances (2), NaN where it has none."""
        series = self.result.filters.series(name)
        ticks, got = series[0], series[which]
        out = np.full((len(self.result.team_steps), *got.shape[1:]), np.nan)
        if len(got):
            out[ticks - 1] = got
        return out

    @property
    def estimates(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, N, 3) each robot's estimated pose after each tick."""
        return {name: self._rows(name, 1) for name in self.filter_names}

    @property
    def covariances(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, N, 3, 3) each robot's covariance (the joint state's marginal)."""
        return {name: self._rows(name, 2) for name in self.filter_names}

    def failed(self, name: str) -> str | None:
        """Why filter ``name`` was switched off (with the time), or None."""
        return self.result.failed(name)

    def metrics(self) -> dict[str, Any]:
        """What ``beacon-sim run TEAM --json`` prints: per filter, each robot's and the team's
        figures (RMSE, ANEES with band and verdict); a failed filter has only ``failed``."""
        return self.result.as_json()
