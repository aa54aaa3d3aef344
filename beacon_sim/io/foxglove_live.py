"""A live session streamed to Foxglove (``beacon-sim play --foxglove``, ``replay --foxglove``).

A Foxglove WebSocket server (``foxglove-sdk``, the ``mcap`` extra) on 127.0.0.1 only: in
Foxglove, *Open connection* > *Foxglove WebSocket* > ``ws://127.0.0.1:8765``. Every tick of
the session goes out as the topics of :class:`beacon_sim.io.foxglove.Publisher`, the same
messages as an MCAP export of the run; ``/world`` is sent again every second of simulated
time, so a client that connects late still sees the beacons.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.io.foxglove import Publisher, foxglove_modules

HOST = "127.0.0.1"
DEFAULT_PORT = 8765


def step_readings(step: Step) -> list[tuple[str, str, np.ndarray, int]]:
    """A tick's readings as the publisher's rows: ``(sensor, kind, z row, beacon id)``, the
    beacon -1 for a fix."""
    rows = []
    for m in step.measurements:
        fix = m.kind in ("pose", "position", "range_finder")   # no beacon ID per row
        for i in range(len(m)):
            rows.append((m.sensor, m.kind, np.asarray(m.z[i], dtype=float),
                         -1 if fix else int(m.beacon_ids[i])))
    return rows


class LiveFoxglove:
    """A Foxglove WebSocket server on ``127.0.0.1:port`` (0: any free port) for one session.

    :meth:`attach` it to a session (anything with ``on_step`` listeners, ``estimate(name)``,
    ``runner.tracks`` and ``names``: :class:`beacon_sim.runs.live.Session` and the replay's);
    :meth:`close` stops the server.
    """

    def __init__(self, scenario: Scenario, filter_names: Sequence[str], port: int = DEFAULT_PORT):
        fox, _, _ = foxglove_modules()
        self.context = fox.Context()
        try:
            self.server = fox.start_server(name=f"beacon-sim {scenario.name}", host=HOST, port=int(port),
                                           context=self.context)
        except Exception as exc:  # the SDK's own error type: a port in use, no permission
            raise OSError(f"Foxglove server on {HOST}:{port}: {exc}") from None
        self.publisher = Publisher(scenario, filter_names, self.context)
        self.world_every = max(1, round(1.0 / scenario.dt))
        self.publisher.declare()
        self.publisher.start(0)
        self.session: Any = None
        self._reported: set[str] = set()

    @property
    def port(self) -> int:
        return int(self.server.port)

    @property
    def url(self) -> str:
        return f"ws://{HOST}:{self.port}"

    def attach(self, session: Any) -> LiveFoxglove:
        self.session = session
        session.on_step.append(self.on_step)
        return self

    def on_step(self, step: Step) -> None:
        """Publish one tick of the attached session."""
        s, pub = self.session, self.publisher
        est = {}
        for name in pub.names:
            track = s.runner.tracks.get(name)
            if track is not None and not track.failed:
                est[name] = s.estimate(name)
        if step.tick % self.world_every == 0:
            pub.start(step.tick * pub.dt_ns)
        pub.tick(step.tick, np.asarray(step.true_pose, dtype=float), est, step_readings(step),
                 [(e.kind, e.detail) for e in step.events])
        for name, track in s.runner.tracks.items():
            if track.failed and name not in self._reported:
                self._reported.add(name)
                pub.failed(step.tick, name, str(track.failed))

    def close(self) -> None:
        if self.session is not None and self.on_step in self.session.on_step:
            self.session.on_step.remove(self.on_step)
        self.publisher.close()
        self.server.stop()
