"""FastSLAM 2.0 (Montemerlo, Thrun, Koller and Wegbreit 2003): particles over the path, each
with its own map of independent 2-D landmark EKFs (docs/slam.md).

FastSLAM 1.0 samples the new pose from the motion model alone and lets the readings only
weight it; with a sensor much better than the odometry almost every sample is then wasted.
FastSLAM 2.0 samples from a proposal that already uses the tick's readings. Per particle k,
starting from the motion prediction ``mu = f(x_k, u)``, ``Sigma = Q`` and for each reading
paired with landmark j (mean m_j, covariance C_j), linearised at the current ``mu``::

    nu = wrap(z - h(mu, m_j))               Hx = dh/dx, Hm = dh/dm
    Z = Hm C_j Hm^T + R                     the reading's noise plus the landmark's
    L = Hx Sigma Hx^T + Z                   predictive covariance of the reading
    K = Sigma Hx^T L^-1
    mu = mu + K nu,  Sigma = Sigma - K Hx Sigma   (the information form of the paper's
                                                   Sigma = (Hx^T Z^-1 Hx + Sigma^-1)^-1)
    w_k = w_k N(nu; 0, L)                   the importance weight: the reading's likelihood
                                            with the pose still unknown

then ``x_k ~ N(mu, Sigma)``, and each paired landmark gets an EKF update from the sampled
pose (``S = Hm C Hm^T + R``, ``K = C Hm^T S^-1``, ``m += K nu``, ``C -= K S K^T``).
A reading of a landmark not yet in a particle's map puts one there (``slam.base.place``,
``C = Gz R Gz^T``) and multiplies the weight by the density ``p0`` of a reading at the
``new_landmark_prob`` distance.

Association per particle (readings without IDs): each particle pairs each reading with its
own most likely landmark (lowest ``d2 + log det L``, against the motion-only proposal, all
the tick's readings at once), or with ``association = "jcbb"`` takes the jointly compatible
pairing of all of them (JCBB against the proposal, whose pose error the readings share);
within the ``gate_prob`` gate it is
used; beyond the ``new_landmark_prob`` quantile it starts a landmark; in between it only
weighs the particle by ``p0``. Particles with different maps can hold different pairings.
Anchors (beacons whose position the filter is given) are landmarks with C = 0 that are
never updated. Resampling (systematic) when the effective sample size falls below
``ess_threshold`` N.

Beside this module: the proposal's equations (``fastslam_proposal.py``), the association
per particle (``particle_association.py``) and the reported covariance
(``linearised_covariance.py``); their names are re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.motion import MotionNoise, move
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.association import gate as chi2_gate
from beacon_sim.filters.base import (
    FilterContext,
    FilterError,
    GaussianBelief,
    LandmarkMap,
    ParticleBelief,
    broad_gaussian,
)
from beacon_sim.filters.resampling import effective_sample_size, systematic
from beacon_sim.filters.slam.base import (
    Reading,
    SlamFilterBase,
    innovation,
    observe,
    place,
    unknown,
)
from beacon_sim.filters.slam.fastslam_proposal import inv_det, predictive_distance, proposal_step
from beacon_sim.filters.slam.linearised_covariance import LinearisedCovariance, without_rows
from beacon_sim.filters.slam.particle_association import EMPTY, GATED, IGNORED, NEW, ParticleAssociation


class FastSLAM2(SlamFilterBase, ParticleAssociation):
    """FastSLAM 2.0 with per-particle landmark EKFs, known or unknown correspondence.

    Parameters (``ctx.params``)
    ---------------------------
    n_particles : int, default 100
    ess_threshold : float, default 0.5
        Resample when the effective sample size drops below this share of N.
    gate_prob, new_landmark_prob : float, defaults 0.99, 0.9999
        Unknown correspondence, per particle (see the module docstring).
    max_landmarks : int, default 500
        Most landmarks per particle.
    confirm_hits : int, default 2
        Unknown correspondence: an unlabelled landmark is tentative until given this many
        readings; a tentative one in view that gets none is dropped (clutter).
    association : str, default "ml"
        Unknown correspondence, per particle: ``"ml"`` (each reading its most likely
        landmark, independently) or ``"jcbb"`` (joint compatibility over the tick's readings
        against the particle's proposal, each landmark at most once; ``association.jcbb_search``).
    max_nodes : int, default 200
        ``"jcbb"``: most search nodes per particle and tick; past them that particle keeps
        its maximum-likelihood pairing.
    covariance : str, default "linearised"
        What ``estimate()``, ``landmarks()`` and ``joint()`` report as the uncertainty (the
        means are the particles' either way). ``"particles"``: the particle set's own
        moments, which resampling makes overconfident in the long run (Bailey, Nieto and
        Nebot 2006). ``"linearised"``: the EKF-SLAM covariance recursion run alongside,
        linearised at the particles' mean each tick (:class:`LinearisedCovariance`), with
        known IDs; without IDs the particle set's.
    gate_chi2 : float, default 0.0
        Known IDs: the outlier gate (0: off; ``beacon-sim mrclam`` sets the EKF's 99.9 %
        gate, as for EKF-SLAM). A particle rejects a reading of a landmark (or anchor) it has
        when the squared Mahalanobis distance against its proposal, ``nu^T L^-1 nu`` with
        ``L = Hx Sigma Hx^T + Hm C Hm^T + R``, exceeds the gate. Whether a reading is an
        outlier is a property of the reading, not of a particle, so it is decided by the
        set: a reading every particle that has the landmark rejects (no pose and map in the
        set can explain it, e.g. a bearing flipped by pi) is dropped for all (no proposal
        step, no weight, no landmark update or new landmark; ``rejected`` counts them), and
        the linearised covariance's EKF-SLAM recursion drops the same readings. A reading
        some particle explains is used by all as without the gate: it is the evidence that
        tells the particles apart. (Tried and measured worse: letting each rejecting particle
        skip the reading and take the density at the gate boundary,
        ``exp(-gate/2) / sqrt(det(2 pi L))``. It caps what a true reading can say against a
        wrong particle, and on MRCLAM robot 1, where no reading is rejected by all, the
        path RMSE was 0.79 / 0.59 / 0.45 m against 0.73 / 0.39 / 0.33 m ungated over three
        random streams; docs/slam.md.)
    """

    defaults: ClassVar[dict] = {"n_particles": 100, "ess_threshold": 0.5, "gate_prob": 0.99,
                                "new_landmark_prob": 0.9999, "max_landmarks": 500, "confirm_hits": 2,
                                "association": "ml", "max_nodes": 200, "covariance": "linearised",
                                "gate_chi2": 0.0}

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.n = int(self.params["n_particles"])
        self.rng = ctx.rng
        self.n_anchor = len(self.anchors)
        if self.params["association"] not in ("ml", "jcbb"):
            raise FilterError(f"{type(self).__name__}: parameter association = "
                              f"{self.params['association']!r}: expected 'ml' or 'jcbb'")
        #: ``association = "jcbb"``: the last tick's particles searched, fallbacks, nodes.
        self.last_jcbb: dict[str, int] = {}
        if self.params["covariance"] not in ("linearised", "particles"):
            raise FilterError(f"{type(self).__name__}: parameter covariance = "
                              f"{self.params['covariance']!r}: expected 'linearised' or 'particles'")
        #: The last update's target of each reading row (in order) for each particle (N,):
        #: a landmark slot, NEW or IGNORED (after resampling: of the resampled particles).
        self.last_targets: list[np.ndarray] = []
        #: Readings with IDs every particle rejected (``gate_chi2``), dropped for all, so far.
        self.rejected = 0
        self.reset(None)

    # -- state -----------------------------------------------------------------------------
    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        n = self.n
        mean = np.asarray(initial.mean, dtype=float).reshape(3)
        cov = np.asarray(initial.cov, dtype=float).reshape(3, 3)
        self.poses = mean + self._draw(np.broadcast_to(0.5 * (cov + cov.T), (n, 3, 3)))
        self.poses[:, 2] = wrap(self.poses[:, 2])
        self.logw = np.zeros(n)
        A = self.n_anchor
        cap = max(8, A + 8)
        self.lm = np.zeros((n, cap, 2))
        self.lc = np.zeros((n, cap, 2, 2))
        self.lid = np.full((n, cap), EMPTY, dtype=np.int64)  # beacon ID, -1 unlabelled
        self.hits = np.zeros((n, cap), dtype=np.int64)        # readings each landmark was given
        for a, (bid, xy) in enumerate(self.anchors.items()):
            self.lm[:, a] = xy
            self.lid[:, a] = bid
        self.count = np.full(n, A, dtype=np.int64)  # slots in use or freed: the high-water mark
        self.prop_mu: np.ndarray | None = None   # the proposal between predict and update
        self.prop_cov: np.ndarray | None = None
        self.companion = LinearisedCovariance(self.ctx, initial) \
            if self.params["covariance"] == "linearised" else None

    def _draw(self, cov: np.ndarray) -> np.ndarray:
        """One zero-mean Gaussian sample per covariance (N, 3, 3) (semi-definite allowed)."""
        w, V = np.linalg.eigh(cov)
        root = V * np.sqrt(np.clip(w, 0.0, None))[:, None, :]
        return np.einsum("nij,nj->ni", root, self.rng.standard_normal((cov.shape[0], 3)))

    def _grow(self, need: int) -> None:
        cap = self.lm.shape[1]
        if need <= cap:
            return
        new = max(need, 2 * cap)
        n = self.n
        self.lm = np.concatenate([self.lm, np.zeros((n, new - cap, 2))], axis=1)
        self.lc = np.concatenate([self.lc, np.zeros((n, new - cap, 2, 2))], axis=1)
        self.lid = np.concatenate([self.lid, np.full((n, new - cap), EMPTY)], axis=1)
        self.hits = np.concatenate([self.hits, np.zeros((n, new - cap), dtype=np.int64)], axis=1)

    @property
    def weights(self) -> np.ndarray:
        w = np.exp(self.logw - np.max(self.logw))
        return w / np.sum(w)

    def _poses_now(self) -> np.ndarray:
        return self.poses if self.prop_mu is None else self.prop_mu

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        mean, cov = self._particle_estimate()
        if self._linearised():
            assert self.companion is not None
            cov = self.companion.ekf.P[:3, :3].copy()
        return mean, cov

    def _linearised(self) -> bool:
        """Whether the linearised covariance is what is reported: known IDs so far, and every
        landmark of the particles in it."""
        c = self.companion
        if c is None or not c.ok or np.any(self.lid == UNKNOWN_ID):
            return False
        mapped = self.lid[:, self.n_anchor:]
        return all(int(b) in c.ekf.index for b in np.unique(mapped[mapped >= 0]).tolist())

    def _particle_estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The particle set's weighted mean pose and covariance (plus, between predict and
        update, the proposals' own covariance)."""
        w = self.weights
        p = self._poses_now()
        th = math.atan2(float(w @ np.sin(p[:, 2])), float(w @ np.cos(p[:, 2])))
        mean = np.array([float(w @ p[:, 0]), float(w @ p[:, 1]), th])
        d = p - mean
        d[:, 2] = wrap(d[:, 2])
        cov = (d * w[:, None]).T @ d
        if self.prop_cov is not None:
            cov += np.einsum("n,nij->ij", w, self.prop_cov)
        return mean, 0.5 * (cov + cov.T)

    def belief(self) -> ParticleBelief:
        return ParticleBelief(self._poses_now().copy(), self.weights)

    def landmarks(self) -> LandmarkMap:
        """Known correspondence: each beacon's landmark as the weighted mixture over the
        particles that have it. Unknown: the map of the particle with the largest weight."""
        A = self.n_anchor
        w = self.weights
        ids_all = self.lid[:, A:]
        labelled = ids_all[ids_all > UNKNOWN_ID]
        if np.any(ids_all == UNKNOWN_ID):
            k = int(np.argmax(w))
            lid, hits = self.lid[k, A:], self.hits[k, A:]
            keep = (lid >= 0) | ((lid == UNKNOWN_ID) & (hits >= int(self.params["confirm_hits"])))
            return LandmarkMap(None, self.lm[k, A:][keep].copy(), self.lc[k, A:][keep].copy())
        ids = np.unique(labelled)
        means = np.zeros((ids.size, 2))
        covs = np.zeros((ids.size, 2, 2))
        for i, bid in enumerate(ids.tolist()):
            has = self.lid == bid
            rows = np.flatnonzero(has.any(axis=1))
            cols = has[rows].argmax(axis=1)
            wk = w[rows] / np.sum(w[rows])
            m = self.lm[rows, cols]
            means[i] = wk @ m
            d = m - means[i]
            covs[i] = np.einsum("n,nij->ij", wk, self.lc[rows, cols]) + (d * wk[:, None]).T @ d
        if self._linearised():
            assert self.companion is not None
            idx = self.companion.ekf.index
            for i, bid in enumerate(ids.tolist()):
                if bid in idx:
                    c = 3 + 2 * idx[bid]
                    covs[i] = self.companion.ekf.P[c:c + 2, c:c + 2]
        return LandmarkMap(ids, means, covs)

    def joint(self) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
        """The pose and the map as one Gaussian, for the joint NEES: mean (3 + 2M,), covariance
        and each landmark's beacon ID (-1 without IDs). The means are the particles' (pose:
        ``estimate()``; landmarks: ``landmarks()``); the covariance is the linearised one
        (``covariance = "linearised"``, known IDs) or the particle set's moments over the
        joint state: ``sum_k w_k (s_k - s)(s_k - s)^T`` plus each particle's landmark
        covariances on the diagonal blocks. Without IDs: the heaviest particle's map, its
        landmarks' covariances, no cross terms (particles' maps cannot be averaged)."""
        mean, cov = self.estimate()
        lm = self.landmarks()
        M = len(lm.means)
        mu = np.concatenate([mean, lm.means.reshape(-1)])
        if lm.ids is None:
            P = np.zeros((3 + 2 * M, 3 + 2 * M))
            P[:3, :3] = cov
            for j in range(M):
                P[3 + 2 * j:5 + 2 * j, 3 + 2 * j:5 + 2 * j] = lm.covs[j]
            return mu, P, (-1,) * M
        ids = [int(b) for b in lm.ids]
        if self._linearised():
            assert self.companion is not None
            ekf = self.companion.ekf
            rows = np.r_[0:3, np.array([[3 + 2 * ekf.index[b], 4 + 2 * ekf.index[b]] for b in ids],
                                       dtype=int).reshape(-1)]
            return mu, ekf.P[np.ix_(rows, rows)].copy(), tuple(ids)
        w = self.weights
        p = self._poses_now()
        S = np.zeros((self.n, 3 + 2 * M))
        S[:, :3] = p - mean
        S[:, 2] = wrap(S[:, 2])
        P = np.zeros((3 + 2 * M, 3 + 2 * M))
        if self.prop_cov is not None:
            P[:3, :3] = np.einsum("n,nij->ij", w, self.prop_cov)
        for j, bid in enumerate(ids):
            has = self.lid == bid
            rows_k = np.flatnonzero(has.any(axis=1))
            cols = has[rows_k].argmax(axis=1)
            S[rows_k, 3 + 2 * j:5 + 2 * j] = self.lm[rows_k, cols] - lm.means[j]
            P[3 + 2 * j:5 + 2 * j, 3 + 2 * j:5 + 2 * j] = np.einsum("n,nij->ij", w[rows_k] / w[rows_k].sum(),
                                                                  self.lc[rows_k, cols])
        P += (S * w[:, None]).T @ S
        return mu, 0.5 * (P + P.T), tuple(ids)

    def _mixture_means(self) -> dict[int, np.ndarray]:
        """Each labelled landmark's weighted mean over the particles that have it (beacon
        ID -> (2,)); with known IDs every particle has the same slots, one matrix product."""
        A = self.n_anchor
        w = self.weights
        lid = self.lid[:, A:int(self.count.max())]
        if lid.size and np.all(lid == lid[0]):
            cols = np.flatnonzero(lid[0] >= 0)
            means = np.einsum("n,nci->ci", w, self.lm[:, A + cols])
            return {int(lid[0, c]): means[q] for q, c in enumerate(cols.tolist())}
        out: dict[int, np.ndarray] = {}
        for bid in np.unique(lid[lid >= 0]).tolist():
            has = self.lid == bid
            rows = np.flatnonzero(has.any(axis=1))
            cols_k = has[rows].argmax(axis=1)
            out[int(bid)] = (w[rows] / w[rows].sum()) @ self.lm[rows, cols_k]
        return out

    # -- prediction ------------------------------------------------------------------------
    def predict(self, control: Control, dt: float) -> None:
        self._sample()  # a tick without update: the motion model alone is the proposal
        if self.companion is not None:
            self.companion.predict(self._particle_estimate()[0], control, dt)
        v, w = float(control.v), float(control.omega)
        noise = self.ctx.motion_noise
        self.prop_cov = self._process_covs(v, w, dt) if type(noise) is MotionNoise \
            else np.stack([noise.process_cov(p, v, w, dt) for p in self.poses])
        self.prop_mu = move(self.poses, v, w, dt)

    def _process_covs(self, v: float, w: float, dt: float) -> np.ndarray:
        """Q at every particle's heading: B M B^T + diag(pose_std^2) (motion.process_cov)."""
        noise = self.ctx.motion_noise
        M = noise.control_cov(v, w)
        th = self.poses[:, 2]
        B = np.zeros((self.n, 3, 2))
        B[:, 0, 0] = dt * np.cos(th)
        B[:, 1, 0] = dt * np.sin(th)
        B[:, 2, 1] = dt
        return B @ M @ B.transpose(0, 2, 1) + np.diag(np.square(noise.pose_std_at(v, w)))

    def _sample(self) -> None:
        if self.prop_mu is None or self.prop_cov is None:
            return
        self.poses = self.prop_mu + self._draw(self.prop_cov)
        self.poses[:, 2] = wrap(self.poses[:, 2])
        self.prop_mu = self.prop_cov = None

    # -- update ----------------------------------------------------------------------------
    def _log_p0(self, rd: Reading) -> float:
        """Log density of a reading at the new-landmark distance (the weight of a new one)."""
        d = rd.z.size
        t = chi2_gate(float(self.params["new_landmark_prob"]), d)
        return -0.5 * t - 0.5 * math.log((2.0 * math.pi) ** d * float(np.linalg.det(rd.R)))

    def update(self, measurements: Sequence[Measurement]) -> None:
        rows = list(self.readings(measurements))
        if not rows:
            self._sample()
            return
        if self.companion is not None:  # linearised at the estimate before the readings
            c_pose, c_means = self._particle_estimate()[0], self._mixture_means()
        if self.prop_mu is None or self.prop_cov is None:  # no predict since the last update
            self.prop_mu, self.prop_cov = self.poses.copy(), np.zeros((self.n, 3, 3))
        mu, Sig = self.prop_mu.copy(), self.prop_cov.copy()
        targets: dict[int, np.ndarray] = {}
        for sensor in dict.fromkeys(rd.sensor for rd in rows if unknown(rd)):
            pick = [i for i, rd in enumerate(rows) if unknown(rd) and rd.sensor == sensor]
            targets.update(zip(pick, self._unknown_targets([rows[i] for i in pick], mu, Sig), strict=True))
        done: list[tuple[Reading, np.ndarray]] = []
        dropped: list[int] = []
        gate = float(self.params["gate_chi2"])
        for i, rd in enumerate(rows):
            tgt = targets[i] if i in targets else self._known_targets(rd)
            k = np.flatnonzero(tgt >= 0)
            if gate > 0.0 and k.size and not unknown(rd):
                tgt = self._gate(rd, tgt, k, mu, Sig, gate)
                if np.all(tgt == GATED):
                    dropped.append(i)
                k = np.flatnonzero(tgt >= 0)
            if k.size:
                mu[k], Sig[k], loglik = proposal_step(rd.kind, rd.z, rd.R, mu[k], Sig[k],
                                                      self.lm[k, tgt[k]], self.lc[k, tgt[k]])
                self.logw[k] += loglik
            other = (tgt == NEW) | (tgt == IGNORED)
            if np.any(other):
                self.logw[other] += self._log_p0(rd)
            done.append((rd, tgt))
        self.rejected += len(dropped)
        if self.companion is not None:
            self.companion.update(c_pose, c_means, without_rows(measurements, dropped))
        self.prop_mu, self.prop_cov = mu, Sig
        self.last_targets = [tgt for _, tgt in done]
        self._sample()
        self._landmark_updates(done)
        self.logw -= np.max(self.logw)
        w = self.weights
        if effective_sample_size(w) < float(self.params["ess_threshold"]) * self.n:
            idx = systematic(w, self.n, self.rng)
            self.poses, self.lm, self.lc = self.poses[idx], self.lm[idx], self.lc[idx]
            self.lid, self.count, self.hits = self.lid[idx], self.count[idx], self.hits[idx]
            self.logw = np.zeros(self.n)
            self.last_targets = [t[idx] for t in self.last_targets]

    def _landmark_updates(self, done: list[tuple[Reading, np.ndarray]]) -> None:
        """Each paired landmark's EKF update from the sampled pose; new landmarks placed;
        tentative unlabelled landmarks that were in view and not seen dropped."""
        A = self.n_anchor
        cap = A + int(self.params["max_landmarks"])
        touched = np.zeros(self.lid.shape, dtype=bool)
        any_unknown = False
        for rd, tgt in done:
            if not unknown(rd):  # known IDs: look the slot up again (it may be new)
                match = self.lid == rd.beacon_id
                tgt = np.where(tgt == GATED, GATED, np.where(match.any(axis=1), match.argmax(axis=1), NEW))
            else:
                any_unknown = True
            k = np.flatnonzero(tgt >= A)
            if k.size:
                c = tgt[k]
                zhat, _, Hm = observe(rd.kind, self.poses[k], self.lm[k, c])
                nu = innovation(rd.z[None, :], zhat)
                C = self.lc[k, c]
                CHt = C @ Hm.transpose(0, 2, 1)
                S = Hm @ CHt + rd.R
                K = CHt @ inv_det(S)[0]
                self.lm[k, c] += np.einsum("kij,kj->ki", K, nu)
                C = C - K @ CHt.transpose(0, 2, 1)
                self.lc[k, c] = 0.5 * (C + C.transpose(0, 2, 1))
                self.hits[k, c] += 1
                touched[k, c] = True
            used = (self.lid[:, A:] > EMPTY).sum(axis=1)
            k = np.flatnonzero((tgt == NEW) & (used < cap - A))
            if k.size and rd.kind == "range_bearing":
                if not np.all((self.lid[k] == EMPTY).any(axis=1)):
                    self._grow(self.lid.shape[1] + 1)
                    touched = np.pad(touched, ((0, 0), (0, self.lid.shape[1] - touched.shape[1])))
                c = np.argmax(self.lid[k] == EMPTY, axis=1)  # the first free slot
                m, _, Gz = place(self.poses[k], rd.z)
                self.lm[k, c] = m
                self.lc[k, c] = Gz @ rd.R @ Gz.transpose(0, 2, 1)
                self.lid[k, c] = rd.beacon_id
                self.hits[k, c] = 1
                self.count[k] = np.maximum(self.count[k], c + 1)
                touched[k, c] = True
        if any_unknown:
            self._drop_tentative(touched, {rd.sensor for rd, _ in done if unknown(rd)})

    def _drop_tentative(self, touched: np.ndarray, sensors: set[str]) -> None:
        """Free the slots of unlabelled landmarks given fewer than ``confirm_hits`` readings
        that were in view of a sensor that fired and got none this tick (clutter)."""
        cmax = int(self.count.max())
        lid, hits = self.lid[:, :cmax], self.hits[:, :cmax]
        cand = (lid == UNKNOWN_ID) & (hits < int(self.params["confirm_hits"])) & ~touched[:, :cmax]
        if not cand.any():
            return
        k, c = np.nonzero(cand)
        zhat = observe("range_bearing", self.poses[k], self.lm[k, c])[0]
        view = np.zeros(k.size, dtype=bool)
        for name in sensors:
            spec = self.ctx.sensor(name)
            view |= (zhat[:, 0] <= spec.max_range) & (
                (spec.fov >= 2 * math.pi) | (np.abs(zhat[:, 1]) <= spec.fov / 2))
        self.lid[k[view], c[view]] = EMPTY
        self.hits[k[view], c[view]] = 0


__all__ = ["EMPTY", "GATED", "IGNORED", "NEW", "FastSLAM2", "LinearisedCovariance", "inv_det",
           "predictive_distance", "proposal_step", "without_rows"]
