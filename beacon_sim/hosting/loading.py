"""Finding a filter class by name, and building filters for a scenario.

A filter is named by
- a built-in name (``ekf``; see ``BUILTIN_FILTERS``),
- a module path ``pkg.mod:Class``,
- a file path ``path/to/file.py:Class``,
- or the name of an entry point in the group ``beacon_sim.filters``.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import re
import sys
import traceback
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from beacon_sim.core import sensor_kinds
from beacon_sim.core.files import MAX_SOURCE_BYTES, check_user_file
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.streams import filter_stream
from beacon_sim.filters.base import Filter, FilterContext, FilterError, GaussianBelief, broad_gaussian
from beacon_sim.filters.param_ranges import check_params
from beacon_sim.filters.registry import TARGETS
from beacon_sim.hosting.runner import FilterExit, run_filter_code

if TYPE_CHECKING:
    import importlib.metadata

#: Built-in filters: name -> "module:Class", imported only when used (read from the
#: records in filters/registry.py).
BUILTIN_FILTERS = TARGETS

ENTRY_POINT_GROUP = "beacon_sim.filters"

#: The longest a filter's module may take to import, and its ``__init__`` or ``reset`` to
#: run, before it is stopped as a failure [s] (an endless loop must not hang the program).
IMPORT_LIMIT_S = 60.0
BUILD_LIMIT_S = 30.0
#: The same in the window, which cannot open before its filters are built [s]: a filter
#: still in ``__init__`` or ``reset`` after this is switched off and the window opens.
WINDOW_BUILD_LIMIT_S = 5.0


class FilterLoadError(FilterError):
    """A filter name that cannot be resolved to a class. The message is one line."""


def entry_point_filters() -> dict[str, importlib.metadata.EntryPoint]:
    """Filters that installed packages register in the ``beacon_sim.filters`` group."""
    import importlib.metadata  # here, not at the top: 0.2 s of every child process's start

    return {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}


def available_filters() -> list[str]:
    """Built-in filters whose module is present, then entry-point filters."""
    names = [n for n, target in BUILTIN_FILTERS.items()
             if importlib.util.find_spec(target.split(":")[0]) is not None]
    return names + sorted(set(entry_point_filters()) - set(names))


def import_file(path: Path, module_name: str | None = None) -> ModuleType:
    """Import a filter file as a module of its own (under a time limit); FilterLoadError
    when it is missing, not Python, or fails to import (even by calling ``sys.exit``)."""
    if not path.exists():
        raise FilterLoadError(f"{path}: no such filter file")
    check_user_file(path, what="filter file", cap=MAX_SOURCE_BYTES, error=FilterLoadError)
    module_name = module_name or f"beacon_sim_user_{abs(hash(path.resolve()))}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:  # e.g. no .py suffix: Python cannot import it
        raise FilterLoadError(f"{path}: not a Python source file (expected path/to/file.py:Class)")
    loader = spec.loader
    module = importlib.util.module_from_spec(spec)
    try:
        sys.modules[module_name] = module
        run_filter_code(lambda: loader.exec_module(module), IMPORT_LIMIT_S, "import")
    except Exception as exc:  # a student's file (even one that calls sys.exit): report, do not crash
        sys.modules.pop(module_name, None)
        why = str(exc) if isinstance(exc, FilterExit) else f"{type(exc).__name__}: {exc}"
        raise FilterLoadError(f"{path}: cannot import: {one_line_text(why)}") from exc
    return module


def _load_file(path: Path, class_name: str) -> type:
    return _get_class(import_file(path), class_name, str(path))


def _get_class(module: ModuleType, class_name: str, where: str) -> type:
    if class_name == FUNCTIONS and getattr(module, FUNCTIONS, None) is None:
        return function_filter_class(module, where)
    cls = getattr(module, class_name, None)
    if cls is None:
        classes = sorted(n for n, v in vars(module).items()
                         if isinstance(v, type) and hasattr(v, "predict") and hasattr(v, "update"))
        hint = f"; filter classes there: {', '.join(classes)}" if classes else ""
        raise FilterLoadError(f"{where}: no class {class_name!r}{hint}")
    return cls


#: The methods that make a class (or a module of functions) a filter; ``belief`` is optional.
FILTER_METHODS = ("reset", "predict", "update", "estimate")
#: The "class name" of a file whose filter is its module-level functions (``file.py:functions``).
FUNCTIONS = "functions"


def implements_filter(obj: object) -> bool:
    """Whether ``obj`` (a class or a module) has every method of :data:`FILTER_METHODS`."""
    return all(callable(getattr(obj, m, None)) for m in FILTER_METHODS)


def choose_filter(module: ModuleType, class_name: str | None, where: str) -> type:
    """The filter a module defines: the class ``class_name`` when given; else the last
    class defined in the module that implements the interface (a helper class with an
    unrelated ``update`` is not chosen); else the module's own functions (``reset``,
    ``predict``, ``update``, ``estimate``, optionally ``belief``: :func:`function_filter_class`)."""
    if class_name == FUNCTIONS:
        return function_filter_class(module, where)
    if class_name is not None:
        return _get_class(module, class_name, where)
    own = [v for v in vars(module).values() if isinstance(v, type)
           and getattr(v, "__module__", None) == module.__name__ and implements_filter(v)]
    if own:
        return own[-1]
    if implements_filter(module):
        return function_filter_class(module, where)
    raise FilterLoadError(f"{where}: no filter: define a class with reset, predict, update and "
                          "estimate, or those four functions at module level")


def function_filter_class(module: ModuleType, where: str) -> type:
    """A filter class whose methods call a module's functions ``reset(initial)``,
    ``predict(control, dt)``, ``update(measurements)``, ``estimate()`` and optionally
    ``belief()`` (docs/writing-a-filter.md, "A file of functions"). The module may define
    ``init(ctx)``, called with the :class:`FilterContext` when the filter is built. One
    module is one filter: its state lives in the module's globals."""
    missing = [m for m in FILTER_METHODS if not callable(getattr(module, m, None))]
    if missing:
        raise FilterLoadError(f"{where}: no filter functions {', '.join(missing)} at module level")
    mod = module

    class FunctionFilter:
        """The module's functions as a filter object."""

        supports_global = bool(getattr(mod, "supports_global", False))
        sensor_kinds = getattr(mod, "sensor_kinds", None)

        def __init__(self, ctx: FilterContext):
            self.ctx = ctx
            init = getattr(mod, "init", None)
            if callable(init):
                init(ctx)

        def reset(self, initial: GaussianBelief | None) -> None:
            mod.reset(initial)

        def predict(self, control: Any, dt: float) -> None:
            mod.predict(control, dt)

        def update(self, measurements: Any) -> None:
            mod.update(measurements)

        def estimate(self) -> Any:
            return mod.estimate()

        def belief(self) -> Any:
            fn = getattr(mod, "belief", None)
            if callable(fn):
                return fn()
            mean, cov = mod.estimate()
            return GaussianBelief(mean, cov)

    FunctionFilter.__module__ = module.__name__
    FunctionFilter.__qualname__ = FunctionFilter.__name__ = "functions"
    return FunctionFilter


_LABEL = re.compile(r"^([A-Za-z0-9_][A-Za-z0-9_.'+-]*)=(.+)$")


def split_label(spec: str) -> tuple[str | None, str]:
    """``"alice=./alice.py:MyEkf"`` -> ``("alice", "./alice.py:MyEkf")``; a spec without a
    label -> ``(None, spec)``. A label is letters, digits, ``_ . ' + -`` before ``=``."""
    m = _LABEL.match(spec)
    return (m.group(1), m.group(2)) if m else (None, spec)


def load_filter_class(spec: str) -> type:
    """Resolve a filter name (built-in, ``pkg.mod:Class``, ``file.py:Class``, entry point),
    with or without a ``LABEL=`` in front."""
    spec = split_label(spec)[1]
    if spec in BUILTIN_FILTERS:
        spec = BUILTIN_FILTERS[spec]
    elif ":" not in spec and spec.endswith(".py"):  # a file: its filter class or functions
        return choose_filter(import_file(Path(spec)), None, spec)
    elif ":" not in spec:
        eps = entry_point_filters()
        if spec in eps:
            try:
                return run_filter_code(eps[spec].load, IMPORT_LIMIT_S, "import")
            except Exception as exc:
                raise FilterLoadError(f"entry point {spec!r}: cannot load: "
                                      f"{one_line_text(str(exc))}") from exc
        known = ", ".join(available_filters())
        raise FilterLoadError(
            f"unknown filter {spec!r}: use one of {known}, pkg.mod:Class or path/to/file.py:Class")
    target, _, class_name = spec.rpartition(":")
    if target.endswith(".py") or "/" in target or "\\" in target:
        return _load_file(Path(target), class_name)
    try:
        module = run_filter_code(lambda: importlib.import_module(target), IMPORT_LIMIT_S, "import")
    except Exception as exc:
        raise FilterLoadError(f"{spec}: cannot import module {target!r}: "
                              f"{one_line_text(str(exc))}") from exc
    return _get_class(module, class_name, target)


def is_file_spec(spec: str) -> bool:
    """Whether a filter spec names a file (``path.py:Class`` or ``path.py``): the filters
    ``eval``, ``check`` and ``grade`` host in a child process of their own."""
    spec = split_label(spec)[1]
    target = spec.rpartition(":")[0] if ":" in spec else spec
    return target.endswith(".py")


def filter_display_name(spec: str) -> str:
    """Short name for a filter spec: its label (``alice`` for ``alice=./a.py:MyEkf``),
    ``ekf``, or ``MyFilter`` for ``my.py:MyFilter``."""
    label, spec = split_label(spec)
    if label:
        return label
    if ":" not in spec and spec.endswith(".py"):
        return Path(spec).stem
    return spec.rpartition(":")[2] if ":" in spec else spec


def _file_stem(spec: str) -> str | None:
    """``alice`` for ``path/to/alice.py:MyEkf``; None for other specs."""
    spec = split_label(spec)[1]
    target = spec.rpartition(":")[0] if ":" in spec else spec
    return Path(target).stem if target.endswith(".py") else None


def filter_names(specs: list[str]) -> list[str]:
    """Display names for filter specs: the names every run, window, replay and evaluation
    gives its filters. A label (``alice=...``) is the name; unlabelled file filters whose
    class names clash (three ``MyEkf``) take their file's name (``alice``, ``bob``...);
    whatever still repeats is primed (``ekf``, ``ekf'``)."""
    first = [filter_display_name(s) for s in specs]
    names: list[str] = []
    for spec, name in zip(specs, first, strict=True):
        stem = _file_stem(spec)
        if first.count(name) > 1 and split_label(spec)[0] is None and stem:
            name = stem
        while name in names:
            name += "'"
        names.append(name)
    return names


def initial_belief(scenario: Scenario) -> GaussianBelief | None:
    """The scenario's initial belief: a Gaussian, or None for a global (uniform) start."""
    ib = scenario.initial_belief
    if ib.global_:
        return None
    return GaussianBelief(np.array(ib.mean, dtype=float), np.diag(np.square(ib.std)))


def parse_set_options(items: list[str]) -> dict[str, dict[str, Any]]:
    """``["pf.n_particles=1000", ...]`` -> ``{"pf": {"n_particles": 1000}}`` (TOML values)."""
    import tomllib

    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, eq, raw = item.partition("=")
        name, dot, param = key.strip().partition(".")
        if not eq or not dot or not name or not param:
            raise FilterLoadError(f"--set {item!r}: expected NAME.KEY=VALUE, e.g. pf.n_particles=1000")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        out.setdefault(name, {})[param] = value
    return out


def check_param_names(params: dict[str, dict[str, Any]] | None, specs: list[str]) -> None:
    """Raise :class:`FilterLoadError` when ``--set NAME.KEY=VALUE`` names a filter that does
    not run (``NAME`` must be one of the filters' display names)."""
    names = sorted({filter_display_name(s) for s in specs})
    for name in params or {}:
        if name not in names:
            hint = difflib.get_close_matches(name, names, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            raise FilterLoadError(f"--set {name}.*: no filter {name!r} in this run{extra}; the "
                                  f"filters are {', '.join(names) or 'none'}")


def merged_params(spec: str, scenario: Scenario, params: dict[str, Any] | None = None) -> dict[str, Any]:
    """The parameters a filter is built with: the scenario's ``[filters.NAME]``, then
    ``params`` (this filter's ``--set`` values) on top."""
    merged = dict(scenario.filter_params.get(filter_display_name(spec), {}))
    merged.update(params or {})
    return merged


def build_filter(spec: str, scenario: Scenario, seed: int, name: str | None = None,
                 params: dict[str, Any] | None = None, *, limit_s: float = BUILD_LIMIT_S,
                 secret: bytes | None = None) -> Filter:
    """Construct and reset one filter for ``scenario``.

    Its random generator comes from ``seed``, its name and ``secret`` only
    (:func:`~beacon_sim.core.streams.filter_stream`; None: the public key, as ``run``,
    ``eval`` and the window), so adding a filter never changes another, and the generator
    does not hand the filter the seed. Parameters: the scenario's ``[filters.NAME]`` then
    ``params``.

    The object is not checked against :class:`~beacon_sim.filters.base.Filter` here (a
    student's class is duck-typed): one that lacks a method is switched off by the
    :class:`~beacon_sim.hosting.runner.FilterRunner` when it first fails, and
    ``beacon-sim check`` names what is missing.
    """
    cls = load_filter_class(spec)
    name = name or filter_display_name(spec)
    ctx = FilterContext.of_scenario(scenario, name, merged_params(spec, scenario, params),
                                    filter_stream(seed, name, secret))
    return build_from_context(cls, ctx, initial_belief(scenario), spec, limit_s=limit_s)


def build_from_context(cls: type, ctx: FilterContext, initial: GaussianBelief | None, spec: str,
                       *, limit_s: float = BUILD_LIMIT_S, cpu: bool = False) -> Filter:
    """Construct ``cls(ctx)`` and reset it to ``initial`` (None: a global start; a broad
    Gaussian for a filter that cannot represent a uniform belief), each under a time limit:
    what :func:`build_filter` does, and what the isolated child does with the context the
    grader sends it; ``cpu``: the limit is CPU time (the hosted child: a verdict that does
    not depend on the machine's load), else wall time (the window must open in time)."""
    check_params(cls, ctx.params, ctx.world)  # finite, in range, fits in memory
    try:
        flt: Filter = run_filter_code(lambda: cls(ctx), limit_s, "__init__", cpu=cpu)
    except FilterError:
        raise
    except TypeError as exc:
        raise FilterLoadError(f"{spec}: cannot construct with a FilterContext: "
                              f"{one_line_text(str(exc))}") from exc

    def reset() -> None:
        init = initial
        if init is None and not getattr(flt, "supports_global", False):
            init = broad_gaussian(ctx.world)
        flt.reset(init)

    run_filter_code(reset, limit_s, "reset", cpu=cpu)
    return flt


def build_filters(specs: list[str], scenario: Scenario, seed: int,
                  params: dict[str, dict[str, Any]] | None = None, *, limit_s: float = BUILD_LIMIT_S,
                  secret: bytes | None = None
                  ) -> tuple[dict[str, Filter | None], dict[str, tuple[str, str]]]:
    """Build every filter of a run, named by :func:`filter_names`: ``(name -> filter or None,
    name -> (why construction failed, traceback))``.

    A name or parameter that cannot work raises :class:`FilterError` (the user named it: one
    line, exit status 2); a filter whose own code fails in import-time-free construction
    (``__init__`` or ``reset`` raising, exiting or hanging) is None with its reason, so the
    run goes on without it."""
    built: dict[str, Filter | None] = {}
    broken: dict[str, tuple[str, str]] = {}
    for name, spec in zip(filter_names(specs), specs, strict=True):
        try:
            built[name] = build_filter(spec, scenario, seed, name=name,
                                       params=(params or {}).get(filter_display_name(spec)),
                                       limit_s=limit_s, secret=secret)
        except FilterError:
            raise
        except Exception as exc:  # a student's __init__ or reset
            built[name] = None
            why = str(exc) if isinstance(exc, FilterExit) else f"{type(exc).__name__}: {exc}"
            broken[name] = (f"construction failed: {one_line_text(why)}", traceback.format_exc())
    return built, broken


def one_line_text(text: str) -> str:
    """The first line of ``text`` (messages are one line), at most 300 characters."""
    lines = text.strip().splitlines()
    first = lines[0] if lines else ""
    return first if len(first) <= 300 else first[:297] + "..."


def sensor_note(spec: str, scenario: Scenario) -> str | None:
    """A one-line note when a filter declares the measurement kinds it uses
    (``sensor_kinds``) and the scenario has no sensor of those kinds: it can only predict."""
    from beacon_sim.filters.gaussian.dead_reckoning import DeadReckoning

    cls = load_filter_class(spec)
    kinds = getattr(cls, "sensor_kinds", None)
    beacon_kinds = {"bearing", "range_bearing"}
    if not scenario.map_known and not hasattr(cls, "landmarks") \
            and not (isinstance(cls, type) and issubclass(cls, DeadReckoning)) \
            and (kinds is None or beacon_kinds & set(kinds)) \
            and any(s.kind in beacon_kinds for s in scenario.sensors):
        return (f"note: {filter_display_name(spec)} has no landmarks() and {scenario.name} does not "
                f"give the filters the beacon map: a localization filter is switched off at its "
                f"first reading of a beacon it was not given (docs/slam.md; try ekf_slam, fastslam)")
    if kinds is None or any(s.kind in kinds for s in scenario.sensors):
        return None
    if getattr(cls, "weighs_kind_models", False) and any(
            s.kind not in sensor_kinds.BUILTIN and sensor_kinds.model_of(s.kind) is not None
            for s in scenario.sensors):
        return None   # a kind it has no form of, weighed with its record's model
    have = ", ".join(sorted({s.kind for s in scenario.sensors})) or "no sensors"
    return (f"note: {filter_display_name(spec)} uses {' / '.join(kinds)} readings and "
            f"{scenario.name} has {have}: it only predicts (dead reckoning)")


def reset_filter(flt: Filter, scenario: Scenario) -> None:
    """Give a filter the scenario's initial belief (a broad Gaussian when the scenario is
    global but the filter cannot represent a uniform belief)."""
    init = initial_belief(scenario)
    if init is None and not getattr(flt, "supports_global", False):
        init = broad_gaussian(scenario.world)
    flt.reset(init)


__all__ = [
    "BUILTIN_FILTERS",
    "FILTER_METHODS",
    "FUNCTIONS",
    "FilterLoadError",
    "available_filters",
    "build_filter",
    "build_filters",
    "build_from_context",
    "check_param_names",
    "choose_filter",
    "filter_display_name",
    "filter_names",
    "function_filter_class",
    "implements_filter",
    "import_file",
    "initial_belief",
    "load_filter_class",
    "split_label",
]
