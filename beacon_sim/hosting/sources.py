"""Which filters ``eval``, ``check`` and ``grade`` host in a child process of their own
(:mod:`beacon_sim.hosting.isolated`), and where the child gets their code: a file, or a
module's top-level package (:class:`~beacon_sim.hosting.containment.ModuleSource`)."""

from __future__ import annotations

from pathlib import Path

from beacon_sim.hosting.containment import ModuleSource, module_source
from beacon_sim.hosting.loading import (
    BUILTIN_FILTERS,
    FilterLoadError,
    entry_point_filters,
    is_file_spec,
    split_label,
)


def hosted_source(spec: str) -> tuple[Path | ModuleSource, str | None] | None:
    """Where the filter named ``spec`` comes from when ``eval``, ``check`` and ``grade`` host
    it in a child process: a file (``path.py[:Class]``), a module (``pkg.mod:Class``) or an
    entry point's module, with the class name (None: the file's choice). None for the
    built-in filters and ``beacon_sim``'s own modules (they may run in process) and for
    names that are no filter (loading them in process says why, in one line). A module
    that cannot be found raises :class:`~beacon_sim.hosting.loading.FilterLoadError`;
    nothing of the module runs here."""
    bare = split_label(spec)[1]
    if is_file_spec(spec):
        target, _, cls = bare.rpartition(":") if ":" in bare else (bare, "", "")
        return Path(target), cls or None
    if bare in BUILTIN_FILTERS:
        return None
    if ":" in bare:
        module, _, cls = bare.rpartition(":")
        if "/" in module or "\\" in module or not module:
            return None
    else:
        ep = entry_point_filters().get(bare)
        if ep is None:
            return None
        module, _, cls = ep.value.partition(":")
        module, cls = module.strip(), cls.strip()
    if module.partition(".")[0] == "beacon_sim":
        return None
    found = module_source(module)
    if found is None:
        raise FilterLoadError(f"{spec}: cannot import module {module!r}: no such module on the "
                              "import path")
    return found, cls or None


__all__ = ["hosted_source"]
