"""A class of student filters, one file each, as a teacher would collect them: working ones,
a slow one, and one broken in each way a filter can break. Every class is called ``MyEkf``
(the template's name), so their names clash. Used by the tests of failed filters, the
window's guard and ``beacon-sim grade``."""

from __future__ import annotations

import textwrap
from pathlib import Path

_BASE = """
import math
import time
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class MyEkf(ExtendedKalmanFilter):
    FAIL_S = math.inf      # simulated time [s] from which the fault shows

    def reset(self, initial):
        super().reset(initial)
        self.t = 0.0

    def predict(self, control, dt):
        super().predict(control, dt)
        self.t += dt
        if self.t >= self.FAIL_S - 1e-9:
            self.predict_fault()

    def predict_fault(self):
        pass

    def estimate(self):
        mean, cov = super().estimate()
        if self.t >= self.FAIL_S - 1e-9:
            return self.spoil(np.array(mean), np.array(cov))
        return mean, cov

    def spoil(self, mean, cov):
        return mean, cov
"""

#: file stem -> (what it does, the class body added to ``_BASE``'s MyEkf, or a whole file).
STUDENTS: dict[str, tuple[str, str]] = {
    "alice": ("working: the EKF as it is", ""),
    "bob": ("working, pessimistic: covariance inflated 4x", """
        def spoil(self, mean, cov):
            return mean, 4.0 * cov
        FAIL_S = 0.0
    """),
    "carol": ("raises at 3 s", """
        FAIL_S = 3.0
        def predict_fault(self):
            raise ZeroDivisionError("division by zero in my Jacobian")
    """),
    "dave": ("NaN at 2 s", """
        FAIL_S = 2.0
        def spoil(self, mean, cov):
            mean[0] = np.nan
            return mean, cov
    """),
    "erin": ("covariance not PSD at 1 s", """
        FAIL_S = 1.0
        def spoil(self, mean, cov):
            return mean, cov - 10.0 * np.eye(3)
    """),
    "frank": ("returns a (2,) mean at 2 s", """
        FAIL_S = 2.0
        def spoil(self, mean, cov):
            return mean[:2], cov
    """),
    "grace": ("returns None at 2 s", """
        FAIL_S = 2.0
        def spoil(self, mean, cov):
            return None
    """),
    "heidi": ("loops forever at 2 s", """
        FAIL_S = 2.0
        def predict_fault(self):
            while True:
                pass
    """),
    "ivan": ("working but slow: about 3 ms per step", """
        FAIL_S = 0.0
        def predict_fault(self):
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < 0.003:
                pass
    """),
    "judy": ("does not import (syntax error)", "RAW:class MyEkf(:\n    pass\n"),
    "mallory": ("memory blow-up at 1 s", """
        FAIL_S = 1.0
        def predict_fault(self):
            self.hoard = np.ones((1 << 20, 1 << 20))   # 8 TiB
    """),
    "oscar": ("covariance non-symmetric and negative definite at 1 s", """
        FAIL_S = 1.0
        def spoil(self, mean, cov):
            return mean, -np.eye(3) + np.triu(np.ones((3, 3)), 1)
    """),
}

WORKING = ("alice", "bob", "ivan")


def source(stem: str) -> str:
    """The text of ``stem``.py."""
    _, body = STUDENTS[stem]
    if body.startswith("RAW:"):
        return body[4:]
    return _BASE + textwrap.indent(textwrap.dedent(body), "    ")


def write_class(folder: Path, stems=None) -> Path:
    """Write the students' files into ``folder``; returns it."""
    folder.mkdir(parents=True, exist_ok=True)
    for stem in stems or STUDENTS:
        (folder / f"{stem}.py").write_text(source(stem))
    return folder
