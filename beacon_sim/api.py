"""The Python API: the same runs as the ``beacon-sim`` command, from a notebook or a script.

A facade over :mod:`beacon_sim.runs` (headless runs, replays), :mod:`beacon_sim.io` (export,
MCAP) and :mod:`beacon_sim.evaluation` (metrics' curves, plots); docs/python-api.md is the
guide. The names in ``beacon_sim.__all__`` are the public API; everything else may change.

Frames and units as everywhere: world frame, metres, radians, seconds; a pose is
``[x, y, theta]``, theta counter-clockwise from +x.
"""

from __future__ import annotations

import sys
import types
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.scenario import Scenario, ScenarioError, parse_scenario, resolve_scenario_path
from beacon_sim.core.scenario import load_scenario as _load_scenario
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.core.team_scenario import load_team_scenario as _load_team_scenario
from beacon_sim.evaluation import plots
from beacon_sim.evaluation.montecarlo import RunOutput, finish_filter
from beacon_sim.evaluation.summary import evaluate
from beacon_sim.filters.base import Filter, FilterBase, FilterContext, GaussianBelief
from beacon_sim.filters.loading import FilterLoadError
from beacon_sim.io.export import filter_arrays, step_arrays, trace_arrays, write_export
from beacon_sim.io.recording import Recording, load_recording
from beacon_sim.runs.headless import RunResult, run_headless
from beacon_sim.runs.replay import replay_recording
from beacon_sim.runs.team import TeamRunResult, check_team_specs, run_team_headless

__all__ = ["Filter", "FilterBase", "FilterContext", "GaussianBelief", "Run", "TeamRun", "load_scenario",
           "load_team_scenario", "replay", "run", "run_team"]

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
    if not changes:
        return _load_scenario(name_or_path)
    import tomllib

    path = resolve_scenario_path(name_or_path)
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    for key, value in changes.items():
        _set_key(data, key, value)
    return parse_scenario(data, f"{path} (changed in code)", name=path.stem)


def _set_key(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ScenarioError(f"changes: {key}: {'.'.join(parts[:i])} has {len(node)} entries")
            node = node[int(part)]
        else:
            node = node.setdefault(part, {})
    if isinstance(node, list):
        node[int(parts[-1])] = value
    else:
        node[parts[-1]] = value


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
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    result = run_headless(sc, _specs(filters), seed=seed, duration=duration,
                          params={k: dict(v) for k, v in (params or {}).items()})
    return Run(result)


def replay(recording: str | Path | Recording, filters: Sequence[str | type] | None = None, *,
           params: Mapping[str, Mapping[str, Any]] | None = None) -> Run:
    """A recording (``beacon-sim play`` writes them) replayed bit for bit, like
    ``beacon-sim replay FILE --headless``; ``filters`` None runs the recorded built-in ones."""
    rec = recording if isinstance(recording, Recording) else load_recording(recording)
    result = replay_recording(rec, _specs(filters),
                              {k: dict(v) for k, v in (params or {}).items()})
    return Run(result, rec)


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
        return self._arrays["truth_time"]

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
        return pose_errors(self.estimates[name], self.truth[1:])

    @property
    def readings(self) -> dict[str, np.ndarray]:
        """One row per reading: ``tick``, ``time`` [s], ``sensor``, ``kind``, ``beacon_id``
        (-1 for a fix), ``z`` (M, 3) NaN-padded (bearing [rad]; range [m], bearing [rad];
        fix x, y [m] (, theta [rad])), ``hdop``."""
        return {k[5:]: v for k, v in self._arrays.items() if k.startswith("meas_")}

    @property
    def events(self) -> dict[str, np.ndarray]:
        """One row per event: ``tick``, ``time`` [s], ``kind``, ``detail``, ``pose_before``
        and ``pose_after`` (E, 3) (NaN unless a kidnap)."""
        return {k[6:]: v for k, v in self._arrays.items() if k.startswith("event_")}

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything above as the flat arrays ``beacon-sim export`` writes (docs/replay.md)."""
        return dict(self._arrays)

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
        return evaluate(self.scenario, [out])[1]

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
        if path.suffix == ".mcap":
            from beacon_sim.io.mcap import write_mcap

            return [write_mcap(path, self.scenario, self._arrays,
                               {"seed": str(self.seed), "truth_checksum": self.result.truth_checksum})]
        return write_export(self._arrays, path)


def load_team_scenario(name_or_path: str | Path) -> TeamScenario:
    """A shipped team scenario by name (``"team_sparse"``) or a team ``.toml`` by path
    (docs/multi-robot.md); a bad file raises ``ScenarioError`` naming the file and the key."""
    return _load_team_scenario(name_or_path)


def run_team(scenario: TeamScenario | str | Path, filters: Sequence[str | type] | None = None, *,
             seed: int | None = None, duration: float | None = None,
             params: Mapping[str, Mapping[str, Any]] | None = None) -> TeamRun:
    """One headless team run, exactly as ``beacon-sim run TEAM_SCENARIO --filter ...``.

    ``filters``: team filter names (``"independent"``, ``"centralised"``,
    ``"decentralised"``, ``"ci"``, ``"naive"``), ``"independent:F"`` (single-robot filter F
    on every robot), ``"file.py:Class"`` or a class (your own team filter: ``reset``,
    ``predict``, ``update``, ``estimates``); None runs the scenario's ``default_filters``.
    """
    team = scenario if isinstance(scenario, TeamScenario) else load_team_scenario(scenario)
    specs = _specs(filters)
    names = list(team.default_filters if specs is None else specs)
    plain = {k: dict(v) for k, v in (params or {}).items()}
    check_team_specs(names, team, plain)
    return TeamRun(run_team_headless(team, names, seed=seed, duration=duration, params=plain))


class TeamRun:
    """The result of :func:`run_team`: one row per tick (``T`` ticks), robots in the
    scenario's order; a filter switched off has NaN rows after it failed."""

    def __init__(self, result: TeamRunResult):
        self.result = result

    def __repr__(self) -> str:
        return (f"<TeamRun {self.result.team.name} seed={self.result.seed} ticks={len(self.result.steps)} "
                f"robots={self.robots} filters={self.filter_names}>")

    @property
    def robots(self) -> list[str]:
        return [r.name for r in self.result.team.robots]

    @property
    def filter_names(self) -> list[str]:
        return list(self.result.tracks)

    @property
    def time(self) -> np.ndarray:
        """(T,) simulated time after each tick [s]."""
        return np.array([s.time for s in self.result.steps])

    @property
    def truth(self) -> np.ndarray:
        """(T, N, 3) true poses after each tick [m, m, rad]."""
        return self.result.truth

    def _rows(self, name: str, attr: str, shape: tuple[int, ...]) -> np.ndarray:
        tr = self.result.tracks[name]
        out = np.full((len(self.result.steps), *shape), np.nan)
        got = np.array(getattr(tr, attr))
        if len(got):
            out[np.array(tr.ticks) - 1] = got
        return out

    @property
    def estimates(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, N, 3) each robot's estimated pose after each tick."""
        n = len(self.robots)
        return {name: self._rows(name, "means", (n, 3)) for name in self.filter_names}

    @property
    def covariances(self) -> dict[str, np.ndarray]:
        """Filter name -> (T, N, 3, 3) each robot's covariance (the joint state's marginal)."""
        n = len(self.robots)
        return {name: self._rows(name, "covs", (n, 3, 3)) for name in self.filter_names}

    def failed(self, name: str) -> str | None:
        """Why filter ``name`` was switched off (with the time), or None."""
        return self.result.failed(name)

    def metrics(self) -> dict[str, Any]:
        """What ``beacon-sim run TEAM --json`` prints: per filter, each robot's and the team's
        figures (RMSE, ANEES with band and verdict); a failed filter has only ``failed``."""
        return self.result.as_json()
