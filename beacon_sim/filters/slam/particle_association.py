"""FastSLAM 2.0's data association, per particle (``slam/fastslam.py``): which landmark of its
own map each particle pairs each reading with, or what else it does with it.

- Readings with IDs: the slot of the beacon's landmark (:meth:`ParticleAssociation._known_targets`),
  and the known-ID outlier gate (``gate_chi2``: a reading no particle can explain is dropped
  for all, :meth:`ParticleAssociation._gate`).
- Readings without IDs: each particle's most likely landmark against its motion-only
  proposal, all the tick's readings of a sensor at once (lowest ``d2 + log det L``), or with
  ``association = "jcbb"`` the jointly compatible pairing (JCBB, ``association.jcbb_search``),
  with a shortcut for the particles whose readings are unambiguous
  (:meth:`ParticleAssociation._unambiguous`). Within the ``gate_prob`` gate the reading is
  used; beyond the ``new_landmark_prob`` quantile it starts a landmark (NEW); in between it
  only weighs the particle (IGNORED).

:class:`ParticleAssociation` is a mixin of :class:`~beacon_sim.filters.slam.fastslam.FastSLAM2`:
the maps it reads (``lm``, ``lc``, ``lid``, ``count``) are the filter's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.filters.association import JointInformation, information_sums, jcbb_search
from beacon_sim.filters.association import gate as chi2_gate
from beacon_sim.filters.slam.base import Reading, innovation, observe
from beacon_sim.filters.slam.fastslam_proposal import inv_det, predictive_distance

#: Target of a reading for one particle: a slot index (>= 0), or one of these.
NEW = -1      # start a landmark
IGNORED = -2  # between the gate and the new-landmark distance: weight only
GATED = -3    # a reading with an ID this particle rejects as an outlier (``gate_chi2``)
#: ``lid`` of an empty landmark slot.
EMPTY = UNKNOWN_ID - 1


class ParticleAssociation:
    """Per-particle data association, as methods of FastSLAM 2.0 (a mixin: the attributes
    below are the filter's)."""

    params: dict[str, Any]
    n: int
    lm: np.ndarray[tuple[int, int, int], np.dtype[np.float64]]             # (N, C, 2)
    lc: np.ndarray[tuple[int, int, int, int], np.dtype[np.float64]]        # (N, C, 2, 2)
    lid: np.ndarray[tuple[int, int], np.dtype[np.int64]]                   # (N, C)
    count: np.ndarray[tuple[int], np.dtype[np.int64]]                      # (N,)
    last_jcbb: dict[str, int]

    def _known_targets(self, rd: Reading) -> np.ndarray:
        """The slot of the reading's beacon in each particle's map (or NEW)."""
        match = self.lid == rd.beacon_id
        return np.where(match.any(axis=1), match.argmax(axis=1), NEW)


    def _unknown_targets(self, rows: list[Reading], mu: np.ndarray, Sig: np.ndarray
                         ) -> list[np.ndarray]:
        """Per-particle maximum-likelihood association of unlabelled readings of one sensor
        (one kind and R): the slot each particle gives each reading (or NEW / IGNORED).

        All the tick's readings are associated against the proposal before any of them is
        folded in: the expected reading, the Jacobians and L of every (particle, landmark)
        pair do not depend on the reading, so they are computed once (N x C) and each reading
        costs only its innovations."""
        n, m = self.n, len(rows)
        cmax = int(self.count.max())
        if cmax == 0:
            return [np.full(n, NEW) for _ in rows]
        kind, R = rows[0].kind, rows[0].R
        lm = self.lm[:, :cmax]
        zhat, Hx, Hm = observe(kind, np.repeat(mu, cmax, axis=0), lm.reshape(-1, 2))
        d = zhat.shape[1]
        Hx = Hx.reshape(n, cmax, d, 3)
        Hm = Hm.reshape(n, cmax, d, 2)
        Z = Hm @ self.lc[:, :cmax] @ Hm.swapaxes(-1, -2) + R       # (n, C, d, d)
        L = Hx @ Sig[:, None] @ Hx.swapaxes(-1, -2) + Z
        z = np.stack([rd.z for rd in rows])                        # (m, d)
        nu = innovation(z[None, :, None, :], zhat.reshape(n, 1, cmax, d))  # (n, m, C, d)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            Linv, det = inv_det(L)
            d2 = np.einsum("nmci,ncij,nmcj->nmc", nu, Linv, nu)
            score = d2 + np.log(det)[:, None, :]
        valid = (self.lid[:, :cmax] > EMPTY)[:, None, :]
        score = np.where(valid & np.isfinite(score), score, np.inf)
        best = np.argmin(score, axis=2)                            # (n, m)
        d2b = np.take_along_axis(d2, best[..., None], axis=2)[..., 0]
        okb = np.isfinite(np.take_along_axis(score, best[..., None], axis=2)[..., 0])
        d2b = np.where(okb, d2b, np.inf)
        gate = chi2_gate(float(self.params["gate_prob"]), d)
        new = chi2_gate(float(self.params["new_landmark_prob"]), d)
        tgt = np.where(d2b <= gate, best, np.where(d2b > new, NEW, IGNORED))
        if self.params["association"] == "jcbb":
            d2v = np.where(valid & np.isfinite(d2), d2, np.inf)
            self._jcbb_targets(tgt, nu, Hx, Sig, Z, d2v, d, new)
        return [tgt[:, i] for i in range(m)]

    def _jcbb_targets(self, tgt: np.ndarray, nu: np.ndarray, Hx: np.ndarray, Sig: np.ndarray,
                      Z: np.ndarray, d2: np.ndarray, d: int, new: float) -> None:
        """Per-particle JCBB (``association = "jcbb"``): each particle's pairing of the tick's
        readings with its landmarks by ``association.jcbb_search``, the joint test against the
        particle's proposal ``Sigma`` (shared by the readings) and each landmark's own
        ``Z = Hm C Hm^T + R`` (independent landmarks). Only the gated candidates are searched
        (a particle with none skips the search); each landmark gets at most one reading; a
        reading left out is NEW beyond the new-landmark distance, else IGNORED. A particle
        whose search passes ``max_nodes`` keeps its maximum-likelihood targets. Writes
        ``tgt`` (n, m) in place and counts into ``last_jcbb``."""
        prob = float(self.params["gate_prob"])
        cap = int(self.params["max_nodes"])
        gated = d2 <= chi2_gate(prob, d)                                   # (n, m, C)
        searched = np.flatnonzero(gated.any(axis=(1, 2)))
        stats = {"searched": int(searched.size), "unambiguous": 0, "fallback": 0, "nodes": 0}
        if searched.size:
            a, b, M = information_sums(nu[searched], Hx[searched], Z[searched])
            left = np.where(np.min(d2, axis=2, initial=np.inf) > new, NEW, IGNORED)  # (n, m)
            dims = [d] * tgt.shape[1]
            easy = self._unambiguous(tgt, searched, gated[searched], Sig[searched], a, b, M, d, prob, left)
            stats["unambiguous"] = int(easy.sum())
            for s, k in enumerate(searched.tolist()):
                if easy[s]:
                    continue
                joint = JointInformation(Sig[k], a[s], b[s], M[s])
                pairing, _, nodes = jcbb_search(d2[k], dims, joint, prob, cap)
                stats["nodes"] += nodes
                if pairing is None:
                    stats["fallback"] += 1
                    continue
                row = left[k].copy()
                for i, j in pairing:
                    row[i] = j
                tgt[k] = row
        self.last_jcbb = stats

    @staticmethod
    def _unambiguous(tgt: np.ndarray, rows: np.ndarray, gated: np.ndarray, Sig: np.ndarray,
                     a: np.ndarray, b: np.ndarray, M: np.ndarray, d: int, prob: float,
                     left: np.ndarray) -> np.ndarray:
        """JCBB's answer for the particles where it needs no search, all at once: every
        reading has at most one gated landmark and no two share one. The search would then
        pair the readings in index order, each prefix tested jointly; when every prefix
        passes, pairing them all is its answer (the most pairs; any other leaf has fewer).
        Those particles' targets are written into ``tgt``; returns which of ``rows`` they
        are (the others go to the search)."""
        ncand = gated.sum(axis=2)                                          # (s, m)
        easy = np.all(ncand <= 1, axis=1) & np.all(gated.sum(axis=1) <= 1, axis=1)
        if not easy.any():
            return easy
        e = np.flatnonzero(easy)
        has = ncand[e] == 1                                                 # (e, m)
        j = np.argmax(gated[e], axis=2)                                     # (e, m)
        ii = np.arange(j.shape[1])[None, :]
        a_s = np.where(has, a[e[:, None], ii, j], 0.0)                      # (e, m)
        b_s = np.where(has[..., None], b[e[:, None], ii, j], 0.0)           # (e, m, 3)
        M_s = np.where(has[..., None, None], M[e[:, None], j], 0.0)         # (e, m, 3, 3)
        ca, cb, cM = np.cumsum(a_s, axis=1), np.cumsum(b_s, axis=1), np.cumsum(M_s, axis=1)
        P = Sig[e][:, None]                                                 # (e, 1, 3, 3)
        with np.errstate(invalid="ignore", over="ignore"):
            x = np.linalg.solve(np.eye(3) + P @ cM, (P @ cb[..., None]))[..., 0]
            value = ca - np.einsum("emk,emk->em", cb, x)
        dof = d * np.cumsum(has, axis=1)
        limit = np.array([chi2_gate(prob, int(k)) if k else np.inf for k in range(d * j.shape[1] + 1)])
        ok = np.all(~has | (np.isfinite(value) & (value <= limit[dof])), axis=1)
        easy[e[~ok]] = False
        for q in np.flatnonzero(ok).tolist():
            row = left[rows[e[q]]].copy()
            row[has[q]] = j[q][has[q]]
            tgt[rows[e[q]]] = row
        return easy

    def _gate(self, rd: Reading, tgt: np.ndarray, k: np.ndarray, mu: np.ndarray, Sig: np.ndarray,
              gate: float) -> np.ndarray:
        """The known-ID outlier gate (``gate_chi2``, the class docstring) on one reading: when
        every particle ``k`` that has its landmark rejects it, every particle's target is
        GATED (the reading is dropped, no weight changes); else the targets are returned as
        they are."""
        d2, _ = predictive_distance(rd.kind, rd.z, rd.R, mu[k], Sig[k], self.lm[k, tgt[k]],
                                    self.lc[k, tgt[k]])
        if np.any(d2 <= gate):  # a distance that is not finite is an outlier too
            return tgt
        return np.full_like(tgt, GATED)


__all__ = ["EMPTY", "GATED", "IGNORED", "NEW", "ParticleAssociation"]
