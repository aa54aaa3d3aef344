"""The best achievable covariance, live: the posterior Cramer-Rao bound (PCRB) computed one
tick at a time along the true path the window is showing (B draws it).

``evaluation/pcrb.py`` runs the recursion offline over whole runs; :class:`LiveBound` runs
the same recursion (same process model, same expected measurement information, same
blackouts and noise bursts, same start) one step at a time, fed with every
:class:`~beacon_sim.core.types.Step` of the session. So at any moment the window can draw
the 95 % ellipse no unbiased filter can beat, centred on the true robot, and the panel can
say how far each filter is from it. Kidnaps do not restart it (as the offline bound): it is
the bound of an estimator told where it was moved. No pygame here.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.events import Blackout, NoiseBurst, active_ticks
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.evaluation.pcrb import _process, _update, measurement_information
from beacon_sim.filters.base import broad_gaussian
from beacon_sim.filters.loading import initial_belief


class LiveBound:
    """The PCRB ``P`` (3, 3) [m^2, m^2, rad^2] after the latest tick fed.

    Parameters
    ----------
    scenario : Scenario
        dt, the truth's motion noise, the sensors, the beacons, events and the prior.
    """

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        dt = scenario.dt
        self._every = {s.name: max(round(s.period / dt), 1) for s in scenario.sensors}
        self._blackout: dict[int, list[Blackout]] = {}
        self._burst: dict[int, list[NoiseBurst]] = {}
        for ev in scenario.events:
            if isinstance(ev, Blackout | NoiseBurst):
                table = self._blackout if isinstance(ev, Blackout) else self._burst
                for k in active_ticks(ev, dt):
                    table.setdefault(k, []).append(ev)  # type: ignore[arg-type]
        global_start = initial_belief(scenario) is None
        self._P0 = (np.asarray(broad_gaussian(scenario.world).cov, dtype=float) if global_start
                    else np.zeros((3, 3)))
        self.reset()

    def reset(self) -> None:
        """Back to the start: the bound before the first tick, at the initial pose."""
        self.P = self._P0.copy()
        self.tick = 0
        self.pose = np.asarray(self.scenario.initial_pose, dtype=float).copy()

    @property
    def valid(self) -> bool:
        """False before the first tick (nothing to draw yet)."""
        return self.tick > 0

    def feed(self, step: Step) -> None:
        """One tick: predict along the command from the previous true pose, then add the
        expected information of the readings due at the new true pose. A step that does not
        follow the last one (a replay seeking back rebuilds from tick 1) restarts."""
        if step.tick != self.tick + 1:
            self.reset()
            if step.tick != 1:  # joined mid-run: no history to build the bound from
                self.tick = -1
                return
        k = step.tick
        sc = self.scenario
        bursts = self._burst.get(k, ())
        bv = math.sqrt(sum(b.v_std**2 for b in bursts))
        bw = math.sqrt(sum(b.omega_std**2 for b in bursts))
        F, Q = _process(sc, self.pose[None], np.array([step.control.v]),
                        np.array([step.control.omega]), step.dt, bv, bw)
        P = F @ self.P[None] @ np.swapaxes(F, 1, 2) + Q
        true = np.asarray(step.true_pose, dtype=float)
        info = None
        for spec in sc.sensors:
            if k % self._every[spec.name] or any(b.covers(spec.name)
                                                 for b in self._blackout.get(k, ())):
                continue
            i_z = measurement_information(spec, true[None], sc.world.beacon_xy)
            info = i_z if info is None else info + i_z
        if info is not None:
            P = _update(P, info)
        self.P = P[0]
        self.pose = true.copy()
        self.tick = k

    def sigmas(self) -> tuple[float, float]:
        """Position sigma [m] (sqrt of the largest eigenvalue of the x-y block) and heading
        sigma [rad] of the bound: the panel's figures."""
        pos = math.sqrt(max(float(np.linalg.eigvalsh(self.P[:2, :2])[-1]), 0.0))
        return pos, math.sqrt(max(float(self.P[2, 2]), 0.0))


__all__ = ["LiveBound"]
