"""The best achievable covariance, live: the posterior Cramer-Rao bound (PCRB) computed one
tick at a time along the true path the window is showing (B draws it).

:func:`beacon_sim.evaluation.pcrb.pcrb` runs the recursion offline over whole runs;
:class:`LiveBound` runs the same recursion one step at a time with the same public pieces
(:func:`~beacon_sim.evaluation.pcrb.step_terms`: process model, noise bursts, expected
measurement information of the readings the tick schedule says are due;
:func:`~beacon_sim.evaluation.pcrb.information_update`; the same start,
:func:`~beacon_sim.evaluation.pcrb.start_cov`), fed with every
:class:`~beacon_sim.core.types.Step` of the session. So at any moment the window can draw
the 95 % ellipse no unbiased filter can beat, centred on the true robot, and the panel can
say how far each filter is from it. Kidnaps do not restart it (as the offline bound): it is
the bound of an estimator told where it was moved. In a map world it takes the range
finder's scans (their information from the walls' normals, core/scan_jacobian.py) and the
walls hiding beacons, as the offline bound does.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.types import Step
from beacon_sim.evaluation.pcrb import information_update, start_cov, step_terms


class LiveBound:
    """The PCRB ``P`` (3, 3) [m^2, m^2, rad^2] after the latest tick fed.

    Parameters
    ----------
    scenario : Scenario
        dt, the truth's motion noise, the sensors, the beacons, events and the prior.
    """

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        self.schedule = tick_schedule(scenario)
        self._P0 = np.asarray(start_cov(scenario), dtype=float)
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
        if self.tick < 0:
            return
        if step.tick != self.tick + 1:
            self.reset()
            if step.tick != 1:  # joined mid-run: no history to build the bound from
                self.tick = -1
                return
        true = np.asarray(step.true_pose, dtype=float)
        control = np.array([[step.control.v, step.control.omega]])
        F, Q, info = step_terms(self.scenario, self.schedule, step.tick, self.pose[None], control,
                                true[None])
        P = F @ self.P[None] @ np.swapaxes(F, 1, 2) + Q
        if info is not None:
            P = information_update(P, info)
        self.P = P[0]
        self.pose = true.copy()
        self.tick = step.tick

    def sigmas(self) -> tuple[float, float]:
        """Position sigma [m] (sqrt of the largest eigenvalue of the x-y block) and heading
        sigma [rad] of the bound: the panel's figures."""
        pos = math.sqrt(max(float(np.linalg.eigvalsh(self.P[:2, :2])[-1]), 0.0))
        return pos, math.sqrt(max(float(self.P[2, 2]), 0.0))


__all__ = ["LiveBound"]
