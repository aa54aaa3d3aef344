"""Replaying on other maths: whether a replay runs the float64 kernels its recording was made
with, and how estimates made with other kernels are compared (docs/replay.md, "Recordings
verify anywhere").

The truth and the readings use the portable kernels (the same bits on every machine), so a
replay checks them bit for bit everywhere. The filters use numpy's fast kernels and BLAS,
whose last bit depends on the processor: a recording stores the maths fingerprint of the
machine that made it (:func:`beacon_sim.core.maths_fingerprint.maths_fingerprint`), and a
replay whose fingerprint differs compares each filter's stored estimate values within
:data:`MEAN_TOL` and :data:`COV_RTOL` instead of their digests.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from beacon_sim.core.maths_fingerprint import maths_description, maths_fingerprint
from beacon_sim.io.recording import VALUES_PER_ROBOT, is_fingerprint

#: Largest difference of a mean on other maths: x and y [m], theta [rad] (wrapped). Rounding
#: the last bit differently (1e-16 relative) stays below 1e-12 over a whole run in a filter
#: that makes no discrete choice (measured: 4e-15 m in the histogram filter over 1,200
#: ticks; the EKF, UKF and particle filter bit for bit), and 1e-6 m is far below any
#: reading's noise, so nothing a run reports changes within it.
MEAN_TOL = 1e-6
#: Largest difference of a covariance entry on other maths, relative to its scale
#: ``sqrt(P_ii P_jj)`` (floored at :data:`COV_SCALE_FLOOR`): covariances run from 1e-6 m^2
#: (beside a beacon) to 100 m^2 (lost), so a fixed bound would be meaningless at one end.
COV_RTOL = 1e-6
#: Smallest scale a covariance entry is compared at [m^2, m rad, rad^2]: a sigma of 1 mm.
COV_SCALE_FLOOR = 1e-6
#: The tolerance in words, for the status line.
TOLERANCE_TEXT = "1e-6 m and 1e-6 rad on the mean, 1e-6 of its scale on the covariance"

_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))  # the order of estimate_values


@dataclass(frozen=True)
class Maths:
    """The maths of a recording's machine against this process's: ``recorded`` None when
    the file does not say (made before beacon-sim stored it, format version 3 and older)."""

    recorded: str | None
    recorded_description: str
    here: str
    here_description: str

    @classmethod
    def of(cls, header: Mapping[str, Any]) -> Maths:
        """The maths a recording's header names, against this process's."""
        fp = header.get("maths")
        return cls(fp if is_fingerprint(fp) else None,
                   str(header.get("maths_description") or "not recorded"),
                   maths_fingerprint(), maths_description())

    @property
    def known(self) -> bool:
        """Whether the file says which maths made it."""
        return self.recorded is not None

    @property
    def same(self) -> bool:
        """Whether this process runs the maths the file was made with (the estimates can
        match bit for bit)."""
        return self.recorded == self.here

    def differs_text(self) -> str:
        """``recorded on a machine whose maths differs (numpy ..., AVX512_SPR; here numpy
        ..., X86_V3)``."""
        return (f"recorded on a machine whose maths differs ({self.recorded_description}; "
                f"here {self.here_description})")

    def as_json(self) -> dict[str, Any]:
        return {"recorded": self.recorded, "recorded_description": self.recorded_description,
                "here": self.here, "here_description": self.here_description,
                "same": self.same if self.known else None}


@dataclass(frozen=True)
class Difference:
    """How far a replayed estimate is from the recorded one: the largest position difference
    [m], heading difference [rad] (wrapped) and covariance difference relative to its scale,
    over every robot of the estimate."""

    position_m: float = 0.0
    heading_rad: float = 0.0
    cov_rel: float = 0.0

    @property
    def within(self) -> bool:
        """Whether it is within the tolerance (:data:`MEAN_TOL`, :data:`COV_RTOL`)."""
        return self.position_m <= MEAN_TOL and self.heading_rad <= MEAN_TOL \
            and self.cov_rel <= COV_RTOL

    def worst(self, other: Difference) -> Difference:
        return Difference(max(self.position_m, other.position_m),
                          max(self.heading_rad, other.heading_rad), max(self.cov_rel, other.cov_rel))

    def text(self) -> str:
        return (f"{self.position_m:.3g} m, {self.heading_rad:.3g} rad, covariance "
                f"{self.cov_rel:.3g} of its scale")

    def as_json(self) -> dict[str, float]:
        return {"position_m": self.position_m, "heading_rad": self.heading_rad,
                "cov_rel": self.cov_rel}


def estimate_difference(recorded: Sequence[float], replayed: Sequence[float]) -> Difference:
    """The difference of two estimates stored as ``estimate_values`` (nine numbers per
    robot); infinite when their lengths differ or one is NaN where the other is not. The
    covariance's scale is the replayed one's (an edited recorded value cannot widen it)."""
    n = len(recorded)
    if n != len(replayed) or n % VALUES_PER_ROBOT:
        return Difference(math.inf, math.inf, math.inf)
    pos = head = cov = 0.0
    for r in range(0, n, VALUES_PER_ROBOT):
        a, b = recorded[r:r + VALUES_PER_ROBOT], replayed[r:r + VALUES_PER_ROBOT]
        pos = max(pos, _gap(a[0], b[0]), _gap(a[1], b[1]))
        head = max(head, _gap(a[2], b[2], wrap=True))
        diag = {0: b[3], 1: b[6], 2: b[8]}  # the replay's: finite (validate_estimate)
        for k, (i, j) in enumerate(_UPPER):
            scale = math.sqrt(abs(diag[i] * diag[j]))
            cov = max(cov, _gap(a[3 + k], b[3 + k]) / max(scale, COV_SCALE_FLOOR))
    return Difference(pos, head, cov)


def _gap(a: float, b: float, wrap: bool = False) -> float:
    """|a - b| (an angle's wrapped to [0, pi]); 0 for two NaN, infinite for one."""
    if math.isnan(a) or math.isnan(b):
        return 0.0 if math.isnan(a) and math.isnan(b) else math.inf
    if a == b:
        return 0.0
    d = a - b
    if wrap and math.isfinite(d):
        d = math.remainder(d, 2 * math.pi)
    return abs(d)


def old_maths_text(tick: int, dt: float, what: str) -> str:
    """The status of a replay whose truth or readings differ from a recording that does not
    say which maths made it (format version 3 and older): not an edit we can name, not
    verified either."""
    return (f"not verified: made before beacon-sim's portable maths (or on a machine whose "
            f"maths differs), so its truth and readings cannot be verified here (the replay "
            f"first differs at tick {tick}, t = {tick * dt:g} s, checked against {what}); "
            f"replayed from its recorded commands")
