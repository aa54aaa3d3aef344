"""What a class is graded on: :class:`GradeConfig` (a ``grade.toml`` read by
:func:`load_config`, each bad key one line naming the file and the key), :class:`GradeError`,
and how the leaderboard names each scenario (:func:`scenario_labels`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beacon_sim.core.arguments import check_simulated_total
from beacon_sim.core.scenario import read_user_toml
from beacon_sim.errors import BeaconSimError
from beacon_sim.evaluation.grading.rubric import RubricItem, parse_rubric
from beacon_sim.hosting.containment import SANDBOXES


class GradeError(BeaconSimError):
    """A bad grading folder or configuration file (one line, exit status 2)."""


@dataclass(frozen=True)
class GradeConfig:
    """What the class is graded on (a ``grade.toml`` may set any of these).

    scenarios : shipped names or TOML paths (default: ``default``).
    seeds : the run seeds, the same for every student (default 0 to 4).
    duration : seconds per run [s] (default 60; None: each scenario's own).
    time_limit : a filter's time limit per run [s] (default 60).
    memory_limit_gb : the address-space limit of each run's filter [GB] (default 4; 0:
        none), on local processes and Dask workers alike (the seeds and the probes share one
        process; when they run out together each is fed again in a process of its own).
    disk_limit_mb : what a student's process may write [MB] (default 64): under bubblewrap
        the size of its working folder, /tmp and /dev/shm (RAM file systems, half, a quarter
        and a quarter of it); at the process level its working folder (and, under a root
        grader, its files in /dev/shm and /var/tmp), measured after each batch of runs.
    class_name : the filter class in each file (default: found in the file).
    sandbox : ``auto``, ``bwrap`` or ``process`` (docs/grading.md, "What grading protects
        against"); ``auto``: bubblewrap where it works, else the process level.
    pseudonyms : the class page (grade.html) names students by a pseudonym; the teacher's
        files (grade.csv, grade.json, pseudonyms.csv) keep the real names.
    allow_unisolated : grade a class (more than one file) at the process level, where the
        students' processes are not isolated from each other (docs/threat-model.md); without
        it such a grade is refused, and with it the page and the terminal say what a file
        could do.
    total_time_s : a student's total wall time [s] for all its runs (default None: twice
        every run's CPU budget and two minutes); when it runs out the student's child is
        stopped and its unfinished runs fail, saying so.
    rubric : the course's tests and points (``[[rubric]]`` tables,
        :mod:`~beacon_sim.evaluation.grading.rubric`): each row's ``rubric`` and
        ``rubric_score``, and Gradescope's results.json (``grade --gradescope``).
    """

    scenarios: tuple[str, ...] = ("default",)
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    duration: float | None = 60.0
    time_limit: float = 60.0
    memory_limit_gb: float = 4.0
    disk_limit_mb: float = 64.0
    class_name: str | None = None
    sandbox: str = "auto"
    pseudonyms: bool = False
    total_time_s: float | None = None
    allow_unisolated: bool = False
    rubric: tuple[RubricItem, ...] = ()


#: The longest run a grading configuration may ask for [s] (one simulated day).
MAX_GRADE_DURATION_S = 86400.0
#: The largest grade config read [bytes].
MAX_CONFIG_BYTES = 2**20


def _config_list(path: str | Path, data: dict[str, Any], key: str, kind: type, what: str,
                 default: tuple[Any, ...]) -> tuple[Any, ...]:
    """``key`` as a non-empty list (at most 10,000 entries) of ``kind`` values."""
    if key not in data:
        return default
    value = data[key]
    ok = isinstance(value, list) and 1 <= len(value) <= 10_000 and all(
        isinstance(v, kind) and not isinstance(v, bool) for v in value)
    if ok and kind is int:
        ok = all(0 <= v <= 2**63 - 1 for v in value)
    if ok and kind is str:
        ok = all(v.strip() for v in value)
    if not ok:
        raise GradeError(f"{path}: {key} = {value!r}: expected a list of 1 to 10000 {what}")
    return tuple(value)


def _config_number(path: str | Path, data: dict[str, Any], key: str, default: float | None, *, hi: float,
                   zero_is_none: bool = False, allow_zero: bool = False) -> Any:
    """``key`` as a finite number in (0, hi] ([0, hi] with ``allow_zero``; 0 means None with
    ``zero_is_none``)."""
    if key not in data:
        return default
    value = data[key]
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if ok:
        try:
            x = float(value)
        except OverflowError:
            ok = False
    if ok and x == 0.0 and (zero_is_none or allow_zero):
        return None if zero_is_none else 0.0
    if not ok or not (math.isfinite(x) and 0.0 < x <= hi):
        low = "[0" if (zero_is_none or allow_zero) else "(0"
        extra = " (0: each scenario's own)" if zero_is_none else ""
        raise GradeError(f"{path}: {key} = {value!r}: expected a number in {low}, {hi:g}]{extra}")
    return x


def _config_name(path: str | Path, data: dict[str, Any]) -> str | None:
    value = data.get("class_name")
    if value is not None and not (isinstance(value, str) and value.isidentifier()):
        raise GradeError(f"{path}: class_name = {value!r}: expected a Python class name")
    return value


def load_config(path: str | Path | None) -> GradeConfig:
    """A :class:`GradeConfig` from a TOML file (keys as the attributes), or the defaults."""
    if path is None:
        return GradeConfig()
    data = read_user_toml(path, what="grade config", cap=MAX_CONFIG_BYTES, error=GradeError)
    known = set(GradeConfig.__dataclass_fields__)
    unknown = sorted(set(data) - known)
    if unknown:
        raise GradeError(f"{path}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    cfg = GradeConfig(
        scenarios=_config_list(path, data, "scenarios", str, "names or paths (strings)",
                               GradeConfig.scenarios),
        seeds=_config_list(path, data, "seeds", int, "integer seeds in [0, 2^63 - 1], e.g. [0, 1, 2]",
                           GradeConfig.seeds),
        duration=_config_number(path, data, "duration", 60.0, hi=MAX_GRADE_DURATION_S, zero_is_none=True),
        time_limit=_config_number(path, data, "time_limit", GradeConfig.time_limit, hi=86400.0),
        memory_limit_gb=_config_number(path, data, "memory_limit_gb", GradeConfig.memory_limit_gb,
                                       hi=1e4, allow_zero=True),
        disk_limit_mb=_config_number(path, data, "disk_limit_mb", GradeConfig.disk_limit_mb, hi=1e6),
        class_name=_config_name(path, data),
        sandbox=_config_sandbox(path, data),
        pseudonyms=_config_bool(path, data, "pseudonyms"),
        allow_unisolated=_config_bool(path, data, "allow_unisolated"),
        total_time_s=_config_number(path, data, "total_time_s", None, hi=7 * 86400.0, zero_is_none=True),
        rubric=parse_rubric(path, data["rubric"], GradeError) if "rubric" in data else ())
    if cfg.duration is not None:
        check_simulated_total(len(cfg.seeds) * len(cfg.scenarios), cfg.duration,
                              f"{path}: seeds x scenarios x duration", GradeError)
    return cfg


def _config_bool(path: str | Path, data: dict[str, Any], key: str) -> bool:
    value = data.get(key, False)
    if not isinstance(value, bool):
        raise GradeError(f"{path}: {key} = {value!r}: expected true or false")
    return value


def _config_sandbox(path: str | Path, data: dict[str, Any]) -> str:
    value = data.get("sandbox", "auto")
    if value not in SANDBOXES:
        raise GradeError(f"{path}: sandbox = {value!r}: expected one of {', '.join(SANDBOXES)}")
    return str(value)


def scenario_labels(scenarios: Sequence[str]) -> dict[str, str]:
    """Configured scenario -> how the leaderboard names it: a shipped scenario by its name, a
    file by its file name, never the folders it is in (grade.json and the pages are shared);
    a file name that two of them share gets `` (2)``, `` (3)``... after it."""
    from beacon_sim.io.export import without_folders

    out: dict[str, str] = {}
    for spec in scenarios:
        label = base = without_folders(spec)
        k = 1
        while label in out.values():
            k += 1
            label = f"{base} ({k})"
        out[spec] = label
    return out
