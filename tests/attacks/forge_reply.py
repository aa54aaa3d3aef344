"""Attack: write a forged answer straight onto the pipe to the grader (its descriptor is on
the child's command line), here a malformed estimate frame. The grader must stop this
child and fail this student only, never raise."""

import os
import struct
import sys

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Forger(ExtendedKalmanFilter):
    def update(self, measurements):
        super().update(measurements)
        if measurements:
            os.write(int(sys.argv[2]), struct.pack("<cI", b"E", 5) + b"xxxxx")
