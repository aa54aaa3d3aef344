"""Peak memory of ``beacon-sim eval`` against its number of runs: the same evaluation of
few runs and of many, each in a process of its own, its peak resident set size (the
kernel's ``ru_maxrss`` of that process) printed, with the difference and the cost per run.
Target: eval of 1,000 runs peaks within 50 MiB of eval of 10 runs (O(1) memory per run).

Usage: python benchmarks/bench_eval_memory.py [--few 10] [--many 1000] [--duration 20]
       [--scenario default] [--filter ekf ...] [--jobs 1]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys


def peak_rss_mib(argv: list[str]) -> tuple[float, int]:
    """(peak RSS of the process running ``beacon-sim argv`` [MiB], its exit status)."""
    proc = subprocess.Popen([sys.executable, "-m", "beacon_sim", *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    if proc.stderr is not None:
        err = proc.stderr.read().decode(errors="replace").strip()
        if err:
            print(f"  ({err.splitlines()[-1][:120]})", file=sys.stderr)
    return usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--few", type=int, default=10)
    ap.add_argument("--many", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=20.0, help="seconds per run")
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--filter", action="append", default=None)
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    filters = args.filter or ["ekf", "dead_reckoning"]
    base = ["eval", args.scenario, "--duration", str(args.duration), "--jobs", str(args.jobs), "--json"]
    for f in filters:
        base += ["--filter", f]
    results = {}
    for runs in (args.few, args.many):
        mib, code = peak_rss_mib([*base, "--runs", str(runs)])
        results[runs] = mib
        print(f"eval {args.scenario} --runs {runs} --duration {args.duration:g} ({', '.join(filters)}, "
              f"--jobs {args.jobs}): peak RSS {mib:.1f} MiB (exit {code})")
    extra = results[args.many] - results[args.few]
    per_run = extra / max(args.many - args.few, 1) * 1024
    verdict = "within" if extra <= 50 else "beyond"
    print(f"{args.many} runs - {args.few} runs: {extra:+.1f} MiB ({per_run:.1f} KiB a run); "
          f"target within 50 MiB: {verdict}")


if __name__ == "__main__":
    main()
