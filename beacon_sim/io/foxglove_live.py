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
from beacon_sim.core.sensor_kinds import table_rows
from beacon_sim.core.types import Step
from beacon_sim.io.foxglove import BeliefFrame, Publisher, belief_frame, foxglove_modules

HOST = "127.0.0.1"
DEFAULT_PORT = 8765


def step_readings(step: Step) -> list[tuple[str, str, np.ndarray, int]]:
    """A tick's readings as the publisher's rows: ``(sensor, kind, z row, beacon id)``, the
    beacon -1 for a fix."""
    rows = []
    for m in step.measurements:
        ids, zs = table_rows(m)   # a fix's or a scan's rows name no beacon (-1)
        for bid, zrow in zip(ids.tolist(), zs, strict=True):
            rows.append((m.sensor, m.kind, np.asarray(zrow, dtype=float), int(bid)))
    return rows


class LiveFoxglove:
    """A Foxglove WebSocket server on ``127.0.0.1:port`` (0: any free port) for one session.

    :meth:`attach` it to a session (anything with ``on_step`` listeners, ``estimate(name)``,
    ``belief(name)``, ``runner.tracks`` and ``names``: :class:`beacon_sim.runs.live.Session`
    and the replay's); :meth:`close` stops the server. ``bound``: the PCRB fed along the
    session (anything with ``feed(step)``, ``valid`` and ``P`` (3, 3):
    :class:`beacon_sim.evaluation.live_bound.LiveBound`), or None for no ``/pcrb`` topics.
    """

    def __init__(self, scenario: Scenario, filter_names: Sequence[str], port: int = DEFAULT_PORT,
                 bound: Any = None):
        fox, _, _ = foxglove_modules()
        self.context = fox.Context()
        try:
            self.server = fox.start_server(name=f"beacon-sim {scenario.name}", host=HOST, port=int(port),
                                           context=self.context)
        except Exception as exc:  # the SDK's own error type: a port in use, no permission
            raise OSError(f"Foxglove server on {HOST}:{port}: {exc}") from None
        self.publisher = Publisher(scenario, filter_names, self.context)
        self.world_every = max(1, round(1.0 / scenario.dt))
        self.bound = bound
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
        """Stream ``session``: every topic advertised now (the belief topics its filters'
        first beliefs have), then one tick per step."""
        self.session = session
        first = self.frame()
        if self.bound is not None:
            first = BeliefFrame(first.particles, first.grids, first.landmarks, np.zeros((3, 3)))
        self.publisher.declare(first)
        session.on_step.append(self.on_step)
        return self

    def frame(self) -> BeliefFrame:
        """The session's beliefs now: each running filter's belief (through the session's
        guard), a SLAM filter's ``landmarks()``, and the PCRB when it is fed."""
        s = self.session
        beliefs, maps = {}, {}
        for name in self.publisher.names:
            track = s.runner.tracks.get(name)
            if track is None or track.failed:
                continue
            beliefs[name] = s.belief(name)
            landmarks = getattr(track.filter, "landmarks", None)
            if callable(landmarks):
                try:
                    maps[name] = landmarks()
                except Exception:  # the window switches such a filter off; its estimate still goes out
                    pass
        bound = self.bound.P if self.bound is not None and self.bound.valid else None
        return belief_frame(beliefs, maps, bound)

    def on_step(self, step: Step) -> None:
        """Publish one tick of the attached session."""
        s, pub = self.session, self.publisher
        if self.bound is not None:
            self.bound.feed(step)
        est = {}
        for name in pub.names:
            track = s.runner.tracks.get(name)
            if track is not None and not track.failed:
                est[name] = s.estimate(name)
        if step.tick % self.world_every == 0:
            pub.start(step.tick * pub.dt_ns)
        pub.tick(step.tick, np.asarray(step.true_pose, dtype=float), est, step_readings(step),
                 [(e.kind, e.detail) for e in step.events], self.frame())
        for name, track in s.runner.tracks.items():
            if track.failed and name not in self._reported:
                self._reported.add(name)
                pub.failed(step.tick, name, str(track.failed))

    def close(self) -> None:
        if self.session is not None and self.on_step in self.session.on_step:
            self.session.on_step.remove(self.on_step)
        self.publisher.close()
        self.server.stop()
