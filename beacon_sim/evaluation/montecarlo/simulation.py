"""A run simulated once, without filters, to be fed to hosted filters
(:func:`simulate_run`, :class:`SimulatedRun`: the truth kept here, each tick's request
pickled once), and the start shared with the in-process runs (:func:`start_run`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation


def start_run(scenario: Scenario, seed: int, duration: float
              ) -> tuple[Simulation, int, np.ndarray, np.ndarray, np.ndarray]:
    """A run's simulation at tick 0 and its arrays to fill: the ticks T, the truth (T + 1, 3)
    with row 0 the start, the commands (T, 2) [m/s, rad/s] and the kidnap flags (T,)."""
    sim = Simulation(scenario, seed)
    T = round(duration / scenario.dt)
    truth = np.empty((T + 1, 3))
    truth[0] = sim.pose
    return sim, T, truth, np.empty((T, 2)), np.zeros(T, dtype=bool)


@dataclass
class SimulatedRun:
    """One (scenario, seed) simulated once by the grader, to be streamed to every
    student's child: the truth (kept in the grader) and, per tick, the request that carries
    what a filter may see (control, dt, readings), pickled once."""

    scenario: Scenario
    index: int
    seed: int
    truth: np.ndarray  # (T + 1, 3)
    controls: np.ndarray  # (T, 2)
    kidnapped: np.ndarray  # (T,)
    truth_checksum: str
    records: list  # the readings of the ticks that had any (for the NIS)
    record_index: np.ndarray  # (T,) int: the index in ``records`` of tick i's readings
    frames: list[bytes]  # (T,) "step" requests
    #: The same run (truth, controls, events) with its readings drawn again from another
    #: stream (the probes' extra run only: does the filter use its readings?).
    frames_other: list[bytes] | None = None
    label: str = ""  # the scenario as the user named it (a shipped name or a path)
    #: The key of the run's filter streams (core/streams.py ``run_key``: a hash of the
    #: grade's secret and the seed; None: the public key's). Stays in the grader.
    key: bytes | None = None
    #: The probes' extra run (a scenario's first run only): one more seed drawn from the
    #: key, its first ticks, with its readings drawn again (hosting/feed.py ``probe_slots``).
    extra: SimulatedRun | None = None

    @property
    def stream_key(self) -> bytes:
        """The run's key (:func:`~beacon_sim.core.streams.run_key`), the public one by default."""
        from beacon_sim.core.streams import run_key

        return self.key if self.key is not None else run_key(self.seed)

    def global_seed(self, name: str) -> int:
        """The seed of the global generators of the filter ``name`` in this run, as sent to
        its child: derived from the run's key, never the seed."""
        from beacon_sim.core.streams import keyed_global_seed

        return keyed_global_seed(self.stream_key, name)

    def readings_within(self, ticks: int) -> bool:
        """Whether the first ``ticks`` ticks hold any reading."""
        n = min(ticks, len(self.frames))
        return n > 0 and any(len(r) for r in self.records[:int(self.record_index[n - 1]) + 1])


def simulate_run(scenario: Scenario, seed: int, duration: float, index: int = 0,
                 probe: bool = False, label: str | None = None,
                 secret: bytes | None = None, redraw: bool = False) -> SimulatedRun:
    """Simulate one run as :func:`one_run` does, without filters. ``probe``: also the
    probes' extra run (``extra``: one more seed drawn from the run's key, for the probes'
    ticks, its readings drawn again too); ``redraw``: this run with its readings drawn
    again (``frames_other``, from a seed derived from the run's key); ``secret``: the key
    of the filters' streams (None: the public key)."""
    from beacon_sim.core.streams import run_key
    from beacon_sim.hosting.client import step_request
    from beacon_sim.hosting.feed import PROBE_TICKS, other_readings_seed, probe_seed

    key = run_key(seed, secret)
    sim, T, truth, controls, kidnapped = start_run(scenario, seed, duration)
    other = Simulation(scenario, seed, readings_seed=other_readings_seed(key)) if redraw else None
    records: list = []
    rec = np.zeros(T, dtype=int)
    frames, other_frames = [], []
    for i in range(T):
        step = sim.step()
        truth[i + 1] = step.true_pose
        controls[i] = (step.control.v, step.control.omega)
        kidnapped[i] = step.kidnapped
        rec[i] = len(records)
        if step.measurements:
            records.append(step.measurements)
        frames.append(step_request(step.control, step.dt, step.measurements, bool(step.measurements)))
        if other is not None:
            st = other.step()
            other_frames.append(step_request(st.control, st.dt, st.measurements, bool(st.measurements)))
    if other is not None and other.truth_checksum != sim.truth_checksum:
        other_frames = []  # readings that moved the truth: no such probe here
    extra = None
    if probe:
        extra = simulate_run(scenario, probe_seed(key), min(duration, PROBE_TICKS * scenario.dt), index,
                             label=label, secret=secret, redraw=True)
    return SimulatedRun(scenario, index, seed, truth, controls, kidnapped, sim.truth_checksum,
                        records, rec, frames, other_frames or None,
                        scenario.name if label is None else label, key, extra)
