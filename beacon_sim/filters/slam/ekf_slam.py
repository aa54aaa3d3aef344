"""EKF-SLAM: one Gaussian over the pose and every landmark (docs/slam.md).

State ``s = [x, y, theta, m1x, m1y, ..., mMx, mMy]`` [m, m, rad, m, ...], covariance P
(3 + 2M square). Landmarks are added as they are first seen (direct initialisation from a
range-bearing reading); anchors (beacons whose position the filter is given) are used as
the localization EKF uses them and are not in the state.

Prediction (only the pose moves; seed 000 eq. 7, 9)::

    x = f(x, u)
    P_xx = F P_xx F^T + Q,   P_xm = F P_xm          (F = df/dx, Q the process noise)

Update, one reading at a time, relinearised at the current mean; the reading's Jacobian
is non-zero only in the pose and its landmark's columns, ``H = [Hx, 0 ... Hm ... 0]``::

    nu = wrap(z - h(x, m_j))
    S = H P H^T + R,   K = P H^T S^-1
    s = s + K nu,      P = P - K S K^T  (symmetrised)

New landmark from ``z = [r, b]`` (``slam.base.place``: m = g(x, z))::

    P_mm = Gx P_xx Gx^T + Gz R Gz^T,   P_m* = Gx P_x*         (Gx = dg/dx, Gz = dg/dz)

Unknown correspondence (readings with ID -1): each tick's readings are paired with the
landmarks and anchors, each landmark at most once, by JCBB (joint compatibility branch and
bound, Neira and Tardos 2001, over the full state: the stacked innovations of a pairing
against ``H P H^T + R`` with every cross term) or by nearest neighbour on the squared
Mahalanobis distance with the full S (parameter ``association``); a reading paired inside
the gate (``gate_prob``) updates its landmark; one farther than the
``new_landmark_prob`` quantile from everything starts a new landmark; one in between is
dropped (it could be either).

Bearing-only, known IDs (delayed initialisation): the first bearing of a new beacon puts a
copy of the current pose into the state (fully correlated with the pose, so nothing is
lost); a later bearing whose ray crosses the first at more than ``min_parallax`` places the
landmark at the crossing, with its covariance and cross terms from the Jacobians of the
crossing in both poses and both bearings, and the copy is marginalised out. Each reading is
used once. Unlabelled bearings update landmarks already on the map but start none.

Bearing-only, known IDs, ``bearing_init = "inverse_depth"`` (Civera, Davison and Montiel
2008; ``inverse_depth.py``): the first bearing puts the landmark into the state at once as
``(x0, y0, theta, rho)`` (after the Euclidean landmarks), every later bearing updates it, and
it is converted to a Euclidean ``(x, y)`` when its linearity index is below
``linearity_threshold``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import jacobian_state, move
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.association import gate as chi2_gate
from beacon_sim.filters.association import jcbb_search
from beacon_sim.filters.base import FilterContext, FilterError, GaussianBelief, LandmarkMap, broad_gaussian
from beacon_sim.filters.slam import inverse_depth
from beacon_sim.filters.slam.base import Reading, SlamFilterBase, innovation, observe, place, unknown


class EKFSLAM(SlamFilterBase):
    """EKF-SLAM over the pose and the landmarks, known or unknown correspondence.

    Parameters (``ctx.params``)
    ---------------------------
    gate_prob : float, default 0.99
        Unknown correspondence: a reading may update a landmark when its squared
        Mahalanobis distance is below this chi-square quantile.
    gate_chi2 : float, default 0.0
        Known IDs: a reading of a mapped landmark (or an anchor) whose squared Mahalanobis
        distance ``nu^T S^-1 nu`` exceeds this is dropped as an outlier (``rejected`` counts
        them); 0 turns the gate off. ``beacon-sim mrclam`` sets the EKF's 99.9 % gate.
    new_landmark_prob : float, default 0.9999
        Unknown correspondence: a reading farther than this quantile from every landmark
        and anchor starts a new landmark.
    max_landmarks : int, default 500
        Most landmarks in the state (readings of further new ones are dropped).
    association : str, default "jcbb"
        Unknown correspondence: ``"jcbb"`` (joint compatibility branch and bound over the
        full state; nearest neighbour when it passes ``max_nodes``) or ``"nn"``.
    max_nodes : int, default 1000
        Most search nodes JCBB may visit in a tick.
    min_parallax : float, default 0.3
        Bearing-only (known IDs): the angle [rad] between two bearings' rays before a
        landmark is put at their crossing. Smaller starts landmarks sooner but linearises a
        badly conditioned crossing: at 0.1 rad the joint ANEES on the test ring is 10-27
        (inconsistent), at 0.3 about 1.
    confirm_hits : int, default 2
        Unknown correspondence: a new landmark is tentative until it has been given this
        many readings; a tentative landmark the sensor should have seen and did not is
        dropped (clutter). ``landmarks()`` reports only the confirmed ones.
    bearing_init : str, default "delayed"
        Bearing-only, known IDs: ``"delayed"`` (a pose copy, then triangulation past
        ``min_parallax``) or ``"inverse_depth"`` (Civera, Davison and Montiel 2008: the
        landmark enters the state at its first bearing as ``(x0, y0, theta, rho)``, every
        later bearing updates it, and it becomes a Euclidean ``(x, y)`` once its linearity
        index falls below ``linearity_threshold``; ``inverse_depth.py``).
    inverse_depth_rho, inverse_depth_std : float, defaults 0.25, 0.25 [1/m]
        The inverse depth's prior mean and standard deviation: the 95 % region
        [-0.25, 0.75] 1/m holds infinity (rho = 0) and every depth beyond 1.33 m.
    linearity_threshold : float, default 0.1
        Convert an inverse-depth landmark to Euclidean when its linearity index is below this.
    """

    defaults: ClassVar[dict] = {"gate_prob": 0.99, "new_landmark_prob": 0.9999, "max_landmarks": 500,
                                "confirm_hits": 2, "association": "jcbb", "max_nodes": 1000,
                                "min_parallax": 0.3, "bearing_init": "delayed", "inverse_depth_rho": 0.25,
                                "inverse_depth_std": 0.25, "linearity_threshold": 0.1, "gate_chi2": 0.0}

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.mu = np.zeros(3)
        self.P = np.eye(3)
        self.ids: list[int] = []           # beacon ID of each landmark (-1: made up, unlabelled)
        self.hits: list[int] = []          # readings each landmark was given
        self.index: dict[int, int] = {}    # beacon ID -> landmark number
        self.last_pairs: list[tuple[int, int | None]] = []  # (reading row, landmark or None)
        self.last_method = ""  # unknown correspondence: "jcbb", "nn" or "nn-fallback" last tick
        self.last_nodes = 0
        self.last_chosen: dict[int, int] = {}  # unlabelled reading -> landmark (or M + anchor)
        self.rejected = 0  # readings with IDs dropped by the gate (gate_chi2) so far
        if self.params["association"] not in ("jcbb", "nn"):
            raise FilterError(f"{type(self).__name__}: parameter association = "
                              f"{self.params['association']!r}: expected 'jcbb' or 'nn'")
        if self.params["bearing_init"] not in ("delayed", "inverse_depth"):
            raise FilterError(f"{type(self).__name__}: parameter bearing_init = "
                              f"{self.params['bearing_init']!r}: expected 'delayed' or 'inverse_depth'")
        if not float(self.params["inverse_depth_std"]) > 0.0:
            raise FilterError(f"{type(self).__name__}: parameter inverse_depth_std = "
                              f"{self.params['inverse_depth_std']!r}: expected a number > 0")
        self.reset(None)

    # -- belief ----------------------------------------------------------------------------
    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mu = np.array(initial.mean, dtype=float).reshape(3)
        self.mu[2] = wrap(self.mu[2])
        c = np.asarray(initial.cov, dtype=float).reshape(3, 3)
        self.P = 0.5 * (c + c.T)
        self.ids, self.index, self.last_pairs = [], {}, []
        self.hits = []
        self.copies: list[tuple[int, float]] = []  # (beacon ID, first bearing) per pose copy
        self.idp: list[int] = []  # beacon ID of each inverse-depth landmark (4 wide, after _end)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mu[:3].copy(), self.P[:3, :3].copy()

    @property
    def _end(self) -> int:
        """One past the last landmark's state index (bearing-only initialisation's pose
        copies, 3 wide, or inverse-depth landmarks, 4 wide, follow)."""
        return 3 + 2 * len(self.ids)

    def joint(self) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
        """The pose and the map: mean (3 + 2M,), covariance, and each landmark's beacon ID
        (the pose copies waiting for a bearing's second look are marginalised out)."""
        e = self._end
        return self.mu[:e].copy(), self.P[:e, :e].copy(), tuple(self.ids)

    def landmarks(self) -> LandmarkMap:
        """The landmarks in the state (unknown correspondence: the confirmed ones)."""
        confirm = int(self.params["confirm_hits"])
        rows = [j for j, (b, h) in enumerate(zip(self.ids, self.hits, strict=True)) if b >= 0 or h >= confirm]
        means = self.mu[3:self._end].reshape(-1, 2)[rows].copy()
        covs = np.empty((len(rows), 2, 2))
        for k, j in enumerate(rows):
            s = 3 + 2 * j
            covs[k] = self.P[s:s + 2, s:s + 2]
        ids = None if any(i < 0 for i in self.ids) else np.array(self.ids, dtype=int)
        return LandmarkMap(ids, means, covs)

    # -- prediction ------------------------------------------------------------------------
    def predict(self, control: Control, dt: float) -> None:
        v, w = float(control.v), float(control.omega)
        pose = self.mu[:3]
        F = jacobian_state(pose, v, dt)
        Q = self.ctx.motion_noise.process_cov(pose, v, w, dt)
        self.mu[:3] = move(pose, v, w, dt)
        P = self.P
        P[:3, :] = F @ P[:3, :]   # rows of the pose: F [P_xx P_xm]
        P[:, :3] = P[:, :3] @ F.T  # then columns: P_xx -> F P_xx F^T, P_mx -> P_mx F^T
        P[:3, :3] += Q

    # -- update ----------------------------------------------------------------------------
    def _model(self, rd: Reading, j: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Innovation, Hx, Hm and the landmark's first state index (0 for an anchor)."""
        lm = np.array(rd.anchor) if j is None else self.mu[3 + 2 * j:5 + 2 * j]
        zhat, Hx, Hm = observe(rd.kind, self.mu[:3], lm)
        return innovation(rd.z, zhat[0]), Hx[0], Hm[0], (0 if j is None else 3 + 2 * j)

    def _gain(self, Hx: np.ndarray, Hm: np.ndarray, s: int, R: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        """``P H^T`` (n, d) and ``S`` (d, d) for a reading with Jacobians Hx, Hm at column s."""
        P = self.P
        PHt = P[:, :3] @ Hx.T
        if s:
            PHt += P[:, s:s + 2] @ Hm.T
        S = Hx @ PHt[:3] + (Hm @ PHt[s:s + 2] if s else 0.0) + R
        return PHt, S

    def _correct(self, rd: Reading, j: int | None) -> bool:
        """The EKF update with one reading of landmark ``j`` (None: an anchor); False when the
        known-ID gate (``gate_chi2``) drops it as an outlier."""
        nu, Hx, Hm, s = self._model(rd, j)
        PHt, S = self._gain(Hx, Hm, s, rd.R)
        gate = float(self.params["gate_chi2"])
        if gate > 0.0 and float(nu @ np.linalg.solve(S, nu)) > gate:
            self.rejected += 1
            return False
        K = np.linalg.solve(S, PHt.T).T          # K = P H^T S^-1 (S symmetric)
        self.mu += K @ nu
        self.mu[2] = wrap(self.mu[2])
        self.P -= K @ PHt.T                      # P - K S K^T
        self.P = 0.5 * (self.P + self.P.T)
        return True

    def _add(self, rd: Reading, beacon_id: int) -> int | None:
        if rd.kind != "range_bearing" or len(self.ids) >= int(self.params["max_landmarks"]):
            return None
        lm, Gx, Gz = place(self.mu[:3], rd.z)
        Gx, Gz = Gx[0], Gz[0]
        P = self.P
        Pmx = Gx @ P[:3, :]                       # (2, n): cross terms with everything
        Pmm = Gx @ P[:3, :3] @ Gx.T + Gz @ rd.R @ Gz.T
        return self._insert(lm[0], Pmx, Pmm, beacon_id)

    def _insert(self, m: np.ndarray, Pmx: np.ndarray, Pmm: np.ndarray, beacon_id: int) -> int:
        """Put a landmark (mean m (2,), cross-covariance with the state Pmx (2, n), covariance
        Pmm) after the last one, before the pose copies."""
        P = self.P
        n, e = P.shape[0], self._end
        old = np.r_[0:e, e + 2:n + 2]               # where the old state goes
        big = np.empty((n + 2, n + 2))
        big[np.ix_(old, old)] = P
        big[e:e + 2, old] = Pmx
        big[old, e:e + 2] = Pmx.T
        big[e:e + 2, e:e + 2] = 0.5 * (Pmm + Pmm.T)
        self.P = big
        mu = np.empty(n + 2)
        mu[old] = self.mu
        mu[e:e + 2] = m
        self.mu = mu
        self.ids.append(beacon_id)
        self.hits.append(1)
        if beacon_id >= 0:
            self.index[beacon_id] = len(self.ids) - 1
        return len(self.ids) - 1

    def _distances(self, rd: Reading) -> np.ndarray:
        """Squared Mahalanobis distance of an unlabelled reading to every landmark, then
        every anchor (M + A,), with the full ``S = H P H^T + R`` of each pairing."""
        M, P = len(self.ids), self.P
        anchors = np.array(list(self.anchors.values()), dtype=float).reshape(-1, 2)
        lm = np.concatenate([self.mu[3:self._end].reshape(M, 2), anchors])
        n = lm.shape[0]
        pose = np.broadcast_to(self.mu[:3], (n, 3))
        zhat, Hx, Hm = observe(rd.kind, pose, lm)
        nu = innovation(rd.z[None, :], zhat)
        Pxm = np.zeros((n, 3, 2))
        Pmm = np.zeros((n, 2, 2))
        if M:
            Pxm[:M] = P[:3, 3:self._end].reshape(3, M, 2).transpose(1, 0, 2)
            idx = 3 + 2 * np.arange(M)
            Pmm[:M, 0, 0], Pmm[:M, 0, 1] = P[idx, idx], P[idx, idx + 1]
            Pmm[:M, 1, 0], Pmm[:M, 1, 1] = P[idx + 1, idx], P[idx + 1, idx + 1]
        HmT, HxT = Hm.transpose(0, 2, 1), Hx.transpose(0, 2, 1)
        cross = Hx @ Pxm @ HmT
        S = Hx @ P[:3, :3] @ HxT + cross + cross.transpose(0, 2, 1) + Hm @ Pmm @ HmT + rd.R
        with np.errstate(invalid="ignore", divide="ignore"):
            d2 = np.einsum("ni,ni->n", nu, np.linalg.solve(S, nu[..., None])[..., 0])
        return np.where(np.isfinite(d2), d2, np.inf)

    # -- bearing-only: delayed initialisation ----------------------------------------------
    def _copy_pose(self, beacon_id: int, b: float) -> None:
        """Keep a copy of the current pose in the state (fully correlated with it) and the
        bearing b [rad] it saw the beacon at, until a second bearing gives enough parallax."""
        P = self.P
        n = P.shape[0]
        big = np.empty((n + 3, n + 3))
        big[:n, :n] = P
        big[n:, :n] = P[:3, :]
        big[:n, n:] = P[:, :3]
        big[n:, n:] = P[:3, :3]
        self.P = big
        self.mu = np.concatenate([self.mu, self.mu[:3]])
        self.copies.append((beacon_id, b))

    def _drop_copy(self, k: int) -> None:
        c = self._end + 3 * k
        keep = np.r_[0:c, c + 3:self.mu.size]
        self.mu = self.mu[keep]
        self.P = self.P[np.ix_(keep, keep)]
        del self.copies[k]

    def _bearing_only(self, rd: Reading) -> None:
        """A bearing of a beacon not yet on the map (known IDs): the first is kept with a
        copy of the pose; a later one whose ray crosses the first at more than
        ``min_parallax`` puts the landmark at the crossing (``triangulate``), with its
        covariance from the Jacobians in both poses and both bearings; the copy goes."""
        k = next((i for i, (bid, _) in enumerate(self.copies) if bid == rd.beacon_id), None)
        if k is None:
            if len(self.ids) < int(self.params["max_landmarks"]):
                self._copy_pose(rd.beacon_id, float(rd.z[0]))
            return
        b1 = self.copies[k][1]
        c = self._end + 3 * k
        v = np.concatenate([self.mu[c:c + 3], self.mu[:3], [b1, float(rd.z[0])]])
        if abs(wrap(v[5] + v[7] - v[2] - v[6])) < float(self.params["min_parallax"]):
            return  # not enough parallax yet: wait (this reading is not used)
        m = triangulate(v)
        if m is None:  # the rays part: start again from this reading
            self._drop_copy(k)
            self._copy_pose(rd.beacon_id, float(rd.z[0]))
            return
        G = triangulation_jacobian(v)             # (2, 8): d m / d(copy, pose, b1, b2)
        Gv, Gz = G[:, :6], G[:, 6:]
        idx = np.r_[c:c + 3, 0:3]
        Pmx = Gv @ self.P[idx, :]
        Pmm = Gv @ self.P[np.ix_(idx, idx)] @ Gv.T + Gz @ (rd.R[0, 0] * np.eye(2)) @ Gz.T
        self._insert(m, Pmx, Pmm, rd.beacon_id)
        self._drop_copy(k)

    # -- bearing-only: inverse-depth initialisation ----------------------------------------
    def _inverse_depth(self, rd: Reading) -> None:
        """A bearing of a beacon not on the Euclidean map (known IDs, ``bearing_init =
        "inverse_depth"``): the first one puts the landmark into the state as ``(x0, y0,
        theta, rho)`` (``inverse_depth.initialise``, the prior ``rho ~ N(inverse_depth_rho,
        inverse_depth_std^2)``; its cross terms from the pose); later ones update it with the
        inverse-depth model (``inverse_depth.observe``), and once its linearity index is below
        ``linearity_threshold`` it is converted to a Euclidean landmark."""
        if rd.beacon_id not in self.idp:
            if len(self.ids) + len(self.idp) >= int(self.params["max_landmarks"]):
                return
            y, Gx, Gz = inverse_depth.initialise(self.mu[:3], float(rd.z[0]),
                                                 float(self.params["inverse_depth_rho"]))
            P = self.P
            n = P.shape[0]
            big = np.zeros((n + 4, n + 4))
            big[:n, :n] = P
            big[n:, :n] = Gx @ P[:3, :]
            big[:n, n:] = big[n:, :n].T
            Pyy = Gx @ P[:3, :3] @ Gx.T + rd.R[0, 0] * np.outer(Gz, Gz)
            Pyy[3, 3] += float(self.params["inverse_depth_std"]) ** 2
            big[n:, n:] = 0.5 * (Pyy + Pyy.T)
            self.P = big
            self.mu = np.concatenate([self.mu, y])
            self.idp.append(rd.beacon_id)
            return
        k = self.idp.index(rd.beacon_id)
        c = self._end + 3 * len(self.copies) + 4 * k
        zhat, Hx, Hy = inverse_depth.observe(self.mu[:3], self.mu[c:c + 4])
        nu = np.array([wrap(float(rd.z[0]) - zhat)])
        PHt = self.P[:, :3] @ Hx[:, None] + self.P[:, c:c + 4] @ Hy[:, None]   # (n, 1)
        S = float(Hx @ PHt[:3, 0] + Hy @ PHt[c:c + 4, 0]) + rd.R[0, 0]
        K = PHt / S
        self.mu += (K @ nu)
        self.mu[2] = wrap(self.mu[2])
        self.mu[c + 2] = wrap(self.mu[c + 2])
        self.P -= K @ PHt.T
        self.P = 0.5 * (self.P + self.P.T)
        L = inverse_depth.linearity_index(self.mu[c:c + 4], float(self.P[c + 3, c + 3]), self.mu[:2])
        if L < float(self.params["linearity_threshold"]):
            self._to_euclidean(k)

    def _to_euclidean(self, k: int) -> None:
        """Convert inverse-depth landmark k to a Euclidean one: ``m = (x0, y0) + (cos theta,
        sin theta) / rho`` with ``P' = J P J^T`` over its block (``inverse_depth.to_xy``)."""
        c = self._end + 3 * len(self.copies) + 4 * k
        m, J = inverse_depth.to_xy(self.mu[c:c + 4])
        bid = self.idp[k]
        keep = np.r_[0:c, c + 4:self.mu.size]
        Pmx = J @ self.P[c:c + 4, :][:, keep]
        Pmm = J @ self.P[c:c + 4, c:c + 4] @ J.T
        self.mu = self.mu[keep]
        self.P = self.P[np.ix_(keep, keep)]
        del self.idp[k]
        self._insert(m, Pmx, Pmm, bid)

    def _remove(self, j: int) -> None:
        """Marginalise landmark j out of the state (drop its rows and columns)."""
        keep = np.r_[0:3 + 2 * j, 5 + 2 * j:self.mu.size]
        self.mu = self.mu[keep]
        self.P = self.P[np.ix_(keep, keep)]
        del self.ids[j], self.hits[j]
        self.index = {b: i for i, b in enumerate(self.ids) if b >= 0}

    def _in_view(self, j: int, sensors: set[str]) -> bool:
        """Whether landmark j is where one of these sensors should have seen it."""
        zhat = observe("range_bearing", self.mu[:3], self.mu[3 + 2 * j:5 + 2 * j])[0][0]
        for name in sensors:
            spec = self.ctx.sensor(name)
            if zhat[0] <= spec.max_range and (spec.fov >= 2 * np.pi or abs(zhat[1]) <= spec.fov / 2):
                return True
        return False

    def update(self, measurements: Sequence[Measurement]) -> None:
        pending: list[Reading] = []
        pairs: list[tuple[int, int | None]] = []
        for row, rd in enumerate(self.readings(measurements)):
            if unknown(rd):
                pending.append(rd)
                continue
            if rd.anchor is not None:
                self._correct(rd, None)
                pairs.append((row, None))
                continue
            j = self.index.get(rd.beacon_id)
            if j is None and rd.beacon_id in self.idp:
                if rd.kind == "bearing":
                    self._inverse_depth(rd)
                    pairs.append((row, self.index.get(rd.beacon_id)))
                    continue
                self._to_euclidean(self.idp.index(rd.beacon_id))  # a range: make it Euclidean
                j = self.index[rd.beacon_id]
            if j is None and rd.kind == "bearing":
                if self.params["bearing_init"] == "inverse_depth":
                    self._inverse_depth(rd)
                else:
                    self._bearing_only(rd)
                pairs.append((row, self.index.get(rd.beacon_id)))
            elif j is None:
                k = next((i for i, (bid, _) in enumerate(self.copies) if bid == rd.beacon_id), None)
                if k is not None:
                    self._drop_copy(k)  # a range-bearing reading places it at once
                pairs.append((row, self._add(rd, rd.beacon_id)))
            else:
                pairs.append((row, j if self._correct(rd, j) else None))
        if pending:
            seen = self._associate(pending)
            # A landmark made from one unlabelled reading is tentative until it is seen again
            # (``confirm_hits``); missed while in view, it was clutter and is dropped.
            fired = {m.sensor for m in measurements if m.kind in ("bearing", "range_bearing")}
            for j in range(len(self.ids) - 1, -1, -1):
                if self.ids[j] < 0 and self.hits[j] < int(self.params["confirm_hits"]) \
                        and j not in seen and self._in_view(j, fired):
                    self._remove(j)
        self.last_pairs = pairs

    def _pair_model(self, rd: Reading, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Innovation (d,) and the full-state Jacobian (d, n) of reading rd paired with
        candidate j (landmarks first, then anchors)."""
        M = len(self.ids)
        if j < M:
            nu, Hx, Hm, s = self._model(rd, j)
        else:
            nu, Hx, Hm, s = self._model(Reading(rd.kind, rd.z, rd.R, -1, list(self.anchors.values())[j - M]),
                                        None)
        H = np.zeros((nu.size, self.mu.size))
        H[:, :3] = Hx
        if s:
            H[:, s:s + 2] = Hm
        return nu, H

    def joint_nis(self, pending: list[Reading], pairs: Sequence[tuple[int, int]]) -> float:
        """Joint NIS of a pairing [(reading i, candidate j), ...]: the stacked innovations
        against ``S = H P H^T + R`` over the stack, with the cross terms that the shared pose
        and landmark errors put between the readings (Neira and Tardos 2001)."""
        if not pairs:
            return 0.0
        models = [self._pair_model(pending[i], j) for i, j in pairs]
        nu = np.concatenate([m[0] for m in models])
        H = np.vstack([m[1] for m in models])
        R = np.zeros((nu.size, nu.size))
        k = 0
        for i, _ in pairs:
            d = pending[i].z.size
            R[k:k + d, k:k + d] = pending[i].R
            k += d
        S = H @ self.P @ H.T + R
        try:
            return float(nu @ np.linalg.solve(S, nu))
        except np.linalg.LinAlgError:
            return float("inf")

    def _jcbb(self, pending: list[Reading], d2: np.ndarray) -> dict[int, int] | None:
        """Joint compatibility branch and bound over the full SLAM state
        (``association.jcbb_search``, the package's one JCBB, with :class:`FullStateJoint`):
        the most readings paired, among those the lowest joint NIS, each pairing jointly
        inside the ``gate_prob`` quantile for its degrees of freedom. None when the search
        passes ``max_nodes`` (the caller falls back to nearest neighbour)."""
        pairing, _, nodes = jcbb_search(d2, [rd.z.size for rd in pending], FullStateJoint(self, pending),
                                        float(self.params["gate_prob"]), int(self.params["max_nodes"]))
        if pairing is None:
            return None
        self.last_nodes = nodes
        return dict(pairing)

    def _associate(self, pending: list[Reading]) -> set[int]:
        """Pair the tick's unlabelled readings with landmarks and anchors (JCBB or nearest
        neighbour, parameter ``association``), update, start new landmarks (see the module
        docstring)."""
        M = len(self.ids)
        anchors = list(self.anchors.values())
        d2 = np.array([self._distances(rd) for rd in pending]).reshape(len(pending), M + len(anchors))
        dof = [rd.z.size for rd in pending]
        gate = np.array([chi2_gate(float(self.params["gate_prob"]), k) for k in dof])
        new = np.array([chi2_gate(float(self.params["new_landmark_prob"]), k) for k in dof])
        chosen = nn_pairs(d2, gate)
        self.last_method = "nn"
        if self.params["association"] == "jcbb" and d2.size:
            found = self._jcbb(pending, d2)
            if found is not None:
                chosen = found
                self.last_method = "jcbb"
            else:
                self.last_method = "nn-fallback"
        self.last_chosen = chosen
        seen = set()
        for i, rd in enumerate(pending):
            if i in chosen:
                j = chosen[i]
                if j < M:
                    self._correct(rd, j)
                    self.hits[j] += 1
                    seen.add(j)
                else:
                    self._correct(Reading(rd.kind, rd.z, rd.R, -1, anchors[j - M]), None)
            elif d2.shape[1] == 0 or float(np.min(d2[i])) > new[i]:
                j_new = self._add(rd, -1)
                if j_new is not None:
                    seen.add(j_new)
        return seen


class FullStateJoint:
    """EKF-SLAM's joint test for ``association.jcbb_search``: a state is the pairing so far,
    and growing it evaluates :meth:`EKFSLAM.joint_nis` of each grown pairing (the stacked
    innovations against ``H P H^T + R`` over the whole state: pose and landmark cross terms)."""

    def __init__(self, flt: EKFSLAM, pending: list[Reading]):
        self.flt, self.pending = flt, pending

    def start(self) -> tuple[tuple[int, int], ...]:
        return ()

    def grow(self, state: tuple[tuple[int, int], ...], i: int, cols: list[int]
             ) -> tuple[list[tuple[tuple[int, int], ...]], np.ndarray]:
        grown = [(*state, (i, j)) for j in cols]
        return grown, np.array([self.flt.joint_nis(self.pending, g) for g in grown])


def nn_pairs(d2: np.ndarray, gate: np.ndarray) -> dict[int, int]:
    """Greedy nearest neighbour: the closest (reading, candidate) pair inside its reading's
    gate first, then the closest of the rest with both free, and so on."""
    chosen: dict[int, int] = {}
    taken: set[int] = set()
    if d2.size:
        for flat in np.argsort(d2, axis=None, kind="stable"):
            i, j = divmod(int(flat), d2.shape[1])
            if d2[i, j] > gate[i] or i in chosen or j in taken:
                continue
            chosen[i] = j
            taken.add(j)
    return chosen


def triangulate(v: np.ndarray) -> np.ndarray | None:
    """Where two bearing rays cross: ``v = [x1, y1, th1, x2, y2, th2, b1, b2]`` (two poses and
    the bearing each saw the landmark at) -> the point (2,) [m], or None when the rays do not
    cross ahead of both poses."""
    p1, p2 = v[0:2], v[3:5]
    u1 = np.array([np.cos(v[2] + v[6]), np.sin(v[2] + v[6])])
    u2 = np.array([np.cos(v[5] + v[7]), np.sin(v[5] + v[7])])
    den = u1[0] * u2[1] - u1[1] * u2[0]          # cross(u1, u2)
    if abs(den) < 1e-12:
        return None
    d = p2 - p1
    t1 = (d[0] * u2[1] - d[1] * u2[0]) / den
    t2 = (d[0] * u1[1] - d[1] * u1[0]) / den
    if t1 <= 0.0 or t2 <= 0.0:
        return None
    return p1 + t1 * u1


def triangulation_jacobian(v: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """d triangulate / d v, shape (2, 8), by central differences (once per new landmark)."""
    G = np.empty((2, 8))
    for i in range(8):
        dv = np.zeros(8)
        dv[i] = eps
        a, b = triangulate(v + dv), triangulate(v - dv)
        if a is None or b is None:
            raise FilterError("bearing-only initialisation: rays too close to parallel")
        G[:, i] = (a - b) / (2 * eps)
    return G


__all__ = ["EKFSLAM", "FullStateJoint", "nn_pairs", "triangulate", "triangulation_jacobian"]
