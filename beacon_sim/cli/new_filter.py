"""``beacon-sim new-filter PATH [--team | --slam | --scan | --tdoa | --gauss-newton]``: write a
working, commented filter template (a team filter's with ``--team``, a SLAM filter's with
``--slam``, a scan-based particle filter's with ``--scan``, a range-difference EKF's with
``--tdoa``), or with ``--gauss-newton`` a graph SLAM solver's step for ``beacon-sim graph --solver``."""

from __future__ import annotations

import argparse
from pathlib import Path

from beacon_sim.core.files import create_text_new
from beacon_sim.errors import UsageError
from beacon_sim.templates import (
    class_name_for,
    render_gauss_newton_template,
    render_scan_template,
    render_slam_template,
    render_tdoa_template,
    render_team_template,
    render_template,
)

#: The templates by kind: how to write it, what the class is, and the scenario and built-in
#: filter the next steps suggest playing it beside.
TEMPLATES = {
    "filter": (render_template, "the class {cls} (dead reckoning, with TODOs for the update)",
               "", "ekf"),
    "team": (render_team_template, "the team filter class {cls} (each robot's own EKF, with a "
             "TODO for the robot-to-robot readings)", "team_sparse ", "centralised"),
    "slam": (render_slam_template, "the SLAM filter class {cls} (it maps each beacon from its "
             "first reading, with a TODO for the EKF-SLAM correction)", "slam_loop ", "ekf_slam"),
    "scan": (render_scan_template, "the scan-based particle filter class {cls} (a small MCL "
             "on the map's likelihood field, with TODOs for recovery and KLD-sampling)", "office ",
             "mcl"),
    "tdoa": (render_tdoa_template, "the TDOA filter class {cls} (an EKF on range differences, "
             "with a TODO for their correlated covariance)", "ulps_leave ", "ekf"),
    "gauss_newton": (render_gauss_newton_template, "the graph SLAM solver class {cls} (its step "
                     "builds the normal equations and walks down the gradient, with a TODO for the "
                     "Gauss-Newton solve)", "slam_loop", "gn"),
}

#: The options that choose a kind other than the plain filter's (at most one of them).
KIND_OPTIONS = ("team", "slam", "scan", "tdoa", "gauss_newton")
#: The scenario ``check`` needs for a kind whose filter does nothing on the default one.
CHECK_ON = {"scan": "corridor", "tdoa": "ruiz_ulps"}


def new_filter_command(args: argparse.Namespace) -> int:
    """Write the template to ``args.path`` (never over an existing file); print next steps."""
    path = Path(args.path)
    if path.suffix != ".py":
        raise UsageError(f"new-filter {path}: the file name must end in .py")
    if path.exists():
        raise UsageError(f"new-filter {path}: the file exists; choose another name")
    if not path.parent.is_dir():
        raise UsageError(f"new-filter {path}: no folder {path.parent}")
    chosen = [k for k in KIND_OPTIONS if getattr(args, k, False)]
    if len(chosen) > 1:
        raise UsageError(f"new-filter: {' and '.join('--' + k.replace('_', '-') for k in chosen)} "
                         "cannot be combined; "
                         "choose one")
    kind = chosen[0] if chosen else "filter"
    render, what, scenario, beside = TEMPLATES[kind]
    cls = class_name_for(path)
    shown = path.as_posix() if path.is_absolute() or "/" in path.as_posix() else f"./{path.name}"
    try:   # created only if no file has that name at that moment (not just at the check above)
        create_text_new(path, render(cls, path.name), what="filter file", error=UsageError)
    except UsageError as exc:
        raise UsageError(f"new-filter {exc}") from None
    print(f"wrote {path} with {what.format(cls=cls)}")
    print("next:")
    if kind == "gauss_newton":  # a solver, not a filter: the graph command runs it
        print(f"  beacon-sim graph {scenario} --solver {shown}:{cls} --headless")
        print(f"  beacon-sim graph {scenario} --solver {shown}:{cls}     # N: one step")
        return 0
    check_on = f" --scenario {CHECK_ON[kind]}" if kind in CHECK_ON else ""
    print(f"  beacon-sim check {shown}:{cls}{check_on}")
    print(f"  beacon-sim play {scenario}--filter {shown}:{cls} --filter {beside}")
    return 0
