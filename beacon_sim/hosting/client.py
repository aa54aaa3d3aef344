"""The one client of the child protocol: what every front end that hosts a filter in a
process of its own (``eval``, ``check``, ``grade``) calls, so that none of them speaks the
wire (:mod:`beacon_sim.hosting.wire`).

- :func:`step_request`: one simulated tick as the child reads it (control, dt, readings);
- :func:`start_child`: the one place a filter's child process is started
  (:class:`~beacon_sim.hosting.isolated.FilterChild`, contained as
  :mod:`beacon_sim.hosting.containment` says);
- :class:`ChildSession`: a child's life over a series of runs: started when first needed,
  started afresh after one that must not be reused, never again after its file failed to
  load, its CPU time summed;
- :func:`hosted_context` and :func:`hosted_slot`: what a hosted filter is given for one run
  (:class:`~beacon_sim.filters.base.FilterContext`, built as every front end builds it), fed
  by :func:`~beacon_sim.hosting.feed.feed_batch`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.streams import keyed_stream
from beacon_sim.filters.base import FilterContext
from beacon_sim.hosting.containment import Limits, ModuleSource
from beacon_sim.hosting.feed import Fed, Slot, feed_batch, judge_probes, probe_slots, slot_order, step_request
from beacon_sim.hosting.isolated import MIN_REPLY_TIMEOUT_S, ChildFailure, FilterChild
from beacon_sim.hosting.loading import initial_belief


def start_child(source: Path | ModuleSource, class_name: str | None, log: Path, sandbox: str,
                limits: Limits, reply_timeout_s: float = MIN_REPLY_TIMEOUT_S) -> FilterChild:
    """A fresh child process hosting the filter of ``source`` (a file, or a module's package)
    and class ``class_name`` (None: the file's choice), its output to ``log``, contained at
    ``sandbox`` level within ``limits``, each answer awaited at most ``reply_timeout_s`` [s].
    Raises :class:`~beacon_sim.hosting.isolated.ChildFailure` (the file does not load)."""
    return FilterChild(source, class_name, log, sandbox, limits, reply_timeout_s)


class ChildSession:
    """One filter's child process over a series of runs (``with`` closes it).

    :meth:`child` starts it when none is running (None, and never tried again, once its
    file failed to load: ``load_problem`` says why); :meth:`stop` closes it (a child that
    must not be reused, or one whose runs are to be fed one at a time afresh). ``form`` is
    how the file gave its filter (``class`` or ``functions``) and ``cpu_s`` the CPU time
    [s] its children said they used (their own word: cost figures only)."""

    def __init__(self, source: Path | ModuleSource, class_name: str | None, log: Path, sandbox: str,
                 limits: Limits, reply_timeout_s: float = MIN_REPLY_TIMEOUT_S):
        self._start = (source, class_name, log, sandbox, limits, reply_timeout_s)
        self.current: FilterChild | None = None
        self.load_problem: str | None = None
        self.form: str | None = None
        self.cpu_s = 0.0

    def child(self) -> FilterChild | None:
        """The running child, started if needed; None when the file does not load."""
        if self.load_problem is None and self.current is None:
            try:
                self.current = start_child(*self._start)
                self.form = self.current.form
            except ChildFailure as exc:
                self.load_problem = str(exc)
        return self.current

    def stop(self) -> None:
        """Close the running child, if any (the next :meth:`child` starts a fresh one)."""
        child, self.current = self.current, None
        if child is not None:
            self.cpu_s += child.reported_cpu_s
            child.close()

    def __enter__(self) -> ChildSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def hosted_context(scenario: Scenario, key: bytes, name: str,
                   params: Mapping[str, Any] | None) -> FilterContext:
    """The context a hosted filter ``name`` gets for a run of ``scenario`` keyed by ``key``
    (:func:`~beacon_sim.core.streams.run_key`): what it may see, its parameters (default the
    scenario's ``[filters.NAME]``) and its own random generator (its name's stream of the
    key: never the seed)."""
    return FilterContext.of_scenario(scenario, name,
                                     dict(scenario.filter_params.get(name, {})) if params is None else params,
                                     keyed_stream(key, name))


def hosted_slot(scenario: Scenario, key: bytes, name: str, params: Mapping[str, Any] | None,
                frames: Sequence[bytes], ticks: int | None = None) -> Slot:
    """The :class:`~beacon_sim.hosting.feed.Slot` of hosted filter ``name`` on a run of
    ``scenario`` keyed by ``key``: fed ``frames`` (its :func:`step_request` per tick), all of
    them or the first ``ticks``."""
    return Slot(hosted_context(scenario, key, name, params), initial_belief(scenario), frames,
                len(frames) if ticks is None else min(ticks, len(frames)), name)


__all__ = ["MIN_REPLY_TIMEOUT_S", "ChildFailure", "ChildSession", "Fed", "FilterChild", "Slot",
           "feed_batch", "hosted_context", "hosted_slot", "judge_probes", "probe_slots", "slot_order",
           "start_child", "step_request"]
