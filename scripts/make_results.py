"""Regenerate docs/results.md and docs/results/*.png in one run (tens of minutes on 2 shared cores).

Usage: python scripts/make_results.py [--runs-scale F] [--mrclam DIR] [--jobs J] [--only NAME[,NAME]]
       [--check-seeds]

Every number in docs/results.md comes from this script: the seeds' findings (000 Krejsa
EKF/UKF bearing-only, 001 MRCLAM, 002 ULPS particle filter, 003 the classroom KF, 004 the
corridor's discrete Bayes filter), the evaluation's targets on `default`, global localization
with kidnaps (`global_kidnap`), and the Monte Carlo figures the other pages quote (SLAM on
`slam_loop`, bearing-only SLAM, FastSLAM's association without IDs and its covariance, graph
SLAM, association without IDs, `team_sparse`, the office's kidnap recovery and particle-count
sweep, the symmetric room's two clouds, mcl against the scan bound, `two_rooms`, the KF against
the EKF, outliers, the window's NEES badge, the particle filter's kidnap trials, injection and
progressive correction; each entry's ``quoted_in``). Monte Carlo runs use seeds DOCS_SEED,
DOCS_SEED + 1, ... (``--check-seeds``: CHECK_SEED, ...); the same command gives the same
tables (except the cost columns, which are measured).

The figures live in the package ``scripts/results/``: one module per group of sections
(``gaussian``, ``particles``, ``maps``, ``slam``, ``association``, ``team``, ``mrclam``), the
shared helpers in ``common`` and the list of sections, the writing and the seed check in
``registry``. A new figure is a ``fig_*`` function in one of them and a line in
``registry.FIGURES``."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the results package beside this file

from results.common import CHECK_SEED, DOCS_SEED, run, wilson_interval
from results.registry import FIGURES, main, overlap

__all__ = ["CHECK_SEED", "DOCS_SEED", "FIGURES", "main", "overlap", "run", "wilson_interval"]

if __name__ == "__main__":
    raise SystemExit(main(__doc__.splitlines()[0]))
