"""Hot reload in the window: a filter given as ``path.py:Class`` is watched, and when its file
changes the new version is swapped in between ticks (caught up on the run so far), or the
error is shown and the previous version keeps running.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from beacon_sim.runs.live import Session

if TYPE_CHECKING:  # imported where used: the window opens without it
    from beacon_sim.hosting.hot_reload import FilterFileWatcher


class FilterReloading:
    """The window's file watchers (``window.App`` is made of them)."""

    # What reloading reads and changes, all set up by the window (window.App.__init__).
    session: Session
    now: float  # the window's clock [s]
    watchers: dict[str, FilterFileWatcher]
    reload_errors: dict[str, str]  # filter name -> last failed reload (one line)
    world_version: int

    def flash(self, text: str) -> None:
        raise NotImplementedError  # a banner (actions.WindowActions.flash)

    def _make_watchers(self, interval: float) -> dict[str, FilterFileWatcher]:
        """A file watcher for every filter given as ``path.py:Class``, on the window's clock
        (``self.now``: real seconds, or 1/60 s per frame when scripted)."""
        from beacon_sim.hosting.hot_reload import FilterFileWatcher
        from beacon_sim.hosting.loading import filter_display_name

        s = self.session
        out: dict[str, FilterFileWatcher] = {}
        if not isinstance(s, Session):  # a finished run played back: nothing to reload
            return out
        for spec, name in zip(s.specs, s.names, strict=True):
            if not spec.rpartition(":")[0].endswith(".py"):
                continue
            assert s.seed is not None  # Session.__post_init__ chose it
            w = FilterFileWatcher(spec, s.scenario, s.seed, name=name,
                                  params=s.params.get(filter_display_name(spec)),
                                  interval=interval, clock=lambda: self.now)
            if w.watchable:
                out[name] = w
        return out

    def poll_watchers(self) -> None:
        """Reload the filters whose file changed: swap the new one in, or show the error and
        keep the previous version (traceback to stderr)."""
        for name, w in self.watchers.items():
            res = w.poll()
            if res.new_filter is not None:
                how = self.swap_filter(name, res.new_filter)
                self.reload_errors.pop(name, None)
                self.flash(f"{res.message}; {how}")
            elif res.error is not None:
                self.reload_errors[name] = res.error
                self.flash(res.error)
                if res.traceback:
                    print(res.traceback, file=sys.stderr, end="")
                print(f"beacon-sim: {res.error}", file=sys.stderr)

    def after_tick(self, step) -> None:
        raise NotImplementedError  # what the window does after each tick shown (window.App)

    def swap_filter(self, name: str, flt) -> str:
        """Replace a running filter (hot reload of a student's file); says how it caught up.
        With the filters on a worker, its ticks are finished and shown first."""
        self.world_version += 1
        self.session.settle(self.after_tick)
        return self.session.replace_filter(name, flt)
