"""Attack: the truth is out of reach, but the scenario is a shipped one and the seeds are
small. Re-simulate it with seeds 0, 1, 2... until the first readings match the ones
received, then return that simulation's true pose. Nothing stops this but secret seeds;
its result is far below the Cramer-Rao bound, so it is flagged "suspicious"."""

import numpy as np

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Cheat(ExtendedKalmanFilter):
    def reset(self, initial):
        super().reset(initial)
        self.steps, self.sim, self.pose, self.tried = [], None, None, False

    def predict(self, control, dt):
        super().predict(control, dt)
        self.steps.append(control)
        if self.sim is not None:
            self.pose = self.sim.step().true_pose

    def update(self, measurements):
        super().update(measurements)
        if self.sim is None and measurements and not self.tried:
            self.tried = True
            try:
                from beacon_sim.core.scenario import load_scenario
                from beacon_sim.core.simulation import Simulation

                sc = load_scenario("default")
                for seed in range(20):
                    sim = Simulation(sc, seed)
                    for _ in self.steps:
                        st = sim.step()
                    if st.measurements and np.array_equal(st.measurements[0].z, measurements[0].z):
                        self.sim, self.pose = sim, st.true_pose
                        break
            except Exception:
                pass

    def estimate(self):
        mean, cov = super().estimate()
        if self.pose is not None:
            return np.array(self.pose, dtype=float), cov
        return mean, cov
