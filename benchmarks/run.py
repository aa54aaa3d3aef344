"""Run every ``benchmarks/bench_*.py`` and print one table of their key figures.

Each script runs as a subprocess, one at a time (so they do not slow each other down), and
reports its key figures through ``benchmarks/figures.py`` (lines ``FIGURE {json}``), each
with the peer measured in the same run, the ratio and the target where there is one. The
scripts' own tables are kept in ``--log FILE`` if asked for.
Usage: python benchmarks/run.py [--only NAME ...] [--timeout S] [--log FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def collect(text: str) -> list[dict]:
    """The ``FIGURE`` records a script printed."""
    return [json.loads(line[len("FIGURE "):]) for line in text.splitlines()
            if line.startswith("FIGURE ")]


def verdict(f: dict) -> str:
    if f.get("target") is None:
        return ""
    x = f["ratio"] if f.get("target_of") == "ratio" else f["value"]
    if x is None:
        return ""
    shown = f"{f['target']:.3g}x" if f.get("target_of") == "ratio" else f"{f['target']:g} {f['unit']}"
    return f"<= {shown}: {'met' if x <= f['target'] else 'NOT met'}"


def fmt(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, help="run only these bench_*.py names")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per script")
    ap.add_argument("--log", help="write every script's own output to this file")
    args = ap.parse_args()
    scripts = sorted(HERE.glob("bench_*.py"))
    if args.only:
        scripts = [s for s in scripts if s.stem in args.only or s.name in args.only]
    rows, log, ok = [], [], True
    load0 = os.getloadavg()
    for script in scripts:
        print(f"running {script.name} ...", file=sys.stderr, flush=True)
        t = time.perf_counter()
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        try:
            proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                                  timeout=args.timeout, cwd=HERE.parent,
                                  env={**os.environ, "BEACON_SIM_BENCH_FIGURES": "1"})
            status = "ok" if proc.returncode == 0 else f"exit {proc.returncode}"
            text = proc.stdout
            log.append(f"== {script.name} ({status})\n{proc.stdout}{proc.stderr}")
        except subprocess.TimeoutExpired:
            status, text = f"timeout {args.timeout:g} s", ""
        ok &= status == "ok"
        figures = collect(text)
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if status != "ok" or not figures:
            rows.append((script.stem, f"{status}: no figures", "", "", "", "", "", "", ""))
        for f in figures:
            peer = f"{f['peer']} {fmt(f['peer_value'])}" if f.get("peer") else ""
            ratio = f"{f['ratio']:.3g}x" if f.get("ratio") is not None else ""
            load = f"{f['load']:.1f}" if f.get("load") is not None else ""
            rows.append((script.stem, f["what"], fmt(f["value"]), fmt(f.get("cpu")), f["unit"], peer,
                         ratio, verdict(f), load))
        cpu = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
        rows.append((script.stem, "(script wall time)", f"{time.perf_counter() - t:.1f}", f"{cpu:.1f}",
                     "s", "", "", "", f"{os.getloadavg()[0]:.1f}"))
    head = ("benchmark", "figure", "value", "cpu", "unit", "peer (same run)", "ratio", "target", "load")
    w = [max(len(r[i]) for r in [head, *rows]) for i in range(9)]
    line = "  ".join(f"{{:<{n}}}" if i in (0, 1, 4, 5, 7) else f"{{:>{n}}}" for i, n in enumerate(w))
    print(f"load average (1, 5, 15 min) at start: {', '.join(f'{x:.2f}' for x in load0)}; "
          f"at end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} cores")
    print(line.format(*head))
    print("-" * (sum(w) + 16))
    for r in rows:
        print(line.format(*r))
    if args.log:
        Path(args.log).write_text("\n".join(log))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
