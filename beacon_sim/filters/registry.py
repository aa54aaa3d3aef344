"""The built-in filters: one record each (docs/filters.md, "Adding a built-in filter").

A record says everything the rest of the program needs to know about a built-in filter:
its name, where its class is (imported only when used), its batched form for Monte Carlo
runs, the documented range of each parameter (beside the class's ``defaults``), how it is
drawn, and the parameters a MRCLAM run gives it. The tables other modules read are
derived from these records: ``BUILTIN_FILTERS`` (hosting/loading.py), the parameter checks
(filters/param_ranges.py), ``KIND_STYLES`` and ``TEAM_STYLES`` (runs/styles.py) and
``MRCLAM_PARAMS`` (runs/mrclam.py). Adding a built-in filter = its module + one record.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from beacon_sim.core.world import World
from beacon_sim.filters.params import MAX_PARTICLES, Param, Range, grid_memory, particle_memory

#: Chi-square gate for one range-bearing reading (2 dof, 99.9 %): on by default in MRCLAM
#: runs of the EKF and UKF.
MRCLAM_GATE_CHI2 = 13.8155

#: The colour names a record may use (runs/styles.py maps them to Okabe-Ito RGB).
COLOUR_NAMES = ("blue", "vermillion", "reddish purple", "bluish green", "orange", "sky blue",
                "yellow", "grey", "black")
#: The line styles a record may use (runs/styles.py maps them to dash patterns).
DASH_NAMES = ("solid", "dashed", "dotted", "dash-dot", "short dash")

#: A memory bound: raises FilterError when the parameters ask for too much in this world.
MemoryCheck = Callable[[str, Mapping[str, Any], World], None]


@dataclass(frozen=True)
class FilterRecord:
    """One built-in filter.

    Attributes
    ----------
    name : str
        The name users type (``--filter ekf``); also its kind for drawing.
    target : str
        ``"module:Class"`` of the filter class (a team filter: the callable that builds it).
    style : (str, str)
        Colour (one of :data:`COLOUR_NAMES`) and line style (one of :data:`DASH_NAMES`).
    ranges : mapping str -> Range
        The documented range of the number parameters, keyed as the class's ``defaults``.
    batched : str or None
        ``"module:Class"`` of the form ``flt.batched(R)`` returns (R runs as arrays), or
        None when the filter has none.
    mrclam : mapping
        Parameters a MRCLAM run gives it unless the caller sets them.
    mrclam_robust : bool
        True when it weighs readings with the calibrated outlier mixture: a MRCLAM run tells
        it the noise pooled from the other robots, not the inflation that makes the Gaussian
        filters consistent on them (runs/mrclam.py ``held_out_inflation``).
    memory : callable or None
        The bound on what its parameters may allocate (``filters/params.py``).
    team : bool
        True for a team filter (``filters/team.py``), built from a ``TeamContext``.
    """

    name: str
    target: str
    style: tuple[str, str]
    ranges: Mapping[str, Range] = field(default_factory=dict)
    batched: str | None = None
    mrclam: Mapping[str, Any] = field(default_factory=dict)
    mrclam_robust: bool = False
    memory: MemoryCheck | None = None
    team: bool = False

    @property
    def module(self) -> str:
        return self.target.partition(":")[0]

    def load(self) -> Any:
        """The filter class (imports its module)."""
        return _load(self.target)

    def load_batched(self) -> type | None:
        """The batched class, or None."""
        return None if self.batched is None else _load(self.batched)

    def params(self) -> dict[str, Param]:
        """Every parameter of the class as a :class:`Param`: the default from the class's
        ``defaults``, the range and text from :attr:`ranges`."""
        defaults = getattr(self.load(), "defaults", None) or {}
        return {key: Param.of(default, self.ranges.get(key)) for key, default in defaults.items()}


def _load(target: str) -> Any:
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


_GATE = Range(0.0, 1e6, "chi-square gate on a reading's NIS; 0 = no gate")
_FRACTION = (0.0, 1.0)
_N = (1, MAX_PARTICLES)

RECORDS: dict[str, FilterRecord] = {r.name: r for r in (
    FilterRecord("kf", "beacon_sim.filters.gaussian.kf:KalmanFilter", ("blue", "solid"),
                 batched="beacon_sim.filters.gaussian.kf:BatchedKF"),
    FilterRecord("ekf", "beacon_sim.filters.gaussian.ekf:ExtendedKalmanFilter", ("vermillion", "solid"),
                 ranges={"gate_chi2": _GATE},
                 batched="beacon_sim.filters.gaussian.ekf:BatchedEKF",
                 mrclam={"gate_chi2": MRCLAM_GATE_CHI2}),
    FilterRecord("ukf", "beacon_sim.filters.gaussian.ukf:UnscentedKalmanFilter", ("bluish green", "dashed"),
                 ranges={"alpha": Range(1e-4, 10.0, "sigma-point spread"),
                         "beta": Range(0.0, 100.0, "prior knowledge of the distribution (2: Gaussian)"),
                         "kappa": Range(-2.5, 100.0, "secondary scaling"),
                         "gate_chi2": _GATE},
                 batched="beacon_sim.filters.gaussian.ukf_batched:BatchedUKF",
                 mrclam={"gate_chi2": MRCLAM_GATE_CHI2}),
    FilterRecord("pf", "beacon_sim.filters.particle.pf:ParticleFilter", ("reddish purple", "dotted"),
                 ranges={"n_particles": Range(*_N, "particles (fixed size)"),
                         "n_min": Range(*_N, "fewest particles (adaptive size)"),
                         "n_max": Range(*_N, "most particles (adaptive size)"),
                         "ess_threshold": Range(*_FRACTION, "resample when ESS < this share of N"),
                         "alpha_slow": Range(*_FRACTION, "long-term likelihood average rate (per update)"),
                         "alpha_fast": Range(*_FRACTION, "short-term likelihood average rate (per update)"),
                         "inject_max": Range(*_FRACTION, "most random particles per resampling [share]"),
                         "kld_epsilon": Range(1e-6, 1.0, "KLD bound between sample and true posterior"),
                         "kld_z": Range(0.0, 10.0, "upper standard normal quantile"),
                         "kld_bin_xy": Range(1e-3, 1e3, "KLD histogram bin [m]"),
                         "kld_bin_theta": Range(1e-3, 2 * math.pi, "KLD histogram bin [rad]"),
                         "ver_max": Range(0.0, 1e12, "seed 002: stop drawing past this summed fit"),
                         "roughen": Range(0.0, 100.0, "jitter after resampling [kernel bandwidths]"),
                         "cluster_cell": Range(1e-3, 1e6, "coarse grid for finding the dominant mode [m]"),
                         "cluster_radius": Range(1e-3, 1e6, "particles this near the mode form it [m]"),
                         "heading_k_a": Range(0.0, 100.0, "K_a of seed 002 eq. 13"),
                         "temper_ess": Range(*_FRACTION, "progressive correction below this ESS share"),
                         "update_min_d": Range(0.0, 1e3, "weight only after moving this far [m]"),
                         "update_min_a": Range(0.0, 2 * math.pi, "weight only after turning this much [rad]"),
                         "lost_chi2": Range(1e-6, 1.0 - 1e-12, "a reading is unexplained when even the best "
                                                                "particle is beyond this chi-square point")},
                 mrclam={"n_particles": 4000, "augmented": False, "roughen": 1.25}, mrclam_robust=True,
                 memory=particle_memory),
    FilterRecord("histogram", "beacon_sim.filters.grid.histogram:HistogramFilter", ("orange", "dash-dot"),
                 ranges={"cell": Range(1e-3, 1e3, "x-y cell size [m]"),
                         "heading_bins": Range(4, 3600, "heading bins over 2 pi"),
                         "floor": Range(0.0, 0.999, "share spread uniformly after an update"),
                         "blur_min": Range(1e-6, 1e3, "motion blur once its variance reaches this * cell^2"),
                         "grid_noise": Range(0.0, 1e6, "a cell^2/12 of noise per this driving [s]")},
                 # No uniform floor on real data with a known start: it turns an unlucky run
                 # of outliers into a jump across the room (robot 5: 4.5 m).
                 mrclam={"floor": 0.0}, mrclam_robust=True,
                 memory=grid_memory),
    # Scan-based MCL on an occupancy grid, with ROS amcl's parameter names.
    FilterRecord("mcl", "beacon_sim.filters.particle.mcl:MonteCarloLocalization", ("sky blue", "dotted"),
                 ranges={"min_particles": Range(*_N, "KLD-sampling's fewest particles"),
                         "max_particles": Range(*_N, "KLD-sampling's most particles"),
                         "kld_err": Range(1e-6, 1.0, "KLD bound between sample and true posterior"),
                         "kld_z": Range(0.0, 10.0, "normal quantile of the KLD bound"),
                         "kld_bin_xy": Range(1e-3, 1e3, "KLD histogram bin [m]"),
                         "kld_bin_theta": Range(1e-3, 2 * math.pi, "KLD histogram bin [rad]"),
                         "recovery_alpha_slow": Range(*_FRACTION, "long-term likelihood average rate"),
                         "recovery_alpha_fast": Range(*_FRACTION, "short-term likelihood average rate"),
                         "resample_interval": Range(1, 1000, "resample after every n-th update"),
                         "update_min_d": Range(0.0, 1e3, "update after moving this far [m]"),
                         "update_min_a": Range(0.0, 2 * math.pi, "update after turning this much [rad]"),
                         "laser_max_beams": Range(1, 4096, "beams used per scan"),
                         "laser_z_hit": Range(0.0, 1e3, "beam model: hit weight"),
                         "laser_z_short": Range(0.0, 1e3, "beam model: short weight"),
                         "laser_z_max": Range(0.0, 1e3, "beam model: max-range weight"),
                         "laser_z_rand": Range(0.0, 1e3, "beam model: random weight"),
                         "laser_sigma_hit": Range(1e-6, 1e3, "hit std [m]"),
                         "laser_lambda_short": Range(1e-6, 1e3, "short-reading rate [1/m]"),
                         "laser_likelihood_max_dist": Range(1e-3, 1e3, "likelihood field's distance cap [m]"),
                         "laser_max_range": Range(-1.0, 1e6, "max range [m]; -1: the sensor's"),
                         "min_distinct": Range(0.0, 1.0, "roughening below this share of distinct poses")}),
    # Seed 004's discrete Bayes filter on the corridor scenario's scans.
    FilterRecord("corridor", "beacon_sim.filters.grid.corridor:CorridorFilter", ("yellow", "dash-dot"),
                 ranges={"x0": Range(-1e6, 1e6, "the corridor's start [m]"),
                         "y_centre": Range(-1e6, 1e6, "its centre line [m]"),
                         "width": Range(1e-3, 1e3, "its width [m]"),
                         "cell": Range(1e-3, 1e3, "a cell's length [m]"),
                         "wall_dist": Range(1e-3, 1e3, "a beam shorter than this is a wall [m]")}),
    FilterRecord("dead_reckoning", "beacon_sim.filters.gaussian.dead_reckoning:DeadReckoning",
                 ("grey", "short dash"),
                 batched="beacon_sim.filters.gaussian.dead_reckoning:BatchedDeadReckoning"),
    # Landmark SLAM (docs/slam.md): the map is part of the estimate.
    FilterRecord("ekf_slam", "beacon_sim.filters.slam.ekf_slam:EKFSLAM", ("sky blue", "solid"),
                 ranges={"gate_prob": Range(0.5, 1.0 - 1e-9, "chi-square share a true pairing passes"),
                         "new_landmark_prob": Range(0.5, 1.0 - 1e-12, "farther than this quantile "
                                                                     "from all: a new landmark"),
                         "max_landmarks": Range(0, 10_000, "most landmarks in the state"),
                         "confirm_hits": Range(1, 1000, "readings before a new unlabelled landmark "
                                                        "is kept"),
                         "max_nodes": Range(1, 10_000_000, "most JCBB search nodes per tick"),
                         "min_parallax": Range(1e-3, 3.0, "angle between two bearings before a "
                                                          "landmark is triangulated [rad]"),
                         "gate_chi2": Range(0.0, 1e9, "drop a reading with an ID farther than this "
                                                      "squared Mahalanobis distance (0: off)")},
                 mrclam={"gate_chi2": MRCLAM_GATE_CHI2}),
    FilterRecord("fastslam", "beacon_sim.filters.slam.fastslam:FastSLAM2", ("yellow", "dash-dot"),
                 ranges={"n_particles": Range(1, 100_000, "particles, each with its own map"),
                         "ess_threshold": Range(*_FRACTION, "resample when ESS < this share of N"),
                         "gate_prob": Range(0.5, 1.0 - 1e-9, "chi-square share a true pairing passes"),
                         "new_landmark_prob": Range(0.5, 1.0 - 1e-12, "farther than this quantile "
                                                                     "from all: a new landmark"),
                         "max_landmarks": Range(0, 10_000, "most landmarks per particle"),
                         "confirm_hits": Range(1, 1000, "readings before a new unlabelled landmark "
                                                        "is kept"),
                         "gate_chi2": Range(0.0, 1e9, "a particle rejects a reading with an ID farther "
                                                      "than this squared Mahalanobis distance (0: off)")},
                 mrclam={"gate_chi2": MRCLAM_GATE_CHI2}),
    # Team filters (filters/team.py): the baseline that ignores the teammates is grey like
    # dead reckoning; naive fusion, the overconfident counter-example, vermillion and dotted.
    FilterRecord("independent", "beacon_sim.filters.team:IndependentTeam", ("grey", "short dash"),
                 team=True),
    FilterRecord("centralised", "beacon_sim.filters.team:CentralisedEKF", ("blue", "solid"),
                 ranges={"gate_chi2": _GATE}, team=True),
    FilterRecord("decentralised", "beacon_sim.filters.team:PairwiseDecentralisedEKF",
                 ("orange", "dash-dot"), ranges={"gate_chi2": _GATE}, team=True),
    FilterRecord("ci", "beacon_sim.filters.team:CovarianceIntersectionTeam", ("bluish green", "dashed"),
                 ranges={"gate_chi2": _GATE}, team=True),
    FilterRecord("naive", "beacon_sim.filters.team:_naive", ("vermillion", "dotted"), team=True),
)}


def single_records() -> Iterator[FilterRecord]:
    """The single-robot built-in filters, in listing order."""
    return (r for r in RECORDS.values() if not r.team)


def team_records() -> Iterator[FilterRecord]:
    """The team filters, in listing order."""
    return (r for r in RECORDS.values() if r.team)


def builtin_modules() -> tuple[str, ...]:
    """The module of every built-in filter (its class's and its batched form's), each once, in
    listing order: what a hosted filter's process imports before it may lose the right to read
    the installation (``PRELOAD`` in hosting/child.py), so a student may subclass any of them."""
    modules = [t.partition(":")[0] for r in RECORDS.values() for t in (r.target, r.batched) if t]
    return tuple(dict.fromkeys(modules))


def class_key(cls: type) -> str:
    """``module:QualName`` of a class (how a record's target names it)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def record_for_class(cls: type) -> FilterRecord | None:
    """The record whose target is ``cls``, or None (a student's class)."""
    key = class_key(cls)
    return next((r for r in RECORDS.values() if r.target == key), None)


class RecordTable(Mapping[str, Any]):
    """A read-only table ``name -> value(record)`` over the single-robot records (or the
    team ones, ``team=True``) that ``keep`` selects, computed from :data:`RECORDS` each
    time it is read, so a record added later (a test's toy filter) shows in it too."""

    def __init__(self, value: Callable[[FilterRecord], Any], team: bool = False,
                 keep: Callable[[FilterRecord], bool] = lambda r: True):
        self._value, self._team, self._keep = value, team, keep

    def _records(self) -> dict[str, FilterRecord]:
        return {n: r for n, r in RECORDS.items() if r.team == self._team and self._keep(r)}

    def __getitem__(self, name: str) -> Any:
        return self._value(self._records()[name])

    def __iter__(self) -> Iterator[str]:
        return iter(self._records())

    def __len__(self) -> int:
        return len(self._records())

    def __repr__(self) -> str:
        return repr(dict(self))


#: name -> "module:Class" of every single-robot built-in filter.
TARGETS: Mapping[str, str] = RecordTable(lambda r: r.target)
#: name -> the parameters a MRCLAM run gives it (only filters that have some).
MRCLAM_DEFAULTS: Mapping[str, Mapping[str, Any]] = RecordTable(lambda r: dict(r.mrclam),
                                                            keep=lambda r: bool(r.mrclam))
#: The filters a MRCLAM run tells the pooled noise, not the Gaussian filters' inflated one.
MRCLAM_ROBUST: Mapping[str, bool] = RecordTable(lambda r: True, keep=lambda r: r.mrclam_robust)


__all__ = ["COLOUR_NAMES", "DASH_NAMES", "MRCLAM_DEFAULTS", "MRCLAM_GATE_CHI2", "MRCLAM_ROBUST", "RECORDS",
           "TARGETS", "FilterRecord", "RecordTable", "builtin_modules", "class_key", "record_for_class",
           "single_records", "team_records"]
