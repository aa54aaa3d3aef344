"""MyTeam: my own team filter for beacon-sim (several robots that see each other).

It runs as it is: every robot keeps its own EKF and uses only its own beacon readings
(the "independent" baseline). Fill in the TODO to use what the robots see of each other,
then compare with the built-in cooperative filters (docs/multi-robot.md).

Try it (from the folder this file is in):

    beacon-sim check my_team.py:MyTeam
    beacon-sim play team_sparse --filter ./my_team.py:MyTeam --filter centralised
    beacon-sim eval team_sparse --filter ./my_team.py:MyTeam --filter decentralised --runs 10

Frames and units: world frame, metres, radians, seconds; a pose is [x, y, theta].
"""

from beacon_sim.api import ExtendedKalmanFilter


class MyTeam:
    def __init__(self, ctx):
        # ctx.members[i]: robot i's id, its single-robot context (ctx.members[i].ctx: the
        # beacon map, the motion and sensor noise the filters are told, its own seeded
        # random generator rng) and its robot sensors (ctx.members[i].robot_sensors).
        self.ctx = ctx
        self.filters = [ExtendedKalmanFilter(m.ctx) for m in ctx.members]
        self.index = {m.id: i for i, m in enumerate(ctx.members)}  # robot id -> index

    def reset(self, initial):
        """``initial``: one GaussianBelief (mean (3,), cov (3, 3)) per robot, team order."""
        for f, belief in zip(self.filters, initial, strict=True):
            f.reset(belief)

    def predict(self, controls, dt):
        """``controls[i]``: robot i's command (v [m/s], omega [rad/s]) over ``dt`` [s]."""
        for f, u in zip(self.filters, controls, strict=True):
            f.predict(u, dt)

    def update(self, measurements):
        """``measurements[i]``: robot i's readings of the tick. Beacon readings have kind
        "bearing" or "range_bearing"; robot readings "robot_bearing" or
        "robot_range_bearing", and their beacon_ids are the ids of the robots seen."""
        for i, (f, readings) in enumerate(zip(self.filters, measurements, strict=True)):
            f.update([m for m in readings if not m.kind.startswith("robot_")])
            for m in readings:
                if not m.kind.startswith("robot_"):
                    continue
                sensor = self.ctx.members[i].robot_sensor(m.sensor)
                std = sensor.reading_std()  # told noise: (range [m],) bearing [rad]
                for z, robot_id in zip(m.z, m.beacon_ids, strict=True):
                    j = self.index.get(int(robot_id))
                    if j is not None and j != i:
                        self.saw(i, j, m.kind, z, std)

    def saw(self, i, j, kind, z, std):
        """Robot i saw robot j: ``z`` = [range, bearing] (kind "robot_range_bearing") or
        [bearing] ("robot_bearing") [m, rad], with the told noise ``std`` (the same rows).

        TODO: use it. beacon_sim.core.team_models.relative_rows(kind, pose_i, pose_j) gives
        the expected reading h and its Jacobians H_i, H_j. A joint update of i and j must
        know how their errors are correlated (see the centralised and decentralised filters
        in docs/multi-robot.md); fusing as if they were independent counts the same
        information twice (the "naive" filter, overconfident).
        """

    def estimates(self):
        """Each robot's (mean (3,), cov (3, 3)), team order."""
        return [f.estimate() for f in self.filters]
