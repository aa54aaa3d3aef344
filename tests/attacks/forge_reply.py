"""Attack: write a forged answer straight onto the pipe to the grader, here a malformed
estimate frame. Its descriptor is not on the child's command line (the pipes are
descriptors of the child's own), so it writes to every pipe it holds (/proc/self/fd). The
grader must stop this child and fail this student only, never raise."""

import os
import struct

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Forger(ExtendedKalmanFilter):
    def update(self, measurements):
        super().update(measurements)
        if measurements:
            for fd in os.listdir("/proc/self/fd"):
                try:
                    if os.readlink(f"/proc/self/fd/{fd}").startswith("pipe:"):
                        os.write(int(fd), struct.pack("<cI", b"E", 5) + b"xxxxx")
                except OSError:  # the read end, or gone
                    pass
