"""``--foxglove [PORT]`` of ``play`` and ``replay``: the window's session also streamed live
to Foxglove on 127.0.0.1 (:mod:`beacon_sim.io.foxglove_live`)."""

from __future__ import annotations

import sys
from typing import Any

from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.io.foxglove_live import LiveFoxglove


def stream(session: Any, port: int | None) -> LiveFoxglove | None:
    """Start a Foxglove server for ``session`` on ``port`` (None: none) and say where."""
    if port is None:
        return None
    bound = LiveBound(session.scenario)  # the PCRB along the session's true path: /pcrb
    live = LiveFoxglove(session.scenario, session.names, port, bound=bound).attach(session)
    print(f"beacon-sim: streaming to Foxglove on {live.url} (in Foxglove: Open connection > "
          "Foxglove WebSocket)", file=sys.stderr)
    return live
