"""Attack (or a debugging student): print 20 KB on every step."""

import sys

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

LINE = "x" * 20_000


class Chatty(ExtendedKalmanFilter):
    def update(self, measurements):
        super().update(measurements)
        print(LINE)
        print(LINE, file=sys.stderr)
