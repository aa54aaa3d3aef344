"""How a benchmark script reports its key figures to ``benchmarks/run.py``.

Besides its own table for people, each script calls :func:`figure` for the numbers that
matter. Under run.py (which sets ``BEACON_SIM_BENCH_FIGURES=1``) it prints one line
``FIGURE {json}``; run.py collects those lines from every script into one table with the
peer, the ratio and the target. Run by hand, it prints one plain ``FIGURE`` line: the
value, the peer and the ratio, the target and whether it is met.

Importing this module limits numpy's BLAS to the thread count the window, headless runs and
eval workers use (``beacon_sim.core.threads``: one unless ``BEACON_SIM_BLAS_THREADS`` says
otherwise), so a benchmark measures what a user gets. Each record carries the 1-minute load
average when it was taken; ``cpu`` (the process's CPU time for the same thing, same unit)
may be given beside the wall-clock value, which other jobs on a shared machine inflate.
"""

from __future__ import annotations

import json
import os
import statistics
import time

from beacon_sim.core.threads import limit_blas_threads

limit_blas_threads()

#: run.py sets this; a script run by hand prints only its own table.
ENV = "BEACON_SIM_BENCH_FIGURES"


def figure(what: str, value: float, unit: str, *, peer: str | None = None,
           peer_value: float | None = None, target: float | None = None,
           target_of: str = "value", cpu: float | None = None) -> None:
    """Report one figure.

    Parameters
    ----------
    what : str
        What was measured, e.g. ``"ekf step, bearing-only"``.
    value, unit : float, str
        The measurement and its unit (``"us"``, ``"ms"``, ``"s"``, ``"steps/s"``).
    peer, peer_value : str, float, optional
        The peer measured in the same run and its figure (same unit); the ratio
        ``value / peer_value`` is printed beside it.
    target : float, optional
        The largest acceptable ``value`` (``target_of="value"``) or ratio
        (``target_of="ratio"``); run.py says whether it is met.
    cpu : float, optional
        The CPU time behind ``value`` (same unit), shown beside it.
    """
    ratio = value / peer_value if peer_value else None
    met = None
    if target is not None:
        x = ratio if target_of == "ratio" else value
        met = None if x is None else bool(x <= target)
    load = os.getloadavg()[0]
    if os.environ.get(ENV):
        print("FIGURE " + json.dumps({"what": what, "value": value, "unit": unit, "peer": peer,
                                      "peer_value": peer_value, "ratio": ratio, "target": target,
                                      "target_of": target_of, "cpu": cpu, "met": met,
                                      "load": load}), flush=True)
        return
    # by hand: one plain line, the target and whether it is met last
    text = f"FIGURE {what}: {value:.4g} {unit}"
    if peer is not None and peer_value is not None:
        text += f"; {peer} {peer_value:.4g} {unit}"
    if ratio is not None:
        text += f"; ratio {ratio:.3f}x"
    if target is not None:
        shown = f"{target:g}x" if target_of == "ratio" else f"{target:g} {unit}"
        text += f"; target <= {shown}: {'met' if met else 'NOT met' if met is not None else '-'}"
    print(f"{text}; load {load:.2f}", flush=True)


class Clock:
    """Wall and CPU time of a block: ``with Clock() as c: ...``, then ``c.wall``, ``c.cpu`` [s]."""

    def __enter__(self) -> Clock:
        self._w, self._c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self._w
        self.cpu = time.process_time() - self._c


def median_ms(fn, n: int) -> tuple[float, float]:
    """Median wall and CPU time [ms] of ``n`` calls of ``fn``, after one warm-up call
    (caches, first touch of tables)."""
    fn()
    wall, cpu = [], []
    for _ in range(n):
        with Clock() as c:
            fn()
        wall.append(c.wall * 1e3)
        cpu.append(c.cpu * 1e3)
    return statistics.median(wall), statistics.median(cpu)


def proc_cpu(pids: list[int]) -> float:
    """CPU time [s] of the processes ``pids`` and the children they reaped (/proc, Linux)."""
    total = 0
    for pid in pids:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rpartition(")")[2].split()
        total += sum(int(f) for f in fields[11:15])  # utime, stime, cutime, cstime
    return total / os.sysconf("SC_CLK_TCK")
