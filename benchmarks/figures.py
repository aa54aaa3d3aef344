"""How a benchmark script reports its key figures to ``benchmarks/run.py``.

Besides its own table for people, each script calls :func:`figure` for the numbers that
matter. Under run.py (which sets ``BEACON_SIM_BENCH_FIGURES=1``) it prints one line
``FIGURE {json}``; run.py collects those lines from every script into one table with the
peer, the ratio and the target.
"""

from __future__ import annotations

import json
import os

#: run.py sets this; a script run by hand prints only its own table.
ENV = "BEACON_SIM_BENCH_FIGURES"


def figure(what: str, value: float, unit: str, *, peer: str | None = None,
           peer_value: float | None = None, target: float | None = None,
           target_of: str = "value") -> None:
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
    """
    if not os.environ.get(ENV):
        return
    ratio = value / peer_value if peer_value else None
    print("FIGURE " + json.dumps({"what": what, "value": value, "unit": unit, "peer": peer,
                                  "peer_value": peer_value, "ratio": ratio, "target": target,
                                  "target_of": target_of}), flush=True)
