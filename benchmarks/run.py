"""Run every ``benchmarks/bench_*.py`` and print one table of their figures.

Each script runs as a subprocess (its own interpreter, one at a time, so they do not slow
each other down) and prints its own table: a header line whose columns are separated by two
or more spaces, then rows of a label and numbers. This collects every number under its
column name, so the peers' figures (rows labelled ``(peer) ...``) and the ratios the
scripts compute end up side by side. A script that fails or prints no table is listed with
its last line of output.
Usage: python benchmarks/run.py [--only NAME ...] [--timeout S] [-- ARGS for every script]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(x|%)?$")


def _segments(header: str) -> list[tuple[int, int, str]]:
    """Column titles of a header line: (start, end, text), split on runs of 2+ spaces."""
    return [(m.start(), m.end(), m.group(0).strip())
            for m in re.finditer(r"\S+(?: \S+)*", header)]


def parse_table(text: str) -> list[tuple[str, str, str]]:
    """(row label, column, value) for every number in the tables of ``text``."""
    out = []
    header: list[tuple[int, int, str]] = []
    for line in text.splitlines():
        tokens = list(re.finditer(r"\S+", line))
        nums = [t for t in tokens if NUMBER.match(t.group(0))]
        if not tokens:
            continue
        if not nums:
            segs = _segments(line)
            if len(segs) >= 2:
                header = segs
            continue
        if not header:  # a sentence: "label: median 6.78 ms, p99 25.89 ms"
            label = line.split(":", 1)[0].strip() if ":" in line else "-"
            for i, t in enumerate(tokens):
                if not NUMBER.match(t.group(0)) or t.start() < len(label):
                    continue
                before = tokens[i - 1].group(0).strip(",;:(") if i else ""
                after = tokens[i + 1].group(0).strip(",;:)") if i + 1 < len(tokens) else ""
                unit = f" [{after}]" if after.isalpha() and len(after) <= 3 else ""
                out.append((label, (before + unit).strip() or "value", t.group(0)))
            continue
        label = line[:nums[0].start()].strip() or "-"
        label_end = len(line[:nums[0].start()].rstrip())
        for t in nums:
            column = "value"
            best = None
            for start, end, title in header:
                # right-aligned columns end where their values end; left-aligned ones start there
                d = min(abs(end - t.end()), abs(start - t.start()))
                if end > label_end and (best is None or d < best):
                    best, column = d, title
            out.append((label, column, t.group(0)))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, help="run only these bench_*.py names")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per script")
    ap.add_argument("rest", nargs=argparse.REMAINDER)
    args = ap.parse_args()
    scripts = sorted(HERE.glob("bench_*.py"))
    if args.only:
        scripts = [s for s in scripts if s.stem in args.only or s.name in args.only]
    extra = [a for a in args.rest if a != "--"]
    rows = []
    for script in scripts:
        print(f"running {script.name} ...", file=sys.stderr, flush=True)
        t = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, str(script), *extra], capture_output=True,
                                  text=True, timeout=args.timeout, cwd=HERE.parent)
            status = "ok" if proc.returncode == 0 else f"exit {proc.returncode}"
            text = proc.stdout
            tail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or [""]
        except subprocess.TimeoutExpired:
            status, text, tail = f"timeout {args.timeout:g} s", "", [""]
        wall = time.perf_counter() - t
        figures = parse_table(text)
        if status != "ok" or not figures:
            rows.append((script.stem, status, "-", "-", tail[0][:60]))
        for label, column, value in figures:
            rows.append((script.stem, status, label, column, value))
        rows.append((script.stem, status, "(script wall time)", "s", f"{wall:.1f}"))
    w = [max(len(str(r[i])) for r in [("benchmark", "status", "row", "figure", "value"), *rows])
         for i in range(5)]
    w[2] = min(w[2], 46)
    line = f"{{:<{w[0]}}}  {{:<{w[1]}}}  {{:<{w[2]}}}  {{:<{w[3]}}}  {{:>{w[4]}}}"
    print(line.format("benchmark", "status", "row", "figure", "value"))
    print("-" * (sum(w) + 8))
    for r in rows:
        print(line.format(r[0], r[1], r[2][:46], r[3], r[4]))
    return 0 if all(r[1] == "ok" for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
