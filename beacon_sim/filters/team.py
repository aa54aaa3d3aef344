"""Filters for a team of robots: the :class:`TeamFilter` protocol beside the
single-robot :class:`~beacon_sim.filters.base.Filter` (which is unchanged), and four team
filters.

- ``independent``: every robot's own single-robot filter (any ``Filter``; the EKF by
  default), fed its beacon readings only. The baseline: it ignores the teammates.
- ``centralised``: one EKF over the joint state ``[x_1, y_1, th_1, ..., x_N, y_N, th_N]``
  (3N) and its 3N x 3N covariance, using the beacon readings and the robot-to-robot
  readings, whose Jacobians (core/team_models.py) couple two robots' blocks (Roumeliotis &
  Bekey, IEEE T-RA 2002, centralised form). With no robot-to-robot reading it is the
  independent EKFs exactly (the blocks stay uncorrelated).
- ``ci``: decentralised. Each robot keeps its own 3-state EKF; an observer i that reads
  range and bearing to a teammate j sends j the position it implies,
  ``p_j = p_i + r [cos(th_i + b), sin(th_i + b)]`` with covariance
  ``J_x P_i J_x^T + J_z R J_z^T``, and j fuses it by covariance intersection (Julier &
  Uhlmann, ACC 1997; for cooperative localization Carrillo-Arce, Nerurkar, Gordillo &
  Roumeliotis, IROS 2013), which stays consistent whatever the unknown correlation between
  the message and j's belief (information that went i -> j -> i is not counted twice)::

      P_new^-1 = w P_j^-1 + (1 - w) H^T P_z^-1 H,        H = [I2 0]
      x_new    = x_j + (1 - w) P_new H^T P_z^-1 (p_j - H x_j)
      w in [0.001, 1] minimising trace(P_new) (golden-section search)

  Bearing-only robot readings do not give a position and are not used by ``ci``.
- ``naive``: the same messages fused by a Kalman update as if independent of j's belief
  (w dropped): it double-counts shared information and is overconfident. Kept as the
  counter-example the tests and docs/multi-robot.md measure.

Poses ``[x, y, theta]`` [m, m, rad], world frame; robot readings have kind
``robot_range_bearing`` or ``robot_bearing`` and name the robots seen in ``beacon_ids``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing_scalar
from beacon_sim.core.scenario import RobotSensorSpec, TeamScenario
from beacon_sim.core.streams import filter_stream
from beacon_sim.core.team_models import ROBOT_MEASUREMENT_DIMS, relative_rows, teammate_position
from beacon_sim.core.types import Control, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import Belief, Filter, FilterContext, FilterError, GaussianBelief
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.gaussian.measurements import process_cov_terms
from beacon_sim.filters.param_ranges import check_value


@dataclass(frozen=True, eq=False)
class TeamMember:
    """What a team filter knows of one robot: its ID, the single-robot context (beacon
    map, told motion and beacon-sensor noise) and its robot sensors with the told noise."""

    id: int
    ctx: FilterContext
    robot_sensors: tuple[RobotSensorSpec, ...] = ()

    def robot_sensor(self, name: str) -> RobotSensorSpec:
        for s in self.robot_sensors:
            if s.name == name:
                return s
        raise FilterError(f"no robot sensor named {name!r} on robot {self.id}")


@dataclass(frozen=True, eq=False)
class TeamContext:
    """Everything a team filter may know (never a true pose): the members in team order."""

    name: str
    world: World
    dt: float
    members: tuple[TeamMember, ...]
    params: Mapping[str, Any] = field(default_factory=dict)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(m.id for m in self.members)


@runtime_checkable
class TeamFilter(Protocol):
    """A filter over a team. ``measurements[i]`` are robot i's readings of the tick (beacon
    readings and robot readings); ``estimates()`` gives each robot's (mean (3,), cov (3, 3))."""

    def reset(self, initial: Sequence[GaussianBelief]) -> None: ...

    def predict(self, controls: Sequence[Control], dt: float) -> None: ...

    def update(self, measurements: Sequence[Sequence[Measurement]]) -> None: ...

    def estimates(self) -> list[tuple[np.ndarray, np.ndarray]]: ...


def is_robot_reading(m: Measurement) -> bool:
    return m.kind in ROBOT_MEASUREMENT_DIMS


def team_context(team: TeamScenario, name: str, params: Mapping[str, Any] | None = None,
                 seed: int | None = None) -> TeamContext:
    """The context of team filter ``name`` for a team scenario: each member gets the model
    noise its robot's scenario tells the filters, and its own random stream."""
    seed = team.seed if seed is None else seed
    members = []
    for r in team.robots:
        sc = r.scenario
        ctx = FilterContext.of_scenario(sc, f"{name}/{r.name}", dict(sc.filter_params.get("ekf", {})),
                                        filter_stream(seed, f"{name}/{r.id}"), world=team.world)
        members.append(TeamMember(r.id, ctx, r.model_robot_sensors))
    return TeamContext(name, team.world, team.dt, tuple(members), dict(params or {}))


def initial_beliefs(team: TeamScenario) -> list[GaussianBelief]:
    """Each robot's initial Gaussian belief from its scenario's ``initial_belief``."""
    out = []
    for r in team.robots:
        ib = r.scenario.initial_belief
        out.append(GaussianBelief(np.array(ib.mean, dtype=float), np.diag(np.square(ib.std))))
    return out


class _TeamBase:
    """Parameters merged with ``defaults`` (unknown names are an error), as FilterBase."""

    defaults: ClassVar[dict[str, Any]] = {}

    def __init__(self, ctx: TeamContext):
        self.ctx = ctx
        self.params = dict(self.defaults)
        for key, value in ctx.params.items():
            if key not in self.defaults:
                known = ", ".join(sorted(self.defaults)) or "none"
                raise FilterError(f"{type(self).__name__}: unknown parameter {key!r}; known: {known}")
            check_value(type(self), key, value, self.defaults[key])  # finite, in its range
            self.params[key] = value
        self.index = {m.id: i for i, m in enumerate(ctx.members)}

    def beliefs(self) -> list[Belief]:
        return [GaussianBelief(m, c) for m, c in self.estimates()]

    def estimates(self) -> list[tuple[np.ndarray, np.ndarray]]:
        raise NotImplementedError


class IndependentTeam(_TeamBase):
    """One single-robot filter per robot, each fed only its own beacon readings (baseline).

    ``member`` builds a robot's filter from its FilterContext (default: the EKF), so any
    single-robot filter, a student's too, becomes a team baseline unchanged.
    """

    def __init__(self, ctx: TeamContext, member: Callable[[FilterContext], Filter] = ExtendedKalmanFilter):
        super().__init__(ctx)
        self.filters = [member(m.ctx) for m in ctx.members]

    def reset(self, initial: Sequence[GaussianBelief]) -> None:
        for f, b in zip(self.filters, initial, strict=True):
            f.reset(b)

    def predict(self, controls: Sequence[Control], dt: float) -> None:
        for f, u in zip(self.filters, controls, strict=True):
            f.predict(u, dt)

    def update(self, measurements: Sequence[Sequence[Measurement]]) -> None:
        for f, ms in zip(self.filters, measurements, strict=True):
            f.update([m for m in ms if not is_robot_reading(m)])

    def estimates(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [f.estimate() for f in self.filters]


#: One scalar row of a joint update: (state indices, H entries, innovation, variance).
JointRow = tuple[tuple[int, ...], tuple[float, ...], float, float]


class CentralisedEKF(_TeamBase):
    """EKF over the joint state of all robots (3N) with robot-to-robot readings.

    Parameters: ``gate_chi2`` (0: off) drops a beacon's or a teammate's reading whose
    squared Mahalanobis distance against the predicted belief exceeds it.

    Predict, robot by robot (F block diagonal)::

        x_i = f(x_i, u_i);  P <- F_i P F_i^T + Q_i   on the rows and columns of block i

    Update: every reading of the tick stacked, linearised once at the predicted joint
    mean, applied as scalar rows (R diagonal) with the innovation corrected by
    ``-H (x - x_pred)``; a robot reading's row has entries in the observer's and the
    subject's blocks (``dh/dx_i``, ``dh/dx_j``). Cost per step O(m (3N)^2) for m rows.
    """

    defaults: ClassVar[dict[str, Any]] = {"gate_chi2": 0.0}

    def __init__(self, ctx: TeamContext):
        super().__init__(ctx)
        n = 3 * len(ctx.members)
        self.x = np.zeros(n)
        self.P = np.eye(n)
        self.gate = float(self.params["gate_chi2"])
        self.rejected = 0
        self._beacons = {b.id: (b.x, b.y) for b in ctx.world.beacons}

    def reset(self, initial: Sequence[GaussianBelief]) -> None:
        n = 3 * len(self.ctx.members)
        if len(initial) != len(self.ctx.members):
            raise FilterError(f"{len(initial)} initial beliefs for {len(self.ctx.members)} robots")
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        for i, b in enumerate(initial):
            c = np.asarray(b.cov, dtype=float)
            self.x[3 * i:3 * i + 3] = b.mean
            self.x[3 * i + 2] = wrap(float(b.mean[2]))
            self.P[3 * i:3 * i + 3, 3 * i:3 * i + 3] = 0.5 * (c + c.T)

    def _move(self, i: int, u: Control, dt: float) -> tuple[float, float, np.ndarray]:
        """Move robot i's mean by its command ``u`` over ``dt`` [s] (the velocity model);
        returns ``(a, b, Q_i)``: the motion Jacobian ``F_i = [[1, 0, a], [0, 1, b], [0, 0, 1]]``
        at the old heading and the process noise (3, 3) of the step."""
        x, k = self.x, 3 * i
        v, w = float(u.v), float(u.omega)
        th = float(x[k + 2])
        c, s = math.cos(th), math.sin(th)
        q00, q01, q02, q11, q12, q22 = process_cov_terms(self.ctx.members[i].ctx.motion_noise,
                                                         th, c, s, v, w, dt)
        x[k] += v * dt * c
        x[k + 1] += v * dt * s
        x[k + 2] = wrap(th + w * dt)
        return -v * dt * s, v * dt * c, np.array([[q00, q01, q02], [q01, q11, q12], [q02, q12, q22]])

    def predict(self, controls: Sequence[Control], dt: float) -> None:
        P = self.P
        if len(controls) != len(self.ctx.members):
            raise FilterError(f"{len(controls)} commands for {len(self.ctx.members)} robots")
        for i, u in enumerate(controls):
            k = 3 * i
            a, b, Q = self._move(i, u, dt)
            P[k, :] += a * P[k + 2, :]
            P[k + 1, :] += b * P[k + 2, :]
            P[:, k] += a * P[:, k + 2]
            P[:, k + 1] += b * P[:, k + 2]
            P[k:k + 3, k:k + 3] += Q

    # -- update ----------------------------------------------------------------------------
    def rows(self, measurements: Sequence[Sequence[Measurement]]) -> list[list[JointRow]]:
        """The stacked model at the current joint mean, grouped per beacon or teammate seen."""
        x = self.x
        groups: list[list[JointRow]] = []
        for i, (member, ms) in enumerate(zip(self.ctx.members, measurements, strict=True)):
            k = 3 * i
            xi, yi, ti = float(x[k]), float(x[k + 1]), float(x[k + 2])
            idx_i = (k, k + 1, k + 2)
            for m in ms:
                if m.kind in ("bearing", "range_bearing"):
                    std = member.ctx.sensor(m.sensor).reading_std()
                    for zrow, bid in zip(m.z.tolist(), m.beacon_ids.tolist(), strict=True):
                        if bid not in self._beacons:
                            raise FilterError(f"no beacon with ID {bid} in the map")
                        bx, by = self._beacons[bid]
                        dx, dy = bx - xi, by - yi
                        q = dx * dx + dy * dy
                        hb = wrap(relative_bearing_scalar(dx, dy, ti))
                        brow = (idx_i, (dy / q, -dx / q, -1.0), wrap(zrow[-1] - hb), float(std[-1]) ** 2)
                        if m.kind == "bearing":
                            groups.append([brow])
                        else:
                            r = math.sqrt(q)
                            groups.append([(idx_i, (-dx / r, -dy / r, 0.0), zrow[0] - r, float(std[0]) ** 2),
                                           brow])
                elif m.kind in ROBOT_MEASUREMENT_DIMS:
                    rstd = member.robot_sensor(m.sensor).reading_std()
                    for zrow, rid in zip(m.z.tolist(), m.beacon_ids.tolist(), strict=True):
                        j = self.index.get(rid)
                        if j is None or j == i:
                            continue
                        kj = 3 * j
                        h, hi, hj = relative_rows(m.kind, x[k:k + 3], x[kj:kj + 3])
                        idx: tuple[int, ...] = (*idx_i, kj, kj + 1, kj + 2)
                        g: list[JointRow] = []
                        for row in range(len(h)):
                            nu = zrow[row] - h[row]
                            if m.kind == "robot_bearing" or row == 1:
                                nu = wrap(nu)
                            g.append((idx, (*hi[row].tolist(), *hj[row].tolist()), float(nu),
                                      float(rstd[row]) ** 2))
                        groups.append(g)
                # pose and position fixes: not used by the team filters (no such sensor here)
        return groups

    def _block_of(self, g: list[JointRow]) -> tuple[np.ndarray, dict[int, int]]:
        """The covariance of the states group ``g`` touches, and where each state index
        sits in it."""
        idx = sorted({i for r in g for i in r[0]})
        return self.P[np.ix_(idx, idx)], {s: t for t, s in enumerate(idx)}

    def _passes_gate(self, g: list[JointRow]) -> bool:
        """Whether group ``g``'s squared Mahalanobis distance is within ``gate_chi2``."""
        C, pos = self._block_of(g)
        H = np.zeros((len(g), len(C)))
        for a, (ix, hv, _, _) in enumerate(g):
            for s, v in zip(ix, hv, strict=True):
                H[a, pos[s]] += v
        nu = np.array([r[2] for r in g])
        S = H @ C @ H.T + np.diag([r[3] for r in g])
        return float(nu @ np.linalg.solve(S, nu)) <= self.gate

    def gated_rows(self, measurements: Sequence[Sequence[Measurement]]) -> list[list[JointRow]]:
        """:meth:`rows`, less the groups the gate drops (counted in ``rejected``)."""
        groups = self.rows(measurements)
        if self.gate > 0.0 and groups:
            kept = [g for g in groups if self._passes_gate(g)]
            self.rejected += len(groups) - len(kept)
            groups = kept
        return groups

    def update(self, measurements: Sequence[Sequence[Measurement]]) -> None:
        groups = self.gated_rows(measurements)
        if not groups:
            return
        P = self.P
        d = np.zeros(self.x.shape[0])  # x - x_pred accumulated over the rows
        for g in groups:
            for idx, hv, nu, r in g:
                ix = list(idx)
                h = np.array(hv)
                nu -= float(h @ d[ix])          # innovation at the one linearisation point
                u = P[:, ix] @ h                # u = P H^T
                s = float(h @ u[ix]) + r        # S = H P H^T + r
                kgain = u / s                   # K = P H^T / S
                d += kgain * nu
                P -= np.outer(kgain, u)         # P - K S K^T
        self.P = 0.5 * (P + P.T)
        self.x += d
        self.x[2::3] = wrap(self.x[2::3])

    def estimates(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(self.x[3 * i:3 * i + 3].copy(), self.P[3 * i:3 * i + 3, 3 * i:3 * i + 3].copy())
                for i in range(len(self.ctx.members))]

    def joint(self) -> tuple[np.ndarray, np.ndarray]:
        """The joint mean (3N,) and covariance (3N, 3N)."""
        return self.x.copy(), self.P.copy()


class PairwiseDecentralisedEKF(CentralisedEKF):
    """Decentralised with pairwise communication (Luft, Schubert, Roumeliotis & Burgard,
    "Recursive decentralized localization for multi-robot systems with asynchronous
    pairwise communication", IJRR 37(10), 2018).

    Robot i keeps only its own mean x_i, its covariance S_ii (3 x 3) and, for every
    teammate j, a factor s_ij (3 x 3) such that the cross-covariance is
    ``S_ij = s_ij s_ji^T``: no robot holds the joint covariance, yet none counts a
    teammate's information twice, because the correlation it creates is kept.

    - Predict (robot i alone): ``S_ii <- F S_ii F^T + Q``, ``s_ij <- F s_ij``.
    - Own beacon readings (robot i alone): the EKF's sequential update of ``S_ii`` with
      the gain's factor ``Phi = prod (I - k h^T)``; ``s_ij <- Phi s_ij`` (exact).
    - A robot reading of b by a (the two exchange x, S and s_ab / s_ba): the joint EKF
      update of the pair's 6-state with ``S_ab = s_ab s_ba^T``; then ``s_ab <- S_ab^+``,
      ``s_ba <- I``, and for third robots k ``s_ak <- S_aa^+ (S_aa^-)^-1 s_ak`` (the
      paper's approximation: k is not in contact and is not changed).

    Readings are stacked per tick and linearised at the predicted means as in
    :class:`CentralisedEKF` (same rows, same gate); with no robot reading the result is
    the independent EKFs'. Cost per robot reading O(1) in the team size, plus O(N) 3 x 3
    products for the third robots' factors.
    """

    def reset(self, initial: Sequence[GaussianBelief]) -> None:
        super().reset(initial)
        n = len(self.ctx.members)
        self.S = np.array([self.P[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(n)])
        self.sig = np.zeros((n, n, 3, 3))  # sig[i, j] = s_ij; zero: independent at the start
        del self.P

    def predict(self, controls: Sequence[Control], dt: float) -> None:
        if len(controls) != len(self.ctx.members):
            raise FilterError(f"{len(controls)} commands for {len(self.ctx.members)} robots")
        for i, u in enumerate(controls):
            a, b, Q = self._move(i, u, dt)
            F = np.array([[1.0, 0.0, a], [0.0, 1.0, b], [0.0, 0.0, 1.0]])
            self.S[i] = F @ self.S[i] @ F.T + Q
            self.sig[i] = F @ self.sig[i]  # every s_ij, j != i (s_ii is unused)

    def _block(self, robots: list[int]) -> np.ndarray:
        """The joint covariance of ``robots`` (one or two), from S and the factors."""
        if len(robots) == 1:
            return self.S[robots[0]].copy()
        a, b = robots
        C = np.zeros((6, 6))
        C[:3, :3], C[3:, 3:] = self.S[a], self.S[b]
        C[:3, 3:] = self.sig[a, b] @ self.sig[b, a].T
        C[3:, :3] = C[:3, 3:].T
        return C

    def _block_of(self, g: list[JointRow]) -> tuple[np.ndarray, dict[int, int]]:
        """The joint covariance of the robots group ``g`` touches (from S and the factors),
        and where each state index sits in it."""
        robots = sorted({i // 3 for r in g for i in r[0]})
        return self._block(robots), {3 * r + t: 3 * n + t for n, r in enumerate(robots) for t in range(3)}

    def update(self, measurements: Sequence[Sequence[Measurement]]) -> None:
        groups = self.gated_rows(measurements)
        if not groups:
            return
        d = np.zeros(self.x.shape[0])  # x - x_pred accumulated over the rows
        for g in groups:
            robots = sorted({i // 3 for r in g for i in r[0]})
            C = self._block(robots)
            m = len(C)
            pos = {3 * r + t: 3 * k + t for k, r in enumerate(robots) for t in range(3)}
            glob = [3 * r + t for r in robots for t in range(3)]
            phi = np.eye(m)
            dl = np.zeros(m)
            for idx, hv, nu, r in g:
                h = np.zeros(m)
                for s_, v in zip(idx, hv, strict=True):
                    h[pos[s_]] += v
                nu -= float(h @ (d[glob] + dl))
                u = C @ h
                s = float(h @ u) + r
                kgain = u / s
                dl += kgain * nu
                C -= np.outer(kgain, u)
                phi -= np.outer(kgain, h @ phi)  # (I - k h^T) phi
            C = 0.5 * (C + C.T)
            d[glob] += dl
            if len(robots) == 1:
                i = robots[0]
                self.S[i] = C
                self.sig[i] = phi @ self.sig[i]  # every s_ij at once (s_ii is unused)
                continue
            a, b = robots
            for i, blk in ((a, C[:3, :3]), (b, C[3:, 3:])):
                grow = np.linalg.solve(self.S[i].T, blk.T).T  # S_ii^+ (S_ii^-)^-1
                self.sig[i] = grow @ self.sig[i]  # third robots k; s_ab, s_ba are set below
                self.S[i] = blk
            self.sig[a, b] = C[:3, 3:]
            self.sig[b, a] = np.eye(3)
        self.x += d
        self.x[2::3] = wrap(self.x[2::3])

    def estimates(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(self.x[3 * i:3 * i + 3].copy(), self.S[i].copy()) for i in range(len(self.ctx.members))]

    def joint(self) -> tuple[np.ndarray, np.ndarray]:
        """The joint mean and the joint covariance the factors imply (for tests)."""
        n = len(self.ctx.members)
        P = np.zeros((3 * n, 3 * n))
        for i in range(n):
            P[3 * i:3 * i + 3, 3 * i:3 * i + 3] = self.S[i]
            for j in range(n):
                if j != i:
                    P[3 * i:3 * i + 3, 3 * j:3 * j + 3] = self.sig[i, j] @ self.sig[j, i].T
        return self.x.copy(), P


def ci_weight(P: np.ndarray, Pz: np.ndarray, iters: int = 20) -> float:
    """Covariance-intersection weight w in [0.001, 1] minimising
    ``trace((w P^-1 + (1 - w) H^T Pz^-1 H)^-1)`` with H = [I2 0] (golden-section search)."""
    Pi = np.linalg.inv(P)
    Zi = np.zeros_like(Pi)
    Zi[:2, :2] = np.linalg.inv(Pz)

    def cost(w: float) -> float:
        return float(np.trace(np.linalg.inv(w * Pi + (1.0 - w) * Zi)))

    lo, hi = 1e-3, 1.0
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = cost(a), cost(b)
    for _ in range(iters):
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = cost(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = cost(b)
    return 0.5 * (lo + hi)


class CovarianceIntersectionTeam(IndependentTeam):
    """Decentralised: one EKF per robot (the independent baseline's); teammates' position
    messages fused by covariance intersection (``fusion = "ci"``) or, as a counter-example,
    by a naive Kalman update that double-counts (``fusion = "naive"``). ``gate_chi2`` (0: off)
    drops a message whose squared Mahalanobis distance ``e^T (P_j,xy + P_z)^-1 e`` exceeds it.
    The members' own EKF parameters come from the scenario's ``[filters.ekf]``."""

    defaults: ClassVar[dict[str, Any]] = {"fusion": "ci", "gate_chi2": 0.0}

    def __init__(self, ctx: TeamContext):
        super().__init__(ctx, ExtendedKalmanFilter)
        if self.params["fusion"] not in ("ci", "naive"):
            raise FilterError(f"fusion = {self.params['fusion']!r}: expected 'ci' or 'naive'")
        self.naive = self.params["fusion"] == "naive"
        self.gate = float(self.params["gate_chi2"])
        self.fused = 0
        self.rejected = 0

    def messages(self, measurements: Sequence[Sequence[Measurement]]
                 ) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """``(subject index, position (2,), covariance (2, 2))`` for every range-bearing robot
        reading, from the observers' current beliefs."""
        out = []
        for i, ms in enumerate(measurements):
            mean, cov = self.filters[i].estimate()
            for m in ms:
                if m.kind != "robot_range_bearing":
                    continue
                sr, sb = self.ctx.members[i].robot_sensor(m.sensor).reading_std()
                R = np.diag([sr * sr, sb * sb])
                for z, rid in zip(m.z, m.beacon_ids.tolist(), strict=True):
                    j = self.index.get(rid)
                    if j is None or j == i:
                        continue
                    p, jx, jz = teammate_position(mean, z)
                    out.append((j, p, jx @ cov @ jx.T + jz @ R @ jz.T))
        return out

    def fuse(self, j: int, p: np.ndarray, Pz: np.ndarray) -> None:
        """Fuse a position message into robot j's belief (CI or naive)."""
        f = self.filters[j]
        x, P = f.estimate()
        e = p - x[:2]
        S = P[:2, :2] + Pz
        if self.gate > 0.0 and float(e @ np.linalg.solve(S, e)) > self.gate:
            self.rejected += 1
            return
        if self.naive:
            K = np.linalg.solve(S, P[:2, :]).T     # K = P H^T S^-1
            x_new = x + K @ e
            P_new = P - K @ S @ K.T
        else:
            w = ci_weight(P, Pz)
            Zi = np.zeros((3, 3))
            Zi[:2, :2] = np.linalg.inv(Pz)
            P_new = np.linalg.inv(w * np.linalg.inv(P) + (1.0 - w) * Zi)
            x_new = x + (1.0 - w) * (P_new[:, :2] @ (Zi[:2, :2] @ e))
        x_new[2] = wrap(float(x_new[2]))
        f.reset(GaussianBelief(x_new, 0.5 * (P_new + P_new.T)))
        self.fused += 1

    def update(self, measurements: Sequence[Sequence[Measurement]]) -> None:
        super().update(measurements)  # each robot's own beacon readings
        for j, p, Pz in self.messages(measurements):
            self.fuse(j, p, Pz)


def _naive(ctx: TeamContext) -> CovarianceIntersectionTeam:
    return CovarianceIntersectionTeam(TeamContext(ctx.name, ctx.world, ctx.dt, ctx.members,
                                                  {"fusion": "naive", **ctx.params}))


#: Team filters by name.
TEAM_FILTERS: dict[str, Callable[[TeamContext], Any]] = {
    "independent": IndependentTeam,
    "centralised": CentralisedEKF,
    "decentralised": PairwiseDecentralisedEKF,
    "ci": CovarianceIntersectionTeam,
    "naive": _naive,
}


def build_team_filter(name: str, team: TeamScenario, params: Mapping[str, Any] | None = None,
                      seed: int | None = None) -> TeamFilter:
    """Team filter ``name`` (a key of :data:`TEAM_FILTERS`) for ``team``, reset to the
    scenario's initial beliefs."""
    if name not in TEAM_FILTERS:
        raise FilterError(f"no team filter named {name!r}; choose one of {', '.join(TEAM_FILTERS)}")
    merged = {**team.filter_params.get(name, {}), **(params or {})}
    f = TEAM_FILTERS[name](team_context(team, name, merged, seed))
    f.reset(initial_beliefs(team))
    return f
