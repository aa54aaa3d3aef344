"""Attack: spot the probes and fail them on purpose (a failed probe used to hide
the filter from the determinism and readings checks). Every copy of the filter in the
child notes the first readings it is fed (module state shared through ``builtins``,
which a fresh import of the file does not reset); a copy fed readings another copy was
already fed (the run fed again) raises. The grader builds and feeds the copies in an
order drawn from a key the child never sees, so this is as likely to fail the scored run
as its probe; either way the failure is shown."""

import builtins

import numpy as np

from beacon_sim.filters.ekf import ExtendedKalmanFilter


class Dodger(ExtendedKalmanFilter):
    def reset(self, initial):
        super().reset(initial)
        self.first = None

    def update(self, measurements):
        if self.first is None and measurements:
            self.first = b"".join(np.ascontiguousarray(m.z).tobytes() for m in measurements)
            seen = builtins.__dict__.setdefault("_dodger_seen", set())
            if self.first in seen:
                raise RuntimeError("I have seen these readings before: a probe")
            seen.add(self.first)
        super().update(measurements)
