"""The sections of results.md in their order (``FIGURES``), writing them, and
``--check-seeds``: every seeded figure re-run from ``CHECK_SEED`` and compared."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable

from beacon_sim.evaluation.montecarlo import default_jobs
from beacon_sim.hosting.loading import available_filters

from .association import fig_lookalike, fig_unknown_ids
from .common import CHECK_SEED, CHECKS_FILE, DOCS, DOCS_SEED, FIG, Context, Figure, splice_section, with_iv
from .gaussian import (
    SMOOTHING_HEADER,
    fig_assignment,
    fig_default,
    fig_distance,
    fig_kf_consistency,
    fig_krejsa,
    fig_nees_alarm,
    fig_outliers,
    fig_smoothing,
    fig_ulps,
)
from .maps import (
    CORRIDOR_HEADER,
    fig_corridor,
    fig_corridor_ladder,
    fig_corridor_mcl,
    fig_map_bound,
    fig_office_kidnap,
    fig_office_sweep,
    fig_symmetric_before,
    fig_symmetric_room,
    fig_two_rooms,
)
from .mrclam import (
    ASSOCIATION_HEADER,
    MRCLAM_HEADER,
    SLAM_HEADER,
    fig_mrclam,
    fig_mrclam_association,
    fig_mrclam_slam,
    mrclam_folder,
)
from .particles import (
    STANDSTILL_HEADER,
    fig_global_kidnap,
    fig_global_start,
    fig_kidnap_trials,
    fig_pf_default,
    fig_pf_tempering,
    fig_standstill,
)
from .slam import (
    fig_bearing_only,
    fig_bearing_ring,
    fig_fastslam_association,
    fig_fastslam_ring,
    fig_graph_slam,
    fig_slam_loop,
)
from .team import fig_team_sparse


@dataclasses.dataclass(frozen=True)
class Entry:
    """A section of results.md: its name (``--only NAME``), its heading, the function that
    makes it, whether it is seeded (``--check-seeds`` re-runs the seeded ones) and the pages
    that quote it."""

    name: str
    header: str
    make: Callable[[Context], Figure]
    seeded: bool = True
    #: The pages (docs/*.md) that quote this section's figures: each links the section
    #: instead of printing numbers of its own (tests/project/test_make_results.py).
    quoted_in: tuple[str, ...] = ()


#: The sections of results.md, in their order. A new figure is a function above and a line here.
FIGURES: tuple[Entry, ...] = (
    Entry("default", "## Targets on `default`", fig_default, quoted_in=("evaluation.md",)),
    Entry("krejsa", "## [Seed 000](references.md#seed-000): EKF against UKF, bearing-only beacons, "
                    "with the kidnap", fig_krejsa, quoted_in=("filters.md",)),
    Entry("ulps", "## [Seed 002](references.md#seed-002): particle filter on the ULPS circle", fig_ulps),
    Entry("distance", "## [Seed 002](references.md#seed-002) at the level of its distances: tight "
                      "against loose coupling, and the naive TDOA update", fig_distance,
          quoted_in=("distance_beacons.md",)),
    Entry("assignment", "## [Seed 003](references.md#seed-003): the classroom KF — no beacon in view "
                        "against three", fig_assignment),
    Entry("kf_consistency", "## The KF against the EKF: where A = I matters", fig_kf_consistency,
          quoted_in=("filters.md",)),
    Entry("outliers", "## Outliers on `default`: the EKF's gate and the particle filter's mixture",
          fig_outliers, quoted_in=("evaluation.md",)),
    Entry("nees_alarm", "## The window's NEES badge: false alarms on a consistent EKF", fig_nees_alarm,
          quoted_in=("window.md",)),
    Entry("global_kidnap", "## Global localization and kidnaps: `global_kidnap`", fig_global_kidnap),
    Entry("global_start", "## The global start on `global_kidnap`: roughening and the grid filter",
          fig_global_start, quoted_in=("particle-and-grid.md",)),
    Entry("kidnap_trials", "## One random kidnap on `global_kidnap`: recovery within 15 s",
          fig_kidnap_trials, quoted_in=("particle-and-grid.md",)),
    Entry("pf_default", "## The particle filter on `default`: augmented MCL against the EKF",
          fig_pf_default, quoted_in=("particle-and-grid.md", "evaluation.md")),
    Entry("pf_tempering", "## Progressive correction: the particle filter on `assignment_kf`",
          fig_pf_tempering, quoted_in=("particle-and-grid.md",)),
    Entry("standstill", STANDSTILL_HEADER, fig_standstill),
    Entry("corridor", CORRIDOR_HEADER, fig_corridor),
    Entry("corridor_global", "## Global localization in the `corridor`: mcl and the corridor filter",
          fig_corridor_mcl, quoted_in=("maps.md",)),
    Entry("corridor_ladder", "## The corridor's mcl settings before the shipped ones, on unseen seeds",
          fig_corridor_ladder, quoted_in=("maps.md",)),
    Entry("slam_loop", "## SLAM on `slam_loop`: EKF-SLAM and FastSLAM 2.0 over seeded runs",
          fig_slam_loop, quoted_in=("slam.md",)),
    Entry("bearing_only", "## Bearing-only SLAM on `slam_bearing_only`: inverse depth against "
                          "delayed initialisation", fig_bearing_only, quoted_in=("slam.md",)),
    Entry("fastslam_association", "## FastSLAM without IDs: per-particle ML against JCBB on "
                                  "look-alike pairs", fig_fastslam_association, quoted_in=("slam.md",)),
    Entry("fastslam_ring", "## FastSLAM's reported covariance on a benign ring: the particles' against "
                           "the linearised", fig_fastslam_ring, quoted_in=("slam.md",)),
    Entry("bearing_ring", "## Bearing-only EKF-SLAM on a benign ring: the parallax threshold and inverse "
                          "depth", fig_bearing_ring, quoted_in=("slam.md",)),
    Entry("lookalike", "## Association without IDs: `lookalike_beacons`", fig_lookalike,
          quoted_in=("association.md",)),
    Entry("unknown_ids", "## Association without IDs: `default` with clutter", fig_unknown_ids,
          quoted_in=("association.md",)),
    Entry("team_sparse", "## Cooperative localization: `team_sparse`", fig_team_sparse,
          quoted_in=("multi-robot.md",)),
    Entry("office_kidnap", "## Kidnap recovery in the `office`: mcl", fig_office_kidnap,
          quoted_in=("maps.md",)),
    Entry("office_sweep", "## Tracking in the `office`: mcl's error and cost against its particle count",
          fig_office_sweep, quoted_in=("maps.md",)),
    Entry("symmetric_room", "## Two clouds in the `symmetric_room`: mcl", fig_symmetric_room,
          quoted_in=("maps.md",)),
    Entry("symmetric_before", "## The symmetric room's settings before the shipped ones, on unseen seeds",
          fig_symmetric_before, quoted_in=("maps.md",)),
    Entry("map_bound", "## The scan bound in the map worlds: mcl against the PCRB", fig_map_bound,
          quoted_in=("maps.md",)),
    Entry("two_rooms", "## Beacons behind walls: `two_rooms`", fig_two_rooms, quoted_in=("maps.md",)),
    Entry("mrclam", MRCLAM_HEADER, fig_mrclam, seeded=False),
    Entry("association", ASSOCIATION_HEADER, fig_mrclam_association, seeded=False,
          quoted_in=("association.md", "slam.md")),
    Entry("slam", SLAM_HEADER, fig_mrclam_slam, seeded=False, quoted_in=("slam.md",)),
    Entry("smoothing", SMOOTHING_HEADER, fig_smoothing),
    Entry("graph_slam", "## Graph SLAM on `slam_loop`: the whole drive at once against EKF-SLAM",
          fig_graph_slam, quoted_in=("smoothing.md",)),
)


def intro() -> list[str]:
    """results.md's opening paragraph: how the figures were made, which seeds."""
    return [
        "# Results", "",
        "Generated by `python scripts/make_results.py` (do not edit by hand; rerun it, or one "
        "section with `--only NAME`). How the figures are defined: [evaluation.md](evaluation.md). "
        f"**Seeds**: every Monte Carlo figure here is made on seeds {DOCS_SEED}, {DOCS_SEED + 1}, ... "
        "(each table says which), a range no test uses and nothing was tuned on; every filter "
        "sees the same simulated runs. `python scripts/make_results.py --check-seeds` re-runs "
        f"every seeded figure on a second range from seed {CHECK_SEED} and prints, per figure, "
        "whether the two 95 % intervals overlap ([evaluation.md](evaluation.md#seeds-of-the-docs-figures)). "
        "Brackets are 95 % bootstrap intervals over the runs (seeded: the same runs give the "
        "same interval). Costs (µs/step) were measured "
        f"on this machine ({platform.machine()}, {os.cpu_count()} cores, shared with other "
        "work) and vary by tens of per cent between runs; the other columns are reproducible "
        "bit for bit.", ""]


def make(entry: Entry, ctx: Context) -> Figure:
    t = time.perf_counter()
    fig = entry.make(ctx)
    print(f"figure {entry.name}: {time.perf_counter() - t:.0f} s", file=sys.stderr, flush=True)
    return fig


def load_checks() -> dict:
    try:
        return json.loads(CHECKS_FILE.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def save_checks(done: dict[str, Figure], ctx: Context) -> None:
    """Keep the checked quantities of the figures just made (merged into ``CHECKS_FILE``)."""
    from beacon_sim.core.files import write_text_atomic

    stored = load_checks()
    for name, fig in done.items():
        stored[name] = {"seed": ctx.seed, "scale": ctx.scale,
                        "checks": {k: [v, iv] for k, (v, iv) in fig.checks.items()}}
    write_text_atomic(CHECKS_FILE, json.dumps(stored, indent=1, sort_keys=True) + "\n")


def overlap(a: list | None, b: list | None) -> bool | None:
    """Whether two intervals [lo, hi] share a point (None ends: open); None without both."""
    if not a or not b:
        return None
    lo = max(x for x in (a[0], b[0]) if x is not None) if (a[0], b[0]) != (None, None) else -math.inf
    hi = min(x for x in (a[1], b[1]) if x is not None) if (a[1], b[1]) != (None, None) else math.inf
    return lo <= hi


#: How often two exact 95 % intervals of the same quantity, from disjoint seeds with equal
#: spread, share no point: |a - b| > 2 x 1.96 se with sd(a - b) = sqrt(2) se, so
#: P(|z| > 1.96 sqrt(2)) = 0.0056. Many quantities on one range (a filter's RMSE and its
#: ANEES) move together, so the disagreements come in groups.
CHANCE_APART = math.erfc(1.96)  # P(|z| > x) = erfc(x / sqrt(2)), x = 1.96 sqrt(2)


def check_seeds(entries: list[Entry], docs: Context, check: Context) -> int:
    """Every seeded figure's checked quantities on the docs range (as stored by the docs run,
    else run again) and on the check range; prints the table a row at a time as each figure
    finishes; 1 if any pair disagrees."""
    stored = load_checks()
    rows, differ = [], 0
    print(f"| figure | quantity | seeds {docs.seed}.. (docs) | seeds {check.seed}.. (check) "
          "| intervals overlap |")
    print("|---|---|---|---|---|", flush=True)
    for e in entries:
        if not e.seeded:
            continue
        kept = stored.get(e.name)
        if kept and kept.get("seed") == docs.seed and kept.get("scale") == docs.scale:
            a = {k: tuple(v) for k, v in kept["checks"].items()}
        else:
            a = make(e, docs).checks
        b = make(e, check).checks
        for q in a:
            if q not in b:
                continue
            ok = overlap(a[q][1], b[q][1])
            differ += ok is False
            rows.append(f"| {e.name} | {q} | {with_iv(a[q][0], a[q][1], '.3g')} "
                        f"| {with_iv(b[q][0], b[q][1], '.3g')} "
                        f"| {'-' if ok is None else 'yes' if ok else 'NO'} |")
            print(rows[-1], flush=True)  # as each figure finishes: a long run shows its way
        print(f"checked {e.name}", file=sys.stderr, flush=True)
    print(f"\n{len(rows)} quantities, {differ} whose intervals do not overlap; "
          f"{CHANCE_APART * len(rows):.1f} expected by chance alone ({CHANCE_APART:.2%} of pairs).")
    return 1 if differ else 0


def main(description: str) -> int:
    """The command line (``description``: its --help line)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--runs-scale", type=float, default=1.0, help="multiply every run count")
    ap.add_argument("--mrclam", metavar="DIR",
                    help="the MRCLAM data set (default: where BEACON_SIM_MRCLAM says; docs/mrclam.md)")
    ap.add_argument("--jobs", type=int, default=default_jobs())
    names = [e.name for e in FIGURES]
    ap.add_argument("--only", metavar="NAME[,NAME]",
                    help=f"regenerate only these sections of results.md ({', '.join(names)})")
    ap.add_argument("--check-seeds", action="store_true",
                    help=f"re-run the seeded figures on seeds {CHECK_SEED}.. and print whether "
                         "their intervals agree with the docs' (changes no file)")
    args = ap.parse_args()
    only = args.only.split(",") if args.only else names
    bad = [x for x in only if x not in names]
    if bad:
        ap.error(f"--only {','.join(bad)}: expected one of {', '.join(names)}")
    entries = [e for e in FIGURES if e.name in only]
    have = set(available_filters())
    if args.check_seeds:
        return check_seeds(entries, Context(DOCS_SEED, args.runs_scale, args.jobs, have, draw=False),
                           Context(CHECK_SEED, args.runs_scale, args.jobs, have, draw=False))
    folder = mrclam_folder(args.mrclam) if any(not e.seeded for e in entries) else None
    if folder is None and args.only and all(not e.seeded for e in entries):
        return 2  # nothing to regenerate it from: the section stays as it is
    ctx = Context(DOCS_SEED, args.runs_scale, args.jobs, have, mrclam=folder)
    FIG.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    done = {e.name: make(e, ctx) for e in entries}
    path = DOCS / "results.md"
    if args.only:
        text = path.read_text(encoding="utf-8")
        lines = text.split("\n")
        first = next((i for i, x in enumerate(lines) if x.startswith("## ")), len(lines))
        text = "\n".join(intro() + lines[first:])
        for e in entries:
            section = [e.header, "", *done[e.name].md]
            if e.header in text.split("\n"):
                text = splice_section(text, e.header, section)
            else:  # a new section: before the one that follows it in FIGURES, else at the end
                after = [x.header for x in FIGURES[FIGURES.index(e) + 1:] if x.header in text.split("\n")]
                mark = after[0] if after else "_Generated"
                text = text.replace("\n" + mark, "\n" + "\n".join(section) + "\n" + mark, 1)
    else:
        text = "\n".join(intro() + [x for e in entries for x in (e.header, "", *done[e.name].md)]
                         + [f"_Generated in {time.perf_counter() - t_all:.0f} s._", ""])
    path.write_text(text, encoding="utf-8")
    save_checks({k: v for k, v in done.items() if v.checks}, ctx)
    print(f"wrote {', '.join(done)} into {path} in {time.perf_counter() - t_all:.0f} s", file=sys.stderr)
    return 0
