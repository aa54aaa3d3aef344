"""scripts/make_results.py's seed discipline: the docs' figures are made on seeds no test
uses, the check re-runs them on a second disjoint range, and every section is one registry
entry."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def make_results():
    spec = importlib.util.spec_from_file_location("make_results", ROOT / "scripts" / "make_results.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_results"] = module        # dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop("make_results", None)


#: A seed a test passes: ``seed=N``, ``seeds=(N, ...)``, ``seed = N``, ``Simulation(sc, N)``'s
#: keyword forms, and ``for seed in range(A, B)``.
SEED_LITERAL = re.compile(r"seeds?\w*\s*=\s*\(?\s*(\d+)")
SEED_RANGE = re.compile(r"seed\w*\s+in\s+range\(\s*(\d+)\s*,\s*(\d+)")


def test_no_test_uses_the_docs_or_the_check_seeds(make_results):
    """The first 10,000 seeds from each range are the figures' (the most runs a figure
    makes is 100): no seed a test passes may fall there."""
    ranges = [(make_results.DOCS_SEED, make_results.DOCS_SEED + 10_000),
              (make_results.CHECK_SEED, make_results.CHECK_SEED + 10_000)]
    assert ranges[0][1] <= ranges[1][0]
    found = []
    for path in sorted((ROOT / "tests").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        seeds = [(int(m.group(1)), int(m.group(1)) + 1) for m in SEED_LITERAL.finditer(text)]
        seeds += [(int(m.group(1)), int(m.group(2))) for m in SEED_RANGE.finditer(text)]
        for a, b in seeds:
            if any(a < hi and lo < b for lo, hi in ranges):
                found.append(f"{path.name}: seeds {a}..{b - 1}")
    assert not found, found
    # the pattern does find the seeds tests use (it is not blind)
    here = Path(__file__).read_text(encoding="utf-8")
    assert SEED_LITERAL.search("run_monte_carlo(sc, ['pf'], 4, seed=5000, jobs=1)").group(1) == "5000"
    assert SEED_RANGE.search("for seed in range(300, 330)").groups() == ("300", "330")
    assert "DOCS_SEED" in here


def test_every_section_is_one_registry_entry(make_results):
    names = [e.name for e in make_results.FIGURES]
    headers = [e.header for e in make_results.FIGURES]
    assert len(set(names)) == len(names) and len(set(headers)) == len(headers)
    assert all(h.startswith("## ") for h in headers)
    assert {"default", "krejsa", "corridor", "corridor_global"} <= set(names)
    assert all(e.seeded for e in make_results.FIGURES if e.name not in ("mrclam", "association", "slam"))


def test_every_seeded_section_of_the_docs_names_its_seeds(make_results):
    """results.md as committed: each seeded section says it was made from DOCS_SEED on."""
    text = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    for e in make_results.FIGURES:
        if not e.seeded:
            continue
        assert e.header in text, e.header
        body = text.split(e.header, 1)[1].split("\n## ", 1)[0]
        assert f"seeds {make_results.DOCS_SEED}.." in body, e.name


def test_intervals_agree_when_they_share_a_point(make_results):
    overlap = make_results.overlap
    assert overlap([1.0, 2.0], [2.0, 3.0]) is True
    assert overlap([1.0, 2.0], [2.1, 3.0]) is False
    assert overlap([None, 2.0], [1.5, None]) is True       # open ends
    assert overlap([5.0, None], [1.0, 4.0]) is False
    assert overlap(None, [1.0, 2.0]) is None                # nothing to compare


def test_wilson_interval_by_hand(make_results):
    """7 of 40 (the issue's corridor figure): [0.09, 0.32]."""
    lo, hi = make_results.wilson_interval(7, 40)
    assert round(lo, 2) == 0.09 and round(hi, 2) == 0.32
    assert make_results.wilson_interval(40, 40)[1] == 1.0


def test_make_results_reports_progress_in_a_log(make_results, capsys, monkeypatch):
    """Off a terminal (pytest's captured stderr) each figure's Monte Carlo prints plain
    progress lines, as eval does: a long regeneration shows a sign of life in a log file."""
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.runs import progress

    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    make_results.run(load_scenario("default"), ["ekf"], 2, 1, duration=1.0, seed=0)
    err = capsys.readouterr().err
    assert re.search(r"^eval default: 2/2 runs", err, flags=re.M), err


def anchor(header: str) -> str:
    """The anchor GitHub gives a ``## `` heading: link targets dropped, lower case, punctuation
    other than ``-`` and ``_`` removed, spaces to ``-``."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", header.removeprefix("## "))
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


def test_anchor_by_hand():
    assert anchor("## SLAM on `slam_loop`: EKF-SLAM and FastSLAM 2.0 over seeded runs") == \
        "slam-on-slam_loop-ekf-slam-and-fastslam-20-over-seeded-runs"
    assert anchor("## [Seed 001](references.md#seed-001): EKF against UKF on MRCLAM (real data)") == \
        "seed-001-ekf-against-ukf-on-mrclam-real-data"


def test_every_link_into_results_names_a_section(make_results):
    """A page that quotes results.md links a section that exists (a renamed heading would
    leave the link dangling)."""
    anchors = {anchor(e.header) for e in make_results.FIGURES}
    dangling = []
    for path in sorted((ROOT / "docs").glob("*.md")):
        for target in re.findall(r"\(results\.md#([^)\s]+)\)", path.read_text(encoding="utf-8")):
            if target not in anchors:
                dangling.append(f"{path.name}: results.md#{target}")
    assert not dangling, dangling


def test_pages_that_quote_a_figure_link_its_section(make_results):
    """Each page an entry names in ``quoted_in`` links that section of results.md: its
    figures come from the script's seeds, not from numbers typed on the page."""
    missing = []
    for e in make_results.FIGURES:
        for page in e.quoted_in:
            text = (ROOT / "docs" / page).read_text(encoding="utf-8")
            if f"(results.md#{anchor(e.header)})" not in text:
                missing.append(f"{page} does not link results.md#{anchor(e.header)} ({e.name})")
    assert not missing, missing
    quoted = {e.name for e in make_results.FIGURES if e.quoted_in}
    assert {"lookalike", "unknown_ids", "team_sparse", "office_kidnap", "symmetric_room", "bearing_only",
            "fastslam_association", "map_bound", "two_rooms", "kf_consistency", "outliers", "nees_alarm",
            "kidnap_trials", "pf_default", "pf_tempering", "graph_slam", "office_sweep",
            "fastslam_ring", "bearing_ring", "global_start", "corridor_ladder", "symmetric_before",
            "krejsa", "distance", "default", "association", "slam"} <= quoted


def test_every_link_out_of_a_section_names_a_heading(make_results):
    """A section's "what it shows is discussed in PAGE#ANCHOR" names a heading of that page
    (the prose the figure moves with): the script's own text and results.md as committed."""
    def headings(page: str) -> set[str]:
        text = (ROOT / "docs" / page).read_text(encoding="utf-8")
        return {anchor("## " + h) for h in re.findall(r"^#{1,6} (.+)$", text, flags=re.M)}

    sources = [ROOT / "scripts" / "make_results.py", *sorted((ROOT / "scripts" / "results").glob("*.py"))]
    script = "\n".join(p.read_text(encoding="utf-8") for p in sources)
    results = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    dangling = []
    for page, target in set(re.findall(r"\]\(([\w-]+\.md)#([^)\s]+)\)", script + results)):
        if page != "results.md" and (ROOT / "docs" / page).exists() and target not in headings(page):
            dangling.append(f"{page}#{target}")
    assert not dangling, sorted(dangling)


#: ``seed N`` / ``seeds A-B`` (``..``, ``to``, ``and``) naming a random seed: not the five texts
#: cited as "seed 000" .. "seed 004", written with leading zeros.
SEED_NAMED = re.compile(r"\bseeds?\s+(?!0\d)(\d+)(?:\s*(?:-|\.\.|to|and)\s*(\d+))?", re.I)
#: A figure: a decimal, a count "k/n" or "k of n", a percentage.
FIGURE = re.compile(r"\d\.\d|\d+ ?/ ?\d+|\d+ of \d+|\d ?%")
#: What a figure on seeds outside the docs' and the check's ranges must say it is.
LABELLED = re.compile(r"tuning|tuned|\btests?\b|tests/|history|by hand|hand[- ]runs?\b|hand-measured"
                      r"|benchmark|soak|\bone (?:run|drive|draw)\b", re.I)


def unlabelled_seed_figures(text: str, lo: int, hi: int) -> list[str]:
    """The paragraphs of a page that name a seed outside [lo, hi) beside a figure without
    saying what it is (a tuning record, a test's, history, a benchmark's, one run). Code blocks
    are left out (an output the text around it labels), and so are seeds inside inline code
    (a command); a paragraph in a section whose opening paragraph runs a `benchmarks/` script
    is that benchmark's report."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    found = []
    for section in re.split(r"^(?=#{1,6} )", text, flags=re.M):
        paras = [p for p in re.split(r"\n\s*\n", section) if p.strip()]
        opening = " ".join(paras[:2])        # the heading and the paragraph under it
        benchmark_report = "benchmarks/" in opening
        for para in paras:
            bare = re.sub(r"`[^`\n]*`", "", para)
            seeds = [int(m.group(1)) for m in SEED_NAMED.finditer(bare)]
            if (any(not lo <= s < hi for s in seeds) and FIGURE.search(bare)
                    and not LABELLED.search(para) and not benchmark_report):
                found.append(" ".join(para.split())[:160])
    return found


def test_figures_on_other_seeds_say_what_they_are(make_results):
    """A docs page that quotes a figure on seeds other than the docs' (20000..) and the
    check's (30000..), such as the test seeds below 10000 or the tuning-era seeds 1000..,
    says beside it that it is a tuning record, a test's figure, history or a benchmark's: it
    is never presented as how well the shipped settings do (those are results.md's)."""
    lo, hi = make_results.DOCS_SEED, make_results.CHECK_SEED + 10_000
    bad = []
    for path in [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]:
        if path.name != "results.md":
            text = path.read_text(encoding="utf-8")
            bad += [f"{path.name}: {p}" for p in unlabelled_seed_figures(text, lo, hi)]
    assert not bad, bad
    # the check is not blind: a tuning-era figure is caught, the same labelled is not,
    # and neither are the cited texts, a command, the docs' seeds or a benchmark's section
    caught = unlabelled_seed_figures("FastSLAM's ATE was 0.209 m on seeds 1000-1009.", lo, hi)
    assert len(caught) == 1
    assert unlabelled_seed_figures("Seed 0: error 1.2 m at 40 s.\n\nNo figure on seed 5.", lo, hi) == \
        ["Seed 0: error 1.2 m at 40 s."]
    for fine in ("FastSLAM's ATE was 0.209 m on seeds 1000-1009, the tuning seeds.",
                 "The tests hold 6 seeds (700-705, at least 5 of 6 found).",
                 "As in seed 002, the fix is 1 cm x HDOP.",
                 "Run `eval default --seed 1000`: 0.12 m.",
                 "ATE 0.243 [0.204, 0.285] m on seeds 20000-20019.",
                 "## Beside a peer\n\n`python benchmarks/bench_x.py`\n\nOn seed 1 the NEES is 19.6."):
        assert unlabelled_seed_figures(fine, lo, hi) == [], fine
