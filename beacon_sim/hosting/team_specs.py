"""Team filter specs: what ``run``, ``play``, ``eval`` and ``grade`` accept as a
filter of a team run, and how each is named and built.

- a name of :data:`~beacon_sim.filters.team.TEAM_FILTERS` (``centralised``, ``ci``, ...): one
  team filter over the joint state;
- a student's team filter class (``my_team.py:MyTeam``, ``pkg.mod:Class``): the same;
- ``independent:F`` (optionally labelled ``alice=independent:./alice.py:MyEkf``): every
  robot's own single-robot filter F (a built-in, an entry point or a file), beacon readings
  only. :class:`~beacon_sim.hosting.team_runner.TeamRunner` runs one copy of F per robot under
  the single-robot guard; :func:`build_team_spec` wraps the copies in one
  :class:`~beacon_sim.filters.team.IndependentTeam` for code that wants a team filter object.
"""

from __future__ import annotations

from functools import partial
from typing import Any

from beacon_sim.core.scenario import TeamScenario
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.team import (
    TEAM_FILTERS,
    IndependentTeam,
    TeamFilter,
    build_team_filter,
    initial_beliefs,
    team_context,
)
from beacon_sim.hosting.loading import (
    BUILD_LIMIT_S,
    build_filter,
    filter_display_name,
    load_filter_class,
    split_label,
)
from beacon_sim.hosting.runner import run_filter_code

#: ``independent:F``: every robot's own single-robot filter F (a built-in name, pkg.mod:Class
#: or file.py:Class), beacon readings only.
MEMBER_PREFIX = "independent:"


def team_filter_name(spec: str) -> str:
    """The name a team filter spec is shown and ``--set`` under: its label, else the spec
    (a student's team filter class ``my_team.py:MyTeam``: its class name, ``MyTeam``)."""
    label, body = split_label(spec)
    if label:
        return label
    if body in TEAM_FILTERS or body.startswith(MEMBER_PREFIX):
        return body
    return filter_display_name(body)


def build_team_class(spec: str, team: TeamScenario, params: dict[str, Any] | None,
                     seed: int) -> TeamFilter:
    """A student's own team filter: a class (``file.py:Class``, ``pkg.mod:Class``) built with
    a :class:`~beacon_sim.filters.team.TeamContext` and reset to the scenario's initial
    beliefs. A single-robot filter class given here is a FilterError that says to use
    ``independent:``."""
    _, body = split_label(spec)
    cls = load_filter_class(body)
    if not callable(getattr(cls, "estimates", None)):
        raise FilterError(f"{body}: {getattr(cls, '__name__', cls)!s} is not a team filter (it has no "
                          f"estimates()); to run a single-robot filter on every robot use "
                          f"independent:{body}")
    name = team_filter_name(spec)
    merged = {**team.filter_params.get(name, {}), **(params or {})}
    f = cls(team_context(team, name, merged, seed))
    f.reset(initial_beliefs(team))
    return f


def build_team_spec(spec: str, team: TeamScenario, params: dict[str, Any] | None = None,
                    seed: int | None = None) -> TeamFilter:
    """A team filter from a spec: a name of ``filters.team.TEAM_FILTERS``; a student's team
    filter class (``my_team.py:MyTeam``, see :func:`build_team_class`); or ``independent:F``
    (optionally labelled ``alice=independent:./alice.py:MyEkf``): every robot's own
    single-robot filter F, built as ``run`` builds it for that robot's scenario (its
    parameters: the scenario's ``[filters.F]`` then ``params``), wrapped in
    :class:`~beacon_sim.filters.team.IndependentTeam`. Raises FilterError for a name or
    parameter that cannot work; a filter's own failing code raises what it raises."""
    name = team_filter_name(spec)
    _, body = split_label(spec)
    if not body.startswith(MEMBER_PREFIX):
        if body not in TEAM_FILTERS and ":" in body:
            return build_team_class(spec, team, params, team.seed if seed is None else seed)
        return build_team_filter(body, team, params, seed)
    member = body[len(MEMBER_PREFIX):]
    if not member:
        raise FilterError(f"{spec}: expected independent:FILTER, e.g. independent:ukf")
    seed = team.seed if seed is None else seed
    members = iter([build_filter(member, r.scenario, seed, name=f"{name}/{r.id}", params=params)
                    for r in team.robots])
    f = IndependentTeam(team_context(team, name, None, seed), member=lambda _ctx: next(members))
    f.reset(initial_beliefs(team))
    return f


def check_team_specs(specs: list[str], team: TeamScenario,
                     params: dict[str, dict[str, Any]] | None = None,
                     limit_s: float = BUILD_LIMIT_S) -> None:
    """Raise FilterError (one line, exit status 2 on the command line) for a team filter
    name, a ``--set`` name or a parameter that cannot work, before anything runs. A
    filter whose own code fails when built (raising, exiting, or still building after
    ``limit_s`` [s]) is left to the run (it fails there, no score)."""
    names = [team_filter_name(s) for s in specs]
    if len(set(names)) < len(names):
        raise FilterError(f"a team filter named twice in {', '.join(names)}")
    for name in params or {}:
        if name not in names:
            raise FilterError(f"--set {name}.*: no team filter {name!r} in this run; the filters are "
                              f"{', '.join(names)}")
    for spec in specs:
        _, body = split_label(spec)
        if not body.startswith(MEMBER_PREFIX) and body not in TEAM_FILTERS and ":" not in body:
            raise FilterError(f"no team filter named {body!r}; choose one of "
                              f"{', '.join(TEAM_FILTERS)}, independent:FILTER or a team filter "
                              "class (file.py:Class)")
        try:
            run_filter_code(partial(build_team_spec, spec, team,
                                    (params or {}).get(team_filter_name(spec)), team.seed),
                            limit_s, "construction")
        except FilterError:
            raise
        except Exception:  # the filter's own code: a failed filter in the run, no score
            pass


def member_spec(spec: str) -> str | None:
    """The single-robot filter F of an ``independent:F`` spec (its label dropped), or None for
    a team filter spec."""
    _, body = split_label(spec)
    return body[len(MEMBER_PREFIX):] if body.startswith(MEMBER_PREFIX) else None
