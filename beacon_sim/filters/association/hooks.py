"""The filters' hooks: each filter calls one at the start of its update and returns at
once when every sensor tells its IDs. :func:`associate_gaussian` (EKF, UKF: NN or JCBB at
the predicted belief, optionally with an inflated gate or ambiguous readings refused),
:func:`particle_loglik` / :func:`particle_start` (per-particle maximum likelihood),
:func:`grid_mixture` (the histogram's mixture over the beacons). The parameters they read
are :data:`GAUSSIAN_PARAMS`; what they chose is reported by ``FilterBase.associations()``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.types import Measurement
from beacon_sim.filters.association.jcbb import jcbb
from beacon_sim.filters.association.linearised import (
    GATE_PROB,
    READING_DIMS,
    Linearised,
    gate,
    linearise,
)
from beacon_sim.filters.association.nearest_neighbour import nearest_neighbour
from beacon_sim.filters.association.per_particle import particle_d2
from beacon_sim.filters.base import FilterContext, FilterError

#: The Gaussian filters' association methods (parameter ``association``).
METHODS = ("nn", "jcbb")


#: The parameters the EKF and the UKF take for unknown correspondence, with their defaults:
#: the method, its gate's probability, the factor on the innovation covariance S the gate
#: and the joint test use (1: as the filter's update), and the share of the gated beacons'
#: likelihood the nearest beacon's group must hold for a reading to be associated, else it
#: is refused as ambiguous (dropped as clutter; :func:`refuse_ambiguous`; 0: off).
GAUSSIAN_PARAMS = {"association": "nn", "association_prob": GATE_PROB, "association_inflation": 1.0,
                   "unambiguous_share": 0.0}


#: The share of unlabeled readings the particle and histogram filters take as clutter at
#: least (their likelihood's floor): a reading no beacon explains costs a bounded amount.
MIN_CLUTTER_SHARE = 0.01


def is_unlabeled(m: Measurement) -> bool:
    """Whether a reading carries no beacon IDs (every entry ``UNKNOWN_ID``): beacon kinds only."""
    return m.kind in READING_DIMS and len(m) > 0 and bool(np.all(np.asarray(m.beacon_ids) == UNKNOWN_ID))


class _Wiring:
    """One filter's association state: the map, whether any sensor is unlabeled, and what
    the last update associated (``last``: sensor name -> beacon ID or None per row)."""

    def __init__(self, ctx: FilterContext, method: str = "nn", prob: float = GATE_PROB,
                 inflation: float = 1.0, share: float = 0.0):
        if method not in METHODS:
            raise FilterError(f"{ctx.name}: association = {method!r}: expected one of "
                              + ", ".join(map(repr, METHODS)))
        if not 0.0 < prob < 1.0:
            raise FilterError(f"{ctx.name}: association_prob = {prob!r}: expected a probability in (0, 1)")
        if not (isinstance(inflation, int | float) and math.isfinite(inflation) and inflation >= 1.0):
            raise FilterError(f"{ctx.name}: association_inflation = {inflation!r}: expected a number >= 1")
        if not (isinstance(share, int | float) and 0.0 <= share < 1.0):
            raise FilterError(f"{ctx.name}: unambiguous_share = {share!r}: expected a share in [0, 1)")
        self.inflation = float(inflation)
        self.share = float(share)
        self.ctx = ctx
        self.unknown = any(s.correspondence != "known" for s in ctx.sensors)
        self.xy = ctx.world.beacon_xy
        self.ids = ctx.world.beacon_ids
        self.method = method
        self.prob = float(prob)
        self.last: dict[str, tuple[int | None, ...]] = {}
        self.readings: list[Measurement] = []  # the last update's unlabeled readings

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        return dict(self.last)


def attach(flt: Any) -> None:
    """Give a Gaussian filter (EKF, UKF) its association state from ``flt.params``
    (``association``, ``association_prob``); FilterError for a bad value. Call in __init__."""
    p = flt.params
    flt._association = _Wiring(flt.ctx, p.get("association", "nn"), p.get("association_prob", GATE_PROB),
                               p.get("association_inflation", 1.0), p.get("unambiguous_share", 0.0))


def inflated(lin: Linearised, factor: float) -> Linearised:
    """``lin`` with every innovation covariance ``S`` (and the pose covariance and reading
    noise it is made of) multiplied by ``factor``: the distances ``d2`` divided by it. For
    association only: a wider gate and joint test for errors the update's model leaves out
    (real data's late readings, range bias); the update itself keeps its own ``S``."""
    if factor == 1.0:
        return lin
    return Linearised(lin.kind, lin.nu, lin.H, lin.P * factor, lin.r * factor, lin.S * factor,
                      lin.d2 / factor, None if lin.Z is None else lin.Z * factor)


def refuse_ambiguous(lin: Linearised, prob: float, share: float) -> Linearised:
    """``lin`` with every *ambiguous* reading made compatible with no beacon (its row of
    ``d2`` set to ``inf``, so it is dropped as clutter).

    The beacons a reading is compared with are those inside its gate (``d2 <= gate(prob,
    d)``); each has the Gaussian likelihood ``exp(-d2 / 2) / sqrt(det S)`` (equal priors).
    The nearest beacon's *group* is the gated beacons the sensor cannot tell from it: their
    expected readings differ from the nearest's by at most the gate under the reading noise
    R alone (``dz^T R^-1 dz <= gate``, ``dz`` the difference of the two expected readings,
    bearing wrapped). The reading is ambiguous when its nearest beacon's group holds less
    than ``share`` of the gated beacons' summed likelihood: a beacon the sensor could tell
    apart fits it nearly as well, and only the pose's uncertainty makes both fit. The nearest
    would then be a guess that, when wrong, pulls the pose towards the wrong beacon and makes
    the next wrong pairing likelier (real data after a long blind stretch: a heading 20
    degrees off, readings given a beacon a metre from theirs). A group of landmarks 18-25 cm
    apart seen from metres counts as one: the nearest is kept, wrong by at most their
    distance."""
    g = gate(prob, lin.dim)
    m, n = lin.d2.shape
    if n < 2 or m == 0:
        return lin
    gated = lin.d2 <= g                                     # (m, n)
    if not (gated.sum(axis=1) >= 2).any():
        return lin
    rows = np.arange(m)
    best = np.argmin(lin.d2, axis=1)
    dz = lin.nu[rows, best][:, None, :] - lin.nu            # h_j - h_best, (m, n, d)
    dz[..., -1] = wrap(dz[..., -1])
    alike = np.einsum("mnd,d->mn", dz * dz, 1.0 / lin.r) <= g
    with np.errstate(divide="ignore", invalid="ignore"):
        logdet = np.linalg.slogdet(lin.S)[1]                # (n,)
        like = np.where(gated, np.exp(-0.5 * (lin.d2 - lin.d2[rows, best][:, None])
                                      - 0.5 * (logdet[None, :] - logdet[best][:, None])), 0.0)
    total = like.sum(axis=1)
    ambiguous = gated[rows, best] & (np.where(alike, like, 0.0).sum(axis=1) < share * total)
    if not ambiguous.any():
        return lin
    d2 = lin.d2.copy()
    d2[ambiguous] = np.inf
    return Linearised(lin.kind, lin.nu, lin.H, lin.P, lin.r, lin.S, d2, lin.Z)


def associate_gaussian(flt: Any, measurements: Sequence[Measurement]) -> Sequence[Measurement]:
    """The EKF's and UKF's hook: each unlabeled reading associated at the predicted belief
    (``flt.mean``, ``flt.cov``) by nearest neighbour or JCBB; returned as a labeled reading
    of the rows that got a beacon (the others are dropped as clutter). Labeled readings pass
    unchanged, and so does everything when no sensor has unknown correspondence."""
    w: _Wiring = flt._association
    if not w.unknown:
        return measurements
    w.last = {}
    out: list[Measurement] = []
    for m in measurements:
        if not is_unlabeled(m):
            out.append(m)
            continue
        lin = inflated(linearise(m.kind, m.z, flt.mean, flt.cov, w.xy,
                                 flt.ctx.sensor(m.sensor).reading_std()), w.inflation)
        if w.share > 0.0:
            lin = refuse_ambiguous(lin, w.prob, w.share)
        found = (jcbb if w.method == "jcbb" else nearest_neighbour)(lin, w.ids, w.prob)
        w.last[m.sensor] = found.beacon_ids
        keep = [i for i, b in enumerate(found.beacon_ids) if b is not None]
        if keep:
            out.append(Measurement(m.sensor, m.kind, np.asarray(m.z)[keep],
                                   np.array([found.beacon_ids[i] for i in keep], dtype=int)))
    return out


class _ParticleWiring(_Wiring):
    """The particle filter's state: each particle's choice per reading of the last update."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.choices: dict[str, np.ndarray] = {}  # sensor -> (N, m) beacon rows, -1 clutter

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        """Per reading, the beacon the particles chose with the most weight (None when the
        weight of those calling it clutter is larger)."""
        w = np.asarray(flt.weights(), dtype=float)
        out: dict[str, tuple[int | None, ...]] = {}
        for name, best in self.choices.items():
            if best.shape[0] != w.size:
                continue  # the set changed since (resampled): nothing to say
            row: list[int | None] = []
            for i in range(best.shape[1]):
                votes = np.bincount(best[:, i] + 1, weights=w, minlength=len(self.ids) + 1)
                j = int(np.argmax(votes)) - 1
                row.append(None if j < 0 else int(self.ids[j]))
            out[name] = tuple(row)
        return out


def particle_loglik(flt: Any, m: Measurement, ll: np.ndarray) -> int:
    """The particle filter's hook for an unlabeled reading: each particle takes, for each
    row, its maximum-likelihood beacon (:func:`particle_ml_association`) and adds
    ``-0.5 min(d2, gate)`` to ``ll`` (n,): a row no beacon explains within the gate counts as
    clutter, a bounded cost. Returns the number of scalar readings (as ``_loglik``)."""
    w = flt.__dict__.get("_association")
    if not isinstance(w, _ParticleWiring):
        w = flt._association = _ParticleWiring(flt.ctx)
    n = flt.n
    spec = flt.ctx.sensor(m.sensor)
    poses = np.asarray(flt._P[:, :n], dtype=float).T
    best, d2 = particle_d2(m.kind, m.z, poses, w.xy, spec.reading_std())
    g = gate(w.prob, READING_DIMS[m.kind])
    w.choices[m.sensor] = np.where(d2 <= g, best, -1)
    # Not counted by the filter's "lost" test (augmented MCL's random particles): with clutter
    # a row no beacon explains is the expected case, and a tick of clutter alone looked like
    # a kidnap; random particles then explained the clutter with some beacon and the cloud
    # left the truth (default with clutter_rate = 0.3: 2.6 m RMSE against 0.09 m).
    ll += -0.5 * np.minimum(d2, g).sum(axis=1)
    return int(np.asarray(m.z).size)


def particle_start(flt: Any) -> None:
    """Forget the last update's per-particle choices (called at each update's start)."""
    w = flt.__dict__.get("_association")
    if isinstance(w, _ParticleWiring):
        w.choices = {}


class _GridWiring(_Wiring):
    """The histogram filter's state: the last update's unlabeled readings, to report; and what
    :func:`grid_mixture` needs of each beacon on the x-y grid that never changes (the grid does
    not move), kept instead of worked out again on every reading."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self._terms: dict[tuple[str, int], tuple[np.ndarray, ...]] = {}
        self._in_range: dict[tuple[int, float], np.ndarray] = {}
        self._scratch = np.empty(0)

    def beacon_terms(self, flt: Any, sensor: str, std: np.ndarray, b: int) -> tuple[np.ndarray, ...]:
        """Flat (nx ny,) arrays over the grid's cells: beacon ``b``'s range [m], the von
        Mises concentration kappa [1/rad^2] (bearing noise inflated by the bin and the cell),
        ``-kappa + log`` of its normaliser, and the cosine and sine of the beacon's direction:
        the arithmetic :func:`grid_mixture` did on each reading's cells, done once on all."""
        key = (sensor, b)
        got = self._terms.get(key)
        if got is None:
            r = flt._r[b].reshape(-1)
            cell_var = flt.cell ** 2 / 6.0
            kappa = 1.0 / (std[-1] ** 2 + flt.bin ** 2 / 12 + cell_var / np.maximum(r, flt.cell) ** 2)
            head = -kappa + 0.5 * np.log(kappa / (2.0 * math.pi))
            got = self._terms[key] = (r, kappa, head, flt._ca[b].reshape(-1), flt._sa[b].reshape(-1))
        return got

    def in_range(self, b: int, r: np.ndarray, reach: float) -> np.ndarray:
        """The flat indices of the cells within ``reach`` [m] of beacon ``b`` (kept)."""
        got = self._in_range.get((b, reach))
        if got is None:
            got = self._in_range[(b, reach)] = np.flatnonzero(r <= reach)
        return got

    def scratch(self, rows: int, cols: int) -> np.ndarray:
        """A (rows, cols) float array to work in, reused from call to call."""
        if self._scratch.size < rows * cols:
            self._scratch = np.empty(rows * cols)
        return self._scratch[: rows * cols].reshape(rows, cols)

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        """Per reading, the beacon most likely at the grid's most probable cell and heading
        (None when the clutter term is larger there)."""
        if not self.readings:
            return {}
        h, i, j = np.unravel_index(int(np.argmax(flt.grid)), flt.grid.shape)
        pose = np.array([flt.xc[i], flt.yc[j], float(flt.theta[h])])
        out: dict[str, tuple[int | None, ...]] = {}
        for m in self.readings:
            std = flt.ctx.sensor(m.sensor).reading_std()
            # the grid knows the pose to a cell and a heading bin: the filter's own inflation
            var = std ** 2 + (np.array([flt.cell ** 2 / 6.0, flt.bin ** 2 / 12.0])[-std.size:])
            best, d2 = particle_d2(m.kind, m.z, pose[None, :], self.xy, np.sqrt(var))
            g = gate(self.prob, READING_DIMS[m.kind])
            out[m.sensor] = tuple(int(self.ids[b]) if d <= g else None
                                  for b, d in zip(best[0], d2[0], strict=True))
        return out


def grid_mixture(flt: Any, measurements: Sequence[Measurement], cos_th: np.ndarray,
                 sin_th: np.ndarray) -> tuple[list[Measurement], np.ndarray | None]:
    """The histogram filter's hook: the labeled readings (to go on as before) and the
    log-likelihood over the grid (nh, nx, ny) of the unlabeled ones, or None if there are
    none. Each unlabeled row's likelihood is a mixture over the beacons, uniform weights,
    plus clutter: ``p(z | x) = (1 - c) / n sum_b N_b(z | x) + c u`` with ``u`` uniform over
    bearings (and ranges up to ``max_range``) and ``c`` the sensor's clutter share
    (``rate / (1 + rate)``, at least ``MIN_CLUTTER_SHARE``). Each beacon's term is the
    filter's own von Mises bearing (noise inflated by the cell and the bin) and Gaussian range."""
    w = flt.__dict__.get("_association")
    if not isinstance(w, _GridWiring):
        w = flt._association = _GridWiring(flt.ctx)
    w.readings = []
    if not w.unknown:
        return list(measurements), None
    labeled: list[Measurement] = []
    total: np.ndarray | None = None
    cell_var = flt.cell ** 2 / 6.0
    nb = len(w.ids)
    for m in measurements:
        if not is_unlabeled(m):
            labeled.append(m)
            continue
        w.readings.append(m)
        spec = flt.ctx.sensor(m.sensor)
        std = spec.reading_std()
        c = max(spec.clutter_rate / (1.0 + spec.clutter_rate), MIN_CLUTTER_SHARE)
        rmax = spec.max_range if math.isfinite(spec.max_range) else math.hypot(flt.ctx.world.width,
                                                                              flt.ctx.world.height)
        log_u = -math.log(2.0 * math.pi) - (math.log(rmax) if m.kind == "range_bearing" else 0.0)
        base0 = math.log(c) + log_u           # the clutter term: the floor of the mixture
        share = math.log((1.0 - c) / nb)
        ranged = m.kind == "range_bearing"
        sr2 = std[0] ** 2 + cell_var if ranged else 1.0
        terms = [w.beacon_terms(flt, m.sensor, std, b) for b in range(nb)]
        for row in np.asarray(m.z, dtype=float):
            cz, sz = math.cos(row[-1]), math.sin(row[-1])
            # sum_b exp(term_b - base0), only where beacon b can explain the row (a range
            # within 6 sigma, a cell within max_range): the rest of each term is below
            # e^-18 of the floor and is left out.
            acc = np.zeros(flt.grid.shape)
            acc_flat = acc.reshape(flt.nh, -1)
            for b, (r, kappa_all, head_all, ca_all, sa_all) in enumerate(terms):
                if ranged:
                    lr = -0.5 * (r - row[0]) ** 2 / sr2
                    where = np.flatnonzero(lr > -18.0)
                else:
                    where = w.in_range(b, r, rmax + flt.cell)
                if where.size == 0:
                    continue
                kappa = kappa_all[where]
                ca, sa = ca_all[where], sa_all[where]
                # kappa (cos(z - alpha + theta) - 1) + log of the von Mises' normaliser
                core = w.scratch(flt.nh, where.size)
                np.multiply(cos_th[:, :, 0], (kappa * (cz * ca + sz * sa))[None], out=core)
                core -= sin_th[:, :, 0] * (kappa * (sz * ca - cz * sa))[None]
                base = head_all[where] + share - base0
                if ranged:
                    base = base + lr[where] - 0.5 * math.log(2.0 * math.pi * sr2)
                core += base[None]
                np.minimum(core, 700.0, out=core)
                np.exp(core, out=core)
                acc_flat[:, where] += core
            mix = base0 + np.log1p(acc)
            total = mix if total is None else total + mix
    return labeled, total
