"""The ``beacon-sim new-filter`` templates: each a real module that runs as it is, which
``new-filter`` copies, putting the user's class and file names where the module has its own.

- ``my_filter.py`` (``new-filter PATH``): dead reckoning, with TODOs that lead to an EKF
  update and pointers to the core's models and Jacobians (docs/writing-a-filter.md);
- ``my_team.py`` (``--team``): every robot's own EKF on its beacon readings (the
  ``independent`` baseline, bit for bit), with a TODO for the robot-to-robot readings
  (docs/multi-robot.md);
- ``my_slam.py`` (``--slam``): one Gaussian over the pose and the landmarks that puts each
  newly seen beacon on its map, with a TODO that turns it into EKF-SLAM (docs/slam.md);
- ``my_scan.py`` (``--scan``): a small Monte Carlo localization weighting its particles by a
  laser scan with the map's likelihood field, with TODOs towards the built-in ``mcl``
  (docs/maps.md);
- ``my_tdoa.py`` (``--tdoa``): an EKF on range differences against a reference beacon with
  the naive independent-difference covariance, with a TODO for the true correlated one
  (docs/distance_beacons.md);
- ``my_gauss_newton.py`` (``--gauss-newton``): a graph SLAM solver whose step builds the
  normal equations edge by edge and walks down the gradient, with a TODO that makes it the
  built-in Gauss-Newton step (``beacon-sim graph --solver``; docs/smoothing.md).

Being modules, they are read by ruff, mypy and the import contracts as the rest of the
package is, and what a student gets is exactly what is checked (tests/filters/test_filter_families.py).
"""

from __future__ import annotations

import keyword
import re
from importlib import resources
from pathlib import Path

#: Each kind of template: its module, whose class and file names are the ones replaced.
TEMPLATES = {"filter": ("my_filter", "MyFilter"), "team": ("my_team", "MyTeam"),
             "slam": ("my_slam", "MySlam"), "scan": ("my_scan", "MyScan"),
             "tdoa": ("my_tdoa", "MyTdoa"),
             "gauss_newton": ("my_gauss_newton", "MyGaussNewton")}


def source(kind: str) -> str:
    """The text of ``kind``'s template module, as it is in the package."""
    module, _ = TEMPLATES[kind]
    return resources.files(__name__).joinpath(f"{module}.py").read_text(encoding="utf-8")


def render(kind: str, class_name: str, file_name: str) -> str:
    """The text ``new-filter`` writes: ``kind``'s module with ``class_name`` for its class's
    name and ``file_name`` for its own file name (one pass: a replaced name is never
    replaced again)."""
    if not class_name.isidentifier() or keyword.iskeyword(class_name):
        raise ValueError(f"{class_name!r} is not a valid Python class name")
    module, cls = TEMPLATES[kind]
    names = {cls: class_name, f"{module}.py": file_name}
    pattern = re.compile(rf"\b{cls}\b|\b{module}\.py\b")
    return pattern.sub(lambda m: names[m.group(0)], source(kind))


def render_template(class_name: str, file_name: str) -> str:
    """The filter template's text for ``class_name`` in a file named ``file_name``."""
    return render("filter", class_name, file_name)


def render_team_template(class_name: str, file_name: str) -> str:
    """The team template's text for ``class_name`` in a file named ``file_name``."""
    return render("team", class_name, file_name)


def render_slam_template(class_name: str, file_name: str) -> str:
    """The SLAM template's text for ``class_name`` in a file named ``file_name``."""
    return render("slam", class_name, file_name)


def render_scan_template(class_name: str, file_name: str) -> str:
    """The scan template's text for ``class_name`` in a file named ``file_name``."""
    return render("scan", class_name, file_name)


def render_tdoa_template(class_name: str, file_name: str) -> str:
    """The TDOA template's text for ``class_name`` in a file named ``file_name``."""
    return render("tdoa", class_name, file_name)


def render_gauss_newton_template(class_name: str, file_name: str) -> str:
    """The Gauss-Newton template's text for ``class_name`` in a file named ``file_name``."""
    return render("gauss_newton", class_name, file_name)


def class_name_for(path: Path) -> str:
    """``my_filter.py`` -> ``MyFilter``; a name that is not an identifier -> ``MyFilter``."""
    words = [w for w in re.split(r"[^0-9A-Za-z]+", path.stem) if w]
    name = "".join(w[:1].upper() + w[1:] for w in words)
    if not name or not name.isidentifier() or name[0].isdigit() or keyword.iskeyword(name):
        return "MyFilter"
    return name


__all__ = ["TEMPLATES", "class_name_for", "render", "render_gauss_newton_template",
           "render_scan_template", "render_slam_template", "render_tdoa_template",
           "render_team_template", "render_template", "source"]
