"""``beacon-sim new-filter PATH [--team | --slam]``: write a working, commented filter template
(a team filter's with ``--team``, a SLAM filter's with ``--slam``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from beacon_sim.errors import UsageError
from beacon_sim.filters.slam_template import render_slam_template
from beacon_sim.filters.team_template import render_team_template
from beacon_sim.filters.template import class_name_for, render_template

#: The templates by kind: how to write it, what the class is, and the scenario and built-in
#: filter the next steps suggest playing it beside.
TEMPLATES = {
    "filter": (render_template, "the class {cls} (dead reckoning, with TODOs for the update)",
               "", "ekf"),
    "team": (render_team_template, "the team filter class {cls} (each robot's own EKF, with a "
             "TODO for the robot-to-robot readings)", "team_sparse ", "centralised"),
    "slam": (render_slam_template, "the SLAM filter class {cls} (it maps each beacon from its "
             "first reading, with a TODO for the EKF-SLAM correction)", "slam_loop ", "ekf_slam"),
}


def new_filter_command(args: argparse.Namespace) -> int:
    """Write the template to ``args.path`` (never over an existing file); print next steps."""
    path = Path(args.path)
    if path.suffix != ".py":
        raise UsageError(f"new-filter {path}: the file name must end in .py")
    if path.exists():
        raise UsageError(f"new-filter {path}: the file exists; choose another name")
    if not path.parent.is_dir():
        raise UsageError(f"new-filter {path}: no folder {path.parent}")
    if getattr(args, "team", False) and getattr(args, "slam", False):
        raise UsageError("new-filter: --team and --slam cannot be combined; choose one")
    kind = "slam" if getattr(args, "slam", False) else "team" if getattr(args, "team", False) else "filter"
    render, what, scenario, beside = TEMPLATES[kind]
    cls = class_name_for(path)
    shown = path.as_posix() if path.is_absolute() or "/" in path.as_posix() else f"./{path.name}"
    path.write_text(render(cls, path.name), encoding="utf-8")
    print(f"wrote {path} with {what.format(cls=cls)}")
    print("next:")
    print(f"  beacon-sim check {shown}:{cls}")
    print(f"  beacon-sim play {scenario}--filter {shown}:{cls} --filter {beside}")
    return 0
