"""The posterior Cramer-Rao bound (PCRB) along true trajectories: the smallest covariance
any unbiased estimator can reach for the scenario's motion and sensor models.

Tichavsky, Muravchik & Nehorai (1998) give the recursion for the Fisher information
``J_k`` of ``x_{k+1} = f(x_k) + w_k``, ``z_k = h(x_k) + v_k``:

    J_{k+1} = D22 - D21 (J_k + D11)^-1 D12 + E[H^T R^-1 H]
    D11 = E[F^T Q^-1 F],  D12 = D21^T = -E[F^T] Q^-1,  D22 = Q^-1

With the Jacobians evaluated along a known true trajectory the first three terms equal
``(F J_k^-1 F^T + Q)^-1`` (matrix inversion lemma), which needs no inverse of Q; the
velocity model's Q = B M B^T is singular when the scenario has no additive pose noise.
So, per step::

    P_pred = F P F^T + Q            F, Q at the true pose and the command (truth's noise)
    J      = P_pred^-1 + I_z        I_z: expected measurement information at the true pose
    P      = J^-1                   the bound

``I_z`` is the expected information of a tick's readings: for each beacon in range, field
of view and (walls) line of sight, ``p_detect * (1 - outlier_rate) * H^T R^-1 H``; for a
range finder's scan, ``z_hit * sum over beams of J^T J / sigma_hit^2`` with J each beam's
range derivative from the wall's normal at its hit (core/scan_jacobian.py; beams that miss,
start in a wall or graze it are left out); for pose and position fixes
the expectation over which beacons are detected (a fix from n beacons is n times as
informative; a position fix's noise is ``position_std * HDOP`` of the detected subset).
Blackouts give no information; noise bursts add to Q.

The prior: the simulation starts the truth exactly at the scenario's initial pose (it does
not draw it from the filters' initial belief), so the bound starts from P = 0, a known
start; a bound started from the filters' prior would not hold for these runs (filters beat
it while the prior dominates). Scenarios with a global (uniform) initial belief start from
the broad world-uniform Gaussian instead. The update is written in covariance form
(``P - P L (I + L^T P L)^-1 L^T P`` with ``I_z = L L^T``), which stays exact when P is
singular. A kidnap is not in any filter's model. By default the bound is *not* restarted
there: it continues along the true path as if the displacement had been driven, which is
the bound of an estimator told the kidnap exactly, so it stays below any filter that is not
told. (Restarting from the broad world-uniform prior, ``restart_at_kidnap=True``, is not a
bound: a kidnap of a known size leaves the filters far closer than a room-wide prior, and
they sit below it.) The evaluation leaves a transient window after each kidnap out of
RMSE/PCRB (``evaluation.summary.model_mask``). Down-weighting outliers by
``1 - outlier_rate`` is an approximation (the exact information of a contaminated
Gaussian is not a closed form).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from beacon_sim.core.beam_model import RangeModelParams
from beacon_sim.core.geometry import hdop
from beacon_sim.core.raycast import beam_angles
from beacon_sim.core.scan_jacobian import scan_information
from beacon_sim.core.scenario import RobotSensorSpec, Scenario, TeamScenario, as_team
from beacon_sim.core.schedule import TickSchedule, tick_schedule
from beacon_sim.core.sensor_kinds import is_scan, model_of
from beacon_sim.core.sensors import SensorSpec, in_view, visible_mask
from beacon_sim.core.team_models import relative_range_bearing, relative_rows
from beacon_sim.core.world import World
from beacon_sim.filters.base import broad_gaussian
from beacon_sim.hosting.loading import initial_belief

#: The kinds whose information is written out here (the others: their record's model).
_OWN_KINDS = ("bearing", "range_bearing", "pose", "position")

#: Position sensors enumerate every detected subset of the visible beacons up to this many.
MAX_SUBSET_BEACONS = 10


def _binom_pmf(n: np.ndarray, k: int, p: float) -> np.ndarray:
    comb = np.array([math.comb(int(m), k) if k <= m else 0 for m in n.ravel()], dtype=float)
    return comb.reshape(n.shape) * p**k * (1.0 - p) ** np.maximum(n - k, 0)


def measurement_information(spec: SensorSpec, poses: np.ndarray, bxy: np.ndarray,
                            world: World | None = None) -> np.ndarray:
    """Expected Fisher information of one reading of ``spec``, shape (R, 3, 3), at true
    ``poses`` (R, 3) [m, m, rad] with beacons at ``bxy`` (nb, 2) [m].

    ``world`` (whose beacons are ``bxy``) brings the walls: a range finder's scan
    (:func:`beacon_sim.core.scan_jacobian.scan_information`) and the beacons they hide
    (``sensors.visible_mask``, the simulation's visibility). Without it beacons are seen
    through everything and a range finder is refused."""
    R = poses.shape[0]
    if is_scan(spec.kind):
        if world is None:
            raise ValueError("a range finder's information needs the world (its walls)")
        model = spec.range_model if spec.range_model is not None else \
            RangeModelParams(laser_max_range=spec.max_range)
        return scan_information(world.grid, poses, beam_angles(spec.n_beams, spec.fov),
                                model.laser_max_range, model.sigma_hit, float(model.weights[0]))
    if spec.kind not in _OWN_KINDS:   # another kind: its record's model (core/sensor_kinds.py)
        kind_model = model_of(spec.kind)
        if kind_model is None:
            raise ValueError(f"unknown sensor kind {spec.kind!r}")
        if world is None:
            raise ValueError(f"a {spec.kind} sensor's information needs the world (its beacons)")
        return kind_model.information(spec, poses, world)
    pos = poses[:, :2]
    vis = in_view(spec, poses, bxy) if world is None else visible_mask(spec, poses, world)
    p = spec.detection_prob * (1.0 - spec.outlier_rate)
    info = np.zeros((R, 3, 3))
    d = bxy[None, :, :] - pos[:, None, :]  # (R, nb, 2) beacon - robot
    q = np.maximum(np.sum(d * d, axis=2), 1e-12)
    if spec.kind == "bearing":
        h = np.stack([d[..., 1] / q, -d[..., 0] / q, -np.ones_like(q)], axis=2)  # (R, nb, 3)
        w = vis * (p / spec.noise.bearing_std**2)
        return np.einsum("rb,rbi,rbj->rij", w, h, h)
    if spec.kind == "range_bearing":
        r = np.sqrt(q)
        hr = np.stack([-d[..., 0] / r, -d[..., 1] / r, np.zeros_like(q)], axis=2)
        hb = np.stack([d[..., 1] / q, -d[..., 0] / q, -np.ones_like(q)], axis=2)
        wr = vis * (p / spec.noise.range_std**2)
        wb = vis * (p / spec.noise.bearing_std**2)
        return np.einsum("rb,rbi,rbj->rij", wr, hr, hr) + np.einsum("rb,rbi,rbj->rij", wb, hb, hb)
    n_vis = vis.sum(axis=1)
    if spec.kind == "pose":
        # A fix from n beacons has covariance R1 / n: information n R1^-1, when n >= min_beacons.
        pd = spec.detection_prob
        e_n = np.zeros(R)
        for k in range(spec.min_beacons, int(n_vis.max(initial=0)) + 1):
            e_n += k * _binom_pmf(n_vis, k, pd)
        r1 = spec.fix_std(1) ** 2
        return (1.0 - spec.outlier_rate) * e_n[:, None, None] * np.diag(1.0 / r1)[None]
    if spec.kind == "position":
        nb = bxy.shape[0]
        pd = spec.detection_prob
        s2 = spec.noise.position_std**2
        scalar = np.zeros(R)
        if nb <= MAX_SUBSET_BEACONS:
            for size in range(spec.min_beacons, nb + 1):
                for subset in itertools.combinations(range(nb), size):
                    mask = np.zeros(nb, dtype=bool)
                    mask[list(subset)] = True
                    inside = np.all(vis[:, mask], axis=1)
                    if not inside.any():
                        continue
                    prob = inside * pd**size * (1.0 - pd) ** (n_vis - size)
                    hd = np.asarray(hdop(pos, bxy[mask], spec.beacon_height), dtype=float)
                    ok = np.isfinite(hd) & inside
                    scalar[ok] += prob[ok] / (s2 * hd[ok] ** 2)
        else:  # too many subsets: every visible beacon detected, weighted by P(n >= min)
            for r in range(R):
                if n_vis[r] >= spec.min_beacons:
                    hd = hdop(pos[r], bxy[vis[r]], spec.beacon_height)
                    p_fix = sum(_binom_pmf(n_vis[r:r + 1], k, pd)[0]
                                for k in range(spec.min_beacons, int(n_vis[r]) + 1))
                    if math.isfinite(hd):
                        scalar[r] = p_fix / (s2 * hd**2)
        info[:, 0, 0] = info[:, 1, 1] = (1.0 - spec.outlier_rate) * scalar
        return info
    raise ValueError(f"unknown sensor kind {spec.kind!r}")


def _process(scenario: Scenario, poses: np.ndarray, v, w, dt: float, burst_v: float,
             burst_w: float):
    """F (R, 3, 3) and Q (R, 3, 3) of the truth's velocity model at ``poses`` (R, 3)."""
    noise = scenario.motion_noise
    th = poses[:, 2]
    c, s = np.cos(th), np.sin(th)
    R = poses.shape[0]
    F = np.broadcast_to(np.eye(3), (R, 3, 3)).copy()
    F[:, 0, 2] = -v * dt * s
    F[:, 1, 2] = v * dt * c
    sv, sw = noise.control_std(v, w)
    g = np.asarray(noise.slip_gain(v, w), dtype=float)  # slip scales with the command
    sv2 = np.asarray(sv, dtype=float) ** 2 + (g * burst_v) ** 2
    sw2 = np.asarray(sw, dtype=float) ** 2 + (g * burst_w) ** 2
    Q = np.zeros((R, 3, 3))  # B M B^T, B = [[dt c, 0], [dt s, 0], [0, dt]]
    Q[:, 0, 0] = dt * dt * c * c * sv2
    Q[:, 0, 1] = Q[:, 1, 0] = dt * dt * c * s * sv2
    Q[:, 1, 1] = dt * dt * s * s * sv2
    Q[:, 2, 2] = dt * dt * sw2
    ps2 = np.square(np.broadcast_to(noise.pose_std_at(v, w), (R, 3)))
    Q[:, 0, 0] += ps2[:, 0]
    Q[:, 1, 1] += ps2[:, 1]
    Q[:, 2, 2] += ps2[:, 2]
    return F, Q


def information_update(P: np.ndarray, info: np.ndarray) -> np.ndarray:
    """The bound after readings of information ``info``: ``(P^-1 + I_z)^-1`` for batches
    (R, n, n) of covariances ``P``, valid for singular P (Woodbury). A run whose
    information is not finite (a scan's: not computed) gets a NaN bound (LAPACK's ``eigh``
    raises on NaN rather than returning it)."""
    bad = ~np.all(np.isfinite(info), axis=(1, 2))
    if bad.any():
        out = np.full(np.broadcast_shapes(P.shape, info.shape), np.nan)
        if not bad.all():
            out[~bad] = information_update(P[~bad], info[~bad])
        return out
    w, V = np.linalg.eigh(0.5 * (info + np.swapaxes(info, 1, 2)))
    L = V * np.sqrt(np.clip(w, 0.0, None))[:, None, :]  # I_z = L L^T
    Lt = np.swapaxes(L, 1, 2)
    PL = P @ L
    M = np.eye(P.shape[-1])[None] + Lt @ PL
    P = P - PL @ np.linalg.solve(M, np.swapaxes(PL, 1, 2))
    return 0.5 * (P + np.swapaxes(P, 1, 2))


def start_cov(scenario: Scenario) -> np.ndarray:
    """The bound's covariance at the start (3, 3): zero (the simulation's known start), or
    the broad world-uniform Gaussian for a scenario with a global initial belief."""
    return broad_gaussian(scenario.world).cov if initial_belief(scenario) is None else np.zeros((3, 3))


def step_terms(scenario: Scenario, sched: TickSchedule, k: int, prev: np.ndarray, control: np.ndarray,
               now: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One robot's terms of step ``k`` (1-based) for a batch of runs: ``F`` and ``Q``
    (R, 3, 3) of the truth's motion from the poses ``prev`` (R, 3) with the commands
    ``control`` (R, 2), and the expected information (R, 3, 3) of the readings taken at the
    new poses ``now`` (R, 3), or None when no sensor reads on this tick."""
    bursts = sched.bursts_at(k)
    bv = math.sqrt(sum(b.v_std**2 for b in bursts))
    bw = math.sqrt(sum(b.omega_std**2 for b in bursts))
    F, Q = _process(scenario, prev, control[:, 0], control[:, 1], scenario.dt, bv, bw)
    info = None
    for spec in scenario.sensors:
        if not sched.reads(spec.name, k):
            continue
        i_z = measurement_information(spec, now, scenario.world.beacon_xy, scenario.world)
        info = i_z if info is None else info + i_z
    return F, Q, info


def pcrb(scenario: Scenario | TeamScenario, truths: np.ndarray, controls: np.ndarray,
         kidnapped: np.ndarray | None = None, initial_cov: np.ndarray | None = None,
         restart_at_kidnap: bool = False, robot_sensing: bool = True) -> np.ndarray:
    """The bound on the error covariance after every step of a batch of runs, over N robots
    (Tichavsky et al. 1998; a single robot is a team of one).

    Per step: ``P_pred = F P F^T + Q`` (F, Q block diagonal: each robot's own motion,
    :func:`step_terms`), then ``P = (P_pred^-1 + I_z)^-1`` where I_z holds each robot's
    beacon information on its diagonal block plus, for a team, every robot reading's
    (:func:`robot_information`), which couples the observer's and the subject's blocks.
    With no robot reading the blocks stay uncorrelated and each diagonal block is that
    robot's own bound.

    Parameters
    ----------
    scenario : Scenario or TeamScenario
        Supplies dt, the truth's motion noise and sensors, events, beacons and the prior
        (each robot's own, for a team).
    truths : array (R, T + 1, 3), or (R, T + 1, N, 3) for a team [m, m, rad]
        True poses; row 0 is the initial pose, row k the pose after step k.
    controls : array (R, T, 2), or (R, T, N, 2) for a team [m/s, rad/s]
        The command of each step.
    kidnapped : bool array (R, T), optional
        Steps on which the robot was teleported; used only with ``restart_at_kidnap``.
    initial_cov : array (3, 3), optional
        Covariance of each robot's initial pose; default :func:`start_cov`.
    restart_at_kidnap : bool
        Reset the bound to the broad world-uniform Gaussian on each kidnap (the former
        behaviour; not a lower bound, kept to show why).
    robot_sensing : bool
        A team's robot readings count (False: each robot alone).

    Returns
    -------
    ndarray (R, T, 3, 3), or (R, T, 3N, 3N) for a team
        ``P_k`` [m^2, m^2, rad^2]: no unbiased estimator has a smaller error covariance.
    """
    solo = not isinstance(scenario, TeamScenario)
    team = as_team(scenario)
    truths = np.asarray(truths, dtype=float)
    controls = np.asarray(controls, dtype=float)
    if solo:
        truths, controls = truths[:, :, None, :], controls[:, :, None, :]
    R, T, N = controls.shape[:3]
    n = 3 * N
    scenarios = [r.scenario for r in team.robots]
    scheds = [tick_schedule(r.scenario, r.robot_sensors) for r in team.robots]
    P = np.zeros((R, n, n))
    P_lost = np.zeros((n, n))
    for i, sc in enumerate(scenarios):
        b = slice(3 * i, 3 * i + 3)
        P[:, b, b] = start_cov(sc) if initial_cov is None else np.asarray(initial_cov, dtype=float)
        P_lost[b, b] = np.asarray(broad_gaussian(sc.world).cov, dtype=float)
    out = np.empty((R, T, n, n))
    F = np.zeros((R, n, n))
    Q = np.zeros((R, n, n))
    for k in range(1, T + 1):
        info = None
        for i, sc in enumerate(scenarios):
            b = slice(3 * i, 3 * i + 3)
            Fi, Qi, Ii = step_terms(sc, scheds[i], k, truths[:, k - 1, i], controls[:, k - 1, i],
                                    truths[:, k, i])
            if N == 1:   # one robot: its own terms as they are
                F, Q, info = Fi, Qi, Ii
            else:
                F[:, b, b], Q[:, b, b] = Fi, Qi
                if Ii is not None:
                    info = np.zeros((R, n, n)) if info is None else info
                    info[:, b, b] += Ii
            if robot_sensing:
                for spec in team.robots[i].robot_sensors:
                    if scheds[i].due(spec.name, k):
                        info = np.zeros((R, n, n)) if info is None else info
                        info += robot_information(spec, i, truths[:, k])
        P = F @ P @ np.swapaxes(F, 1, 2) + Q  # P_pred = F P F^T + Q
        if restart_at_kidnap and kidnapped is not None and kidnapped[:, k - 1].any():
            P[kidnapped[:, k - 1]] = P_lost
        if info is not None:
            P = information_update(P, info)  # P = (P_pred^-1 + I_z)^-1
        out[:, k - 1] = P
    return out


def bound_rmse(P: np.ndarray) -> tuple[float, float]:
    """Best position RMSE [m] and heading RMSE [rad] an unbiased filter could reach, from
    bounds ``P`` (..., 3, 3): ``sqrt(mean(P_xx + P_yy))`` and ``sqrt(mean(P_thth))``."""
    return (float(np.sqrt(np.mean(P[..., 0, 0] + P[..., 1, 1]))),
            float(np.sqrt(np.mean(P[..., 2, 2]))))


def robot_information(spec: RobotSensorSpec, observer: int, poses: np.ndarray) -> np.ndarray:
    """Expected Fisher information on the joint state (R, 3N, 3N) of one reading of robot
    sensor ``spec`` carried by robot index ``observer``, at the true ``poses`` (R, N, 3).

    Each teammate j in range and field of view is detected with ``detection_prob``; a
    detection's rows ``H = [.. dh/dx_i .. dh/dx_j ..]`` (core/team_models.py) fill the
    observer's and the subject's blocks and the two cross blocks: this coupling is what
    robot-to-robot readings add to the bound."""
    R, N = poses.shape[:2]
    std = np.asarray(spec.reading_std(), dtype=float)
    info = np.zeros((R, 3 * N, 3 * N))
    a = slice(3 * observer, 3 * observer + 3)
    for r in range(R):
        for j in range(N):
            if j == observer:
                continue
            rng, bearing = relative_range_bearing(poses[r, observer], poses[r, j])
            if rng > spec.max_range or rng <= 0.0 or (spec.fov < 2.0 * math.pi
                                                      and abs(bearing) > 0.5 * spec.fov):
                continue
            _, hi, hj = relative_rows(spec.kind, poses[r, observer], poses[r, j])
            w = spec.detection_prob / std**2  # (d,)
            b = slice(3 * j, 3 * j + 3)
            info[r, a, a] += hi.T @ (w[:, None] * hi)
            info[r, a, b] += hi.T @ (w[:, None] * hj)
            info[r, b, a] += hj.T @ (w[:, None] * hi)
            info[r, b, b] += hj.T @ (w[:, None] * hj)
    return info


def team_pcrb(team: TeamScenario, truths: np.ndarray, controls: np.ndarray,
              robot_sensing: bool = True) -> np.ndarray:
    """:func:`pcrb` of a team (its old name): truths (R, T + 1, N, 3), controls (R, T, N, 2),
    returns (R, T, 3N, 3N)."""
    return pcrb(team, truths, controls, robot_sensing=robot_sensing)


def robot_blocks(P: np.ndarray, i: int) -> np.ndarray:
    """Robot i's 3 x 3 blocks (..., 3, 3) of joint bounds ``P`` (..., 3N, 3N)."""
    return P[..., 3 * i:3 * i + 3, 3 * i:3 * i + 3]
