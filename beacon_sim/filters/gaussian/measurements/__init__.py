"""What the Gaussian filters share, for one run or for R runs at once (a module of each idea
below; this package re-exports their names, so ``from beacon_sim.filters.gaussian.measurements
import X`` keeps working).

Shapes: one run has a mean (3,) [m, m, rad], a covariance (3, 3) and m readings (m,); R runs
(``evaluation.montecarlo`` batches them) add a leading axis: (R, 3), (R, 3, 3), (R, M). The
array functions here take either, so one piece of code serves both forms.

- Readings: all readings of a tick (any sensors, any number of beacons) become one vector
  ``z``, one diagonal noise variance vector ``r`` and the angle rows (bearings, the heading
  of a pose fix), whose residuals are wrapped. ``stack`` does it for one run;
  ``SlotPacker`` for R runs, in slots fixed by the sensors (every beacon of every beacon
  sensor, every fix row), so a run's numbers never depend on the other runs of its batch.
  Empty slots have z = 0, r = 1 and ``valid`` False: H = 0 and innovation 0 there, so they
  add an identity block to S and a zero column to K, i.e. nothing.
- The stacked model: ``StackedReadings.predict`` (h at many poses, the UKF's) and
  ``StackedReadings.linearise`` (H and the innovation, the EKF's and the KF's).
- The Kalman update ``kalman_update`` (S, K, mean, Joseph or plain P), the NIS ``nis``.
- The velocity model's process noise ``process_cov_terms``.
- ``BatchableFilter``: a filter that declares the parameters its R-run form reproduces.

Noise comes from the filter's context: ``reading_std()`` for beacon readings,
``fix_std(len(beacon_ids), hdop)`` for pose and position fixes.
"""

from beacon_sim.filters.gaussian.measurements.batching import (
    BatchableFilter,
    BatchedGaussian,
)
from beacon_sim.filters.gaussian.measurements.gates import (
    OUTLIER_GATE_QUANTILE,
    READING_DOF,
    effective_gate,
    gate_blocks,
    gated_rows,
    outlier_gate,
)
from beacon_sim.filters.gaussian.measurements.kalman import (
    LOW_RANK_ROWS,
    add_diagonal,
    corrected_mean,
    kalman_update,
    kalman_update_full,
    kalman_update_low_rank,
    nis,
    nis_low_rank,
    solve,
    symmetrise,
)
from beacon_sim.filters.gaussian.measurements.process_noise import (
    cov_entries,
    cov_matrix,
    process_cov_terms,
)
from beacon_sim.filters.gaussian.measurements.readings import (
    ALL_ROWS,
    ANGLE_PATTERN,
    BEACON_KINDS,
    FIX_KINDS,
    KINDS,
    PRESENT_FRACTION,
    AngleRows,
    Block,
    ReadingModels,
    StackedReadings,
    angle_rows,
    model_readings,
    stack,
)
from beacon_sim.filters.gaussian.measurements.slots import SlotPacker

__all__ = [
    "ALL_ROWS",
    "ANGLE_PATTERN",
    "BEACON_KINDS",
    "FIX_KINDS",
    "KINDS",
    "LOW_RANK_ROWS",
    "OUTLIER_GATE_QUANTILE",
    "PRESENT_FRACTION",
    "READING_DOF",
    "AngleRows",
    "BatchableFilter",
    "BatchedGaussian",
    "Block",
    "ReadingModels",
    "SlotPacker",
    "StackedReadings",
    "add_diagonal",
    "angle_rows",
    "corrected_mean",
    "cov_entries",
    "cov_matrix",
    "effective_gate",
    "gate_blocks",
    "gated_rows",
    "kalman_update",
    "kalman_update_full",
    "kalman_update_low_rank",
    "model_readings",
    "nis",
    "nis_low_rank",
    "outlier_gate",
    "process_cov_terms",
    "solve",
    "stack",
    "symmetrise",
]
