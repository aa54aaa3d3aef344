"""Data association against hand-built cases, brute force and the maths:
Mahalanobis distances and the joint NIS against explicit loops, JCBB against an exhaustive search,
the joint NIS of the true pairing chi-square distributed (the cross terms are right), the per-particle
maximum-likelihood association against a loop, and the sensor side (clutter, hidden IDs)."""

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.core import clutter as cl
from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap
from beacon_sim.core.sensors import SensorNoise, SensorSpec, sense
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World
from beacon_sim.filters import association as assoc

# The hand-built case of docs/association.md: two beacons 0.2 rad apart seen from the origin,
# a heading uncertain by 0.2 rad (1 sigma), bearings good to 0.01 rad. The robot has in fact
# turned 0.15 rad less than the estimate says, so both readings appear 0.15 rad to the left.
LOOKALIKE_XY = np.array([[5 * math.cos(0.1), 5 * math.sin(0.1)], [5 * math.cos(-0.1), 5 * math.sin(-0.1)]])
LOOKALIKE_IDS = np.array([7, 8])
LOOKALIKE_P = np.diag([1e-4, 1e-4, 0.2 ** 2])
LOOKALIKE_Z = np.array([[0.1 + 0.15], [-0.1 + 0.15]])  # truly beacon 7, then beacon 8


def brute_force_d2(kind, z, mean, P, xy, std):
    d = 1 if kind == "bearing" else 2
    R = np.diag(np.asarray(std, dtype=float) ** 2)
    out = np.empty((len(z), len(xy)))
    for i in range(len(z)):
        for j in range(len(xy)):
            dx, dy = xy[j] - mean[:2]
            q = dx * dx + dy * dy
            b = math.atan2(dy, dx) - mean[2]
            if d == 1:
                nu = np.array([math.remainder(z[i, 0] - b, 2 * math.pi)])
                H = np.array([[dy / q, -dx / q, -1.0]])
            else:
                r = math.sqrt(q)
                nu = np.array([z[i, 0] - r, math.remainder(z[i, 1] - b, 2 * math.pi)])
                H = np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])
            S = H @ P @ H.T + R
            out[i, j] = nu @ np.linalg.inv(S) @ nu
    return out


@pytest.mark.parametrize("kind", ["bearing", "range_bearing"])
def test_mahalanobis_distances_match_a_brute_force_loop(kind):
    rng = np.random.default_rng(3)
    xy = rng.uniform(-10, 10, (6, 2))
    mean = np.array([0.5, -0.3, 3.1])  # near +pi: the bearing residuals must be wrapped
    A = rng.normal(size=(3, 3)) * 0.2
    P = A @ A.T + np.diag([0.01, 0.01, 0.001])
    std = [0.05] if kind == "bearing" else [0.2, 0.05]
    z = rng.uniform(-math.pi, math.pi, (5, 1))
    if kind == "range_bearing":
        z = np.hstack([rng.uniform(0, 12, (5, 1)), z])
    lin = assoc.linearise(kind, z, mean, P, xy, std)
    assert lin.d2.shape == (5, 6)
    assert np.allclose(lin.d2, brute_force_d2(kind, z, mean, P, xy, std), rtol=1e-9)
    assert np.all(np.abs(lin.nu[..., -1]) <= math.pi)


def test_an_inflated_linearisation_is_the_linearisation_of_the_inflated_belief_and_noise():
    """``inflated(lin, k)``: the distances of the same readings under k P and k R (by the
    brute-force loop), and the joint NIS of any pairing divided by k."""
    rng = np.random.default_rng(11)
    xy = rng.uniform(-8, 8, (5, 2))
    mean, P = np.array([0.2, 0.1, 0.4]), np.diag([0.04, 0.09, 0.02])
    std, k = [0.3, 0.05], 2.5
    z = np.hstack([rng.uniform(1, 10, (4, 1)), rng.uniform(-math.pi, math.pi, (4, 1))])
    lin = assoc.linearise("range_bearing", z, mean, P, xy, std)
    big = assoc.inflated(lin, k)
    want = brute_force_d2("range_bearing", z, mean, k * P, xy, np.sqrt(k) * np.array(std))
    assert np.allclose(big.d2, want, rtol=1e-9)
    pairing = ((0, 1), (2, 3))
    assert assoc.joint_nis(big, pairing) == pytest.approx(assoc.joint_nis(lin, pairing) / k, rel=1e-9)
    assert assoc.inflated(lin, 1.0) is lin


def test_refuse_ambiguous_drops_a_reading_two_distinguishable_beacons_fit_alike():
    """Against the definitions: beacons 7 and 8 of the look-alike case are 0.2 rad apart
    (20 sigma of the 0.01 rad bearing: distinguishable) and both inside the gate of a
    reading between them under the 0.2 rad heading sigma. The nearest's share of the summed
    Gaussian likelihood, computed here by hand, decides: refused when the share asked for is
    above it, kept below. A beacon 0.005 rad from the nearest (half a bearing sigma:
    indistinguishable) is in its group, so it never makes a reading ambiguous."""
    z = np.array([[0.02]])
    lin = assoc.linearise("bearing", z, np.zeros(3), LOOKALIKE_P, LOOKALIKE_XY, [0.01])
    assert np.all(lin.d2 <= assoc.gate(0.99, 1))
    like = np.exp(-0.5 * lin.d2[0]) / np.sqrt(np.linalg.det(lin.S))
    own = like.max() / like.sum()
    assert 0.5 < own < 0.9
    assert np.all(np.isinf(assoc.refuse_ambiguous(lin, 0.99, own + 0.01).d2))
    assert np.array_equal(assoc.refuse_ambiguous(lin, 0.99, own - 0.01).d2, lin.d2)
    assert assoc.nearest_neighbour(assoc.refuse_ambiguous(lin, 0.99, own + 0.01), LOOKALIKE_IDS
                                   ).beacon_ids == (None,)
    twin = np.array([[5 * math.cos(0.1), 5 * math.sin(0.1)], [5 * math.cos(0.095), 5 * math.sin(0.095)]])
    lin2 = assoc.linearise("bearing", np.array([[0.098]]), np.zeros(3), LOOKALIKE_P, twin, [0.01])
    assert np.all(lin2.d2 <= assoc.gate(0.99, 1))
    assert np.array_equal(assoc.refuse_ambiguous(lin2, 0.99, 0.999).d2, lin2.d2)


def test_a_bearing_residual_across_pi_is_small():
    xy = np.array([[-5.0, 0.001]])  # bearing ~ +pi from the origin
    lin = assoc.linearise("bearing", np.array([[-math.pi + 0.01]]), np.zeros(3), np.eye(3) * 1e-4, xy, [0.05])
    assert abs(lin.nu[0, 0, 0]) < 0.02
    assert lin.d2[0, 0] < 1.0


def test_joint_nis_matches_the_stacked_formula_and_carries_the_cross_terms():
    lin = assoc.linearise("bearing", LOOKALIKE_Z, np.zeros(3), LOOKALIKE_P, LOOKALIKE_XY, [0.01])
    pairing = ((0, 0), (1, 1))
    nu = np.array([lin.nu[0, 0, 0], lin.nu[1, 1, 0]])
    H = np.vstack([mm.bearing_jacobian(np.zeros(3), LOOKALIKE_XY[[0]]),
                   mm.bearing_jacobian(np.zeros(3), LOOKALIKE_XY[[1]])])
    S = H @ LOOKALIKE_P @ H.T + np.eye(2) * 1e-4
    assert assoc.joint_nis(lin, pairing) == pytest.approx(nu @ np.linalg.inv(S) @ nu, rel=1e-12)
    # The shared heading error correlates the readings: the joint NIS is not the sum of the
    # individual distances...
    individual = lin.d2[0, 0] + lin.d2[1, 1]
    assert abs(assoc.joint_nis(lin, pairing) - individual) > 0.1 * individual
    # ... and it is, when the pose is certain (S block diagonal).
    sure = assoc.linearise("bearing", LOOKALIKE_Z, np.zeros(3), np.zeros((3, 3)), LOOKALIKE_XY, [0.01])
    assert assoc.joint_nis(sure, pairing) == pytest.approx(sure.d2[0, 0] + sure.d2[1, 1], rel=1e-12)
    assert assoc.joint_nis(lin, ()) == 0.0


def test_jcbb_rejects_the_crossed_assignment_that_nearest_neighbour_accepts():
    lin = assoc.linearise("bearing", LOOKALIKE_Z, np.zeros(3), LOOKALIKE_P, LOOKALIKE_XY, [0.01])
    # Each reading alone is compatible with both beacons.
    assert np.all(lin.d2 <= assoc.gate(0.99, 1))
    nn = assoc.nearest_neighbour(lin, LOOKALIKE_IDS)
    jc = assoc.jcbb(lin, LOOKALIKE_IDS)
    # NN takes the closest pair first (reading 1 with beacon 7), then has to cross.
    assert nn.beacon_ids == (8, 7)
    assert nn.joint_nis > assoc.gate(0.99, 2)  # jointly impossible: a heading error of +0.25 and -0.05
    assert jc.beacon_ids == (7, 8)
    assert jc.method == "jcbb" and jc.dof == 2 and jc.n_paired == 2
    assert jc.joint_nis <= assoc.gate(0.99, 2)


def test_jcbb_leaves_a_reading_out_when_no_full_pairing_is_jointly_compatible():
    """Readings spread apart (one 0.15 rad left of beacon 7, one 0.15 rad right of beacon 8):
    each fits both beacons alone, but no single heading error explains both. NN pairs both;
    JCBB pairs one and calls the other clutter."""
    z = np.array([[0.1 + 0.15], [-0.1 - 0.15]])
    lin = assoc.linearise("bearing", z, np.zeros(3), LOOKALIKE_P, LOOKALIKE_XY, [0.01])
    assert np.all(lin.d2 <= assoc.gate(0.99, 1))
    nn = assoc.nearest_neighbour(lin, LOOKALIKE_IDS)
    assert nn.beacon_ids == (7, 8) and nn.joint_nis > assoc.gate(0.99, 2)
    assert assoc.joint_nis(lin, ((0, 1), (1, 0))) > assoc.gate(0.99, 2)
    jc = assoc.jcbb(lin, LOOKALIKE_IDS)
    assert jc.n_paired == 1 and jc.dof == 1
    assert jc.beacon_ids in ((7, None), (None, 8))
    assert jc.joint_nis <= assoc.gate(0.99, 1)


@pytest.mark.parametrize("kind", ["bearing", "range_bearing"])
def test_nn_and_jcbb_agree_and_are_right_when_the_beacons_are_far_apart(kind):
    rng = np.random.default_rng(11)
    xy = np.array([[8.0, 0.0], [0.0, 8.0], [-8.0, 0.0], [0.0, -8.0], [6.0, 6.0]])
    ids = np.array([10, 11, 12, 13, 14])
    std = np.array([0.05]) if kind == "bearing" else np.array([0.1, 0.05])
    P = np.diag([0.05 ** 2, 0.05 ** 2, 0.02 ** 2])
    for _ in range(20):
        truth = np.array([0.3, -0.2, rng.uniform(-math.pi, math.pi)])
        mean = truth + rng.multivariate_normal(np.zeros(3), P)
        seen = rng.permutation(5)[:4]
        zt = mm.bearing(truth, xy[seen])[:, None] if kind == "bearing" else mm.range_bearing(truth, xy[seen])
        z = zt + rng.normal(size=zt.shape) * std
        z[:, -1] = wrap(z[:, -1])
        lin = assoc.linearise(kind, z, mean, P, xy, std)
        # A 99.99 % gate: with 80 true readings a 99 % one would drop about one of them.
        nn, jc = assoc.nearest_neighbour(lin, ids, prob=0.9999), assoc.jcbb(lin, ids, prob=0.9999)
        assert nn.beacon_ids == jc.beacon_ids == tuple(int(i) for i in ids[seen])


def test_the_gate_rejects_clutter():
    xy = np.array([[5.0, 0.0], [0.0, 5.0]])
    ids = np.array([1, 2])
    P = np.diag([0.01, 0.01, 0.001])
    z = np.vstack([mm.range_bearing(np.zeros(3), xy), [[3.0, -2.0]]])  # a false detection last
    lin = assoc.linearise("range_bearing", z, np.zeros(3), P, xy, [0.1, 0.02])
    for result in (assoc.nearest_neighbour(lin, ids), assoc.jcbb(lin, ids)):
        assert result.beacon_ids == (1, 2, None)
        assert result.dof == 4
    # Nothing but clutter: nothing is paired.
    lone = assoc.linearise("range_bearing", [[3.0, -2.0]], np.zeros(3), P, xy, [0.1, 0.02])
    assert assoc.jcbb(lone, ids).beacon_ids == (None,)
    assert assoc.nearest_neighbour(lone, ids).beacon_ids == (None,)


def test_nearest_neighbour_gives_each_beacon_at_most_once():
    xy = np.array([[5.0, 0.0], [-5.0, 0.0]])
    z = np.array([[0.0], [0.01], [-0.01]])  # three readings of beacon 0's bearing
    lin = assoc.linearise("bearing", z, np.zeros(3), np.eye(3) * 1e-4, xy, [0.05])
    result = assoc.nearest_neighbour(lin, np.array([4, 5]))
    assert result.beacon_ids == (4, None, None)


def exhaustive_best(lin, prob):
    """Every pairing of individually compatible, distinct beacons: the most pairs that are
    jointly compatible, and the lowest joint NIS among them."""
    m, n = lin.d2.shape
    g = assoc.gate(prob, lin.dim)
    best = (0, 0.0, ())
    for choice in itertools.product(*[[None] + [j for j in range(n) if lin.d2[i, j] <= g] for i in range(m)]):
        used = [j for j in choice if j is not None]
        if len(used) != len(set(used)):
            continue
        pairing = tuple((i, j) for i, j in enumerate(choice) if j is not None)
        value = assoc.joint_nis(lin, pairing)
        if pairing and value > assoc.gate(prob, lin.dim * len(pairing)):
            continue
        if len(pairing) > best[0] or (len(pairing) == best[0] and value < best[1]):
            best = (len(pairing), value, pairing)
    return best


@pytest.mark.parametrize("seed", range(6))
def test_jcbb_finds_what_an_exhaustive_search_finds(seed):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-4, 4, (5, 2)) + np.array([6.0, 0.0])  # a cluster: many candidates
    truth = np.array([0.0, 0.0, 0.0])
    P = np.diag([0.3 ** 2, 0.3 ** 2, 0.1 ** 2])
    mean = truth + rng.multivariate_normal(np.zeros(3), P)
    z = mm.range_bearing(truth, xy[:3]) + rng.normal(size=(3, 2)) * [0.1, 0.02]
    z = np.vstack([z, [[rng.uniform(0, 10), rng.uniform(-1, 1)]]])  # and one clutter
    lin = assoc.linearise("range_bearing", z, mean, P, xy, [0.1, 0.02])
    count, value, pairing = exhaustive_best(lin, 0.99)
    jc = assoc.jcbb(lin, np.arange(5))
    assert jc.method == "jcbb"
    assert jc.n_paired == count
    assert jc.joint_nis == pytest.approx(value, rel=1e-9, abs=1e-12)
    assert jc.beacon_ids == tuple(dict(pairing).get(i) for i in range(4))


@pytest.mark.parametrize("singular", [False, True])
def test_jcbbs_incremental_joint_nis_equals_the_stacked_one(singular):
    """JCBB grows the joint NIS pair by pair in information form; it must equal the direct
    ``nu^T (H P H^T + R)^-1 nu`` over the stack, for a singular P too."""
    rng = np.random.default_rng(17)
    xy = rng.uniform(-6, 6, (5, 2))
    z = np.column_stack([rng.uniform(0, 8, 4), rng.uniform(-math.pi, math.pi, 4)])
    A = rng.normal(size=(3, 2 if singular else 3)) * 0.3
    lin = assoc.linearise("range_bearing", z, np.array([0.2, -0.1, 1.0]), A @ A.T, xy, [0.2, 0.05])
    joint = assoc.JointInformation.of(lin)
    for cols in itertools.permutations(range(5), 4):
        state = joint.start()
        for i, j in enumerate(cols):
            states, values = joint.grow(state, i, [j])
            state = states[0]
            direct = assoc.joint_nis(lin, tuple(zip(range(i + 1), cols[: i + 1], strict=True)))
            assert values[0] == pytest.approx(direct, rel=1e-8)


def test_jcbb_falls_back_to_nearest_neighbour_at_its_node_cap():
    lin = assoc.linearise("bearing", LOOKALIKE_Z, np.zeros(3), LOOKALIKE_P, LOOKALIKE_XY, [0.01])
    capped = assoc.jcbb(lin, LOOKALIKE_IDS, max_nodes=2)
    assert capped.method == "nn-fallback"
    assert capped.beacon_ids == assoc.nearest_neighbour(lin, LOOKALIKE_IDS).beacon_ids
    assert assoc.jcbb(lin, LOOKALIKE_IDS).nodes > 2


def test_the_true_pairings_joint_nis_is_chi_square():
    """Monte Carlo: pose drawn from N(mean, P), readings with noise R; the joint NIS of the true
    pairing (with the cross terms) has chi-square(6)'s mean 6 and variance 12 and passes the 99 %
    gate 99 % of the time. The sum of the individual distances (cross terms dropped) has the same
    mean but not the variance: it fails the gate about four times too often."""
    rng = np.random.default_rng(29)
    xy = np.array([[6.0, 1.0], [5.0, 4.0], [7.0, -3.0]])
    P = np.diag([0.05 ** 2, 0.05 ** 2, 0.03 ** 2])
    std = np.array([0.05, 0.01])
    mean = np.zeros(3)
    pairing = ((0, 0), (1, 1), (2, 2))
    joint, blockwise = [], []
    for _ in range(2000):
        truth = rng.multivariate_normal(mean, P)
        z = mm.range_bearing(truth, xy) + rng.normal(size=(3, 2)) * std
        lin = assoc.linearise("range_bearing", z, mean, P, xy, std)
        joint.append(assoc.joint_nis(lin, pairing))
        blockwise.append(lin.d2[0, 0] + lin.d2[1, 1] + lin.d2[2, 2])
    joint_a, block_a = np.array(joint), np.array(blockwise)
    # Standard errors: mean sqrt(12 / 2000) ~ 0.08, variance ~ 0.54, the 1 % tail ~ 0.22 %.
    assert joint_a.mean() == pytest.approx(6.0, abs=0.35)
    assert joint_a.var() == pytest.approx(12.0, abs=2.2)
    assert 0.983 <= np.mean(joint_a <= assoc.gate(0.99, 6)) <= 0.997
    assert block_a.var() > 17.0
    assert np.mean(block_a > assoc.gate(0.99, 6)) > 0.025


def test_per_particle_ml_association_matches_a_loop_over_particles():
    rng = np.random.default_rng(5)
    xy = rng.uniform(-6, 6, (7, 2))
    poses = np.column_stack([rng.uniform(-3, 3, (50, 2)), rng.uniform(-math.pi, math.pi, 50)])
    std = np.array([0.3, 0.1])
    z = np.column_stack([rng.uniform(0, 8, 4), rng.uniform(-math.pi, math.pi, 4)])
    best, loglik = assoc.particle_ml_association("range_bearing", z, poses, xy, std)
    gated, _ = assoc.particle_ml_association("range_bearing", z, poses, xy, std, prob=0.99)
    for k, pose in enumerate(poses):
        zhat = mm.range_bearing(pose, xy)
        for i in range(4):
            ll, d2 = [], []
            for j in range(7):
                e = np.array([z[i, 0] - zhat[j, 0], math.remainder(z[i, 1] - zhat[j, 1], 2 * math.pi)]) / std
                d2.append(float(e @ e))
                ll.append(sum(-0.5 * ek ** 2 - math.log(math.sqrt(2 * math.pi) * sk)
                              for ek, sk in zip(e, std, strict=True)))
            j = int(np.argmax(ll))
            assert best[k, i] == j
            assert loglik[k, i] == pytest.approx(ll[j], rel=1e-12)
            assert gated[k, i] == (j if d2[j] <= assoc.gate(0.99, 2) else -1)
    assert np.any(gated == -1) and np.any(gated >= 0)


def test_per_particle_ml_association_for_bearings_picks_the_true_beacon():
    xy = np.array([[5.0, 0.0], [0.0, 5.0], [-5.0, 0.0]])
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2], [1.0, 1.0, -3.1]])
    for k, pose in enumerate(poses):
        z = mm.bearing(pose, xy[[2, 0]])[:, None]
        best, loglik = assoc.particle_ml_association("bearing", z, poses[[k]], xy, [0.05])
        assert best[0].tolist() == [2, 0]
        assert loglik[0] == pytest.approx(np.full(2, -0.5 * math.log(2 * math.pi * 0.05 ** 2)))


def test_association_refuses_what_it_cannot_associate():
    with pytest.raises(ValueError, match="kind 'pose'"):
        assoc.linearise("pose", np.zeros((1, 3)), np.zeros(3), np.eye(3), LOOKALIKE_XY, [0.1])
    with pytest.raises(ValueError, match="needs 2 values"):
        assoc.linearise("range_bearing", np.zeros((1, 2)), np.zeros(3), np.eye(3), LOOKALIKE_XY, [0.1])
    with pytest.raises(ValueError, match="finite and > 0"):
        assoc.linearise("bearing", np.zeros((1, 1)), np.zeros(3), np.eye(3), LOOKALIKE_XY, [0.0])
    with pytest.raises(ValueError, match="shape"):
        assoc.linearise("bearing", np.zeros((1, 1)), np.zeros(2), np.eye(3), LOOKALIKE_XY, [0.1])
    lin2 = assoc.linearise("bearing", [[0.0]], np.zeros(3), np.eye(3) * 0.01, LOOKALIKE_XY, [0.05])
    with pytest.raises(ValueError, match="3 beacon IDs for 2 beacons"):
        assoc.jcbb(lin2, np.array([1, 2, 3]))
    best, loglik = assoc.particle_ml_association("bearing", [[math.nan]], np.zeros((2, 3)), LOOKALIKE_XY,
                                                 [0.05], prob=0.99)
    assert best.tolist() == [[-1], [-1]] and np.all(loglik == -np.inf)
    # A reading that is not a number fits no beacon.
    nan = assoc.linearise("bearing", [[math.nan]], np.zeros(3), np.eye(3) * 0.01, LOOKALIKE_XY, [0.05])
    assert np.all(nan.d2 == math.inf) and assoc.jcbb(nan, LOOKALIKE_IDS).beacon_ids == (None,)
    # A beacon on the robot has no bearing: it is never compatible, nothing raises.
    lin = assoc.linearise("bearing", [[0.0]], np.zeros(3), np.eye(3) * 0.01, [[0.0, 0.0], [5.0, 0.0]], [0.05])
    assert lin.d2[0, 0] == math.inf
    assert assoc.jcbb(lin, np.array([1, 2])).beacon_ids == (2,)


def test_association_is_deterministic():
    rng = np.random.default_rng(8)
    xy = rng.uniform(-4, 4, (6, 2))
    z = np.column_stack([rng.uniform(0, 6, 5), rng.uniform(-math.pi, math.pi, 5)])
    P = np.diag([0.5, 0.5, 0.2])
    runs = [assoc.jcbb(assoc.linearise("range_bearing", z, np.zeros(3), P, xy, [0.3, 0.1]), np.arange(6))
            for _ in range(2)]
    assert runs[0] == runs[1]


# --- The sensor side: clutter, hidden IDs, look-alike layouts ---------------------------------

RB = SensorSpec("beacons", "range_bearing", max_range=8.0, fov=math.pi / 2,
                noise=SensorNoise(range_std=0.0, bearing_std=0.0))
WORLD = World((-10.0, -10.0, 10.0, 10.0), cl.symmetric_ring(0.0, 0.0, 5.0, 6, first_id=20))


def test_clutter_has_the_poisson_rate_and_is_uniform_in_range_and_bearing():
    rng = np.random.default_rng(2026)
    spec = cl.ClutterSpec(rate=1.5)
    draws = [cl.draw_clutter(RB, spec, rng) for _ in range(4000)]
    counts = np.array([len(d) for d in draws])
    # Poisson(1.5): mean and variance 1.5; standard error of the mean ~ 0.02.
    assert counts.mean() == pytest.approx(1.5, abs=0.08)
    assert counts.var() == pytest.approx(1.5, abs=0.15)
    z = np.vstack(draws)
    assert np.all((z[:, 0] >= 0.0) & (z[:, 0] <= 8.0))
    assert np.all(np.abs(z[:, 1]) <= math.pi / 4)
    for column, lo, hi in ((z[:, 0], 0.0, 8.0), (z[:, 1], -math.pi / 4, math.pi / 4)):
        observed, _ = np.histogram(column, bins=10, range=(lo, hi))
        expected = len(column) / 10
        assert np.sum((observed - expected) ** 2 / expected) < assoc.gate(0.999, 9)
    # All around for a full field of view, bearing-only.
    around = np.vstack([cl.draw_clutter(SensorSpec("b", "bearing", max_range=3.0), cl.ClutterSpec(2.0), rng)
                        for _ in range(500)])
    assert around.shape[1] == 1 and around.min() < -3.0 and around.max() > 3.0


def test_clutter_needs_a_finite_range_and_a_sane_rate():
    with pytest.raises(ValueError, match="finite max_range"):
        cl.draw_clutter(SensorSpec("b", "range_bearing"), cl.ClutterSpec(rate=1.0), np.random.default_rng(0))
    assert cl.draw_clutter(SensorSpec("b", "range_bearing"), cl.ClutterSpec(1.0, max_range=4.0),
                           np.random.default_rng(0)).shape[1] == 2
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="clutter rate"):
            cl.ClutterSpec(rate=bad)


def test_hidden_ids_keep_the_truth_aside_and_shuffle_the_rows():
    sensor = SensorSpec("beacons", "range_bearing", max_range=20.0,
                        noise=SensorNoise(range_std=0.0, bearing_std=0.0))
    pose = np.array([0.5, -0.5, 0.3])
    m = sense(sensor, pose, WORLD, np.random.default_rng(1))
    assert m is not None and len(m) == 6
    orders = set()
    for seed in range(5):
        u = cl.hide_ids(m, sensor, cl.ClutterSpec(rate=2.0), np.random.default_rng(seed))
        assert u is not None
        assert np.all(u.measurement.beacon_ids == cl.UNKNOWN_ID)
        real = u.true_ids != cl.UNKNOWN_ID
        assert sorted(u.true_ids[real].tolist()) == sorted(m.beacon_ids.tolist())
        # Each real row is its true beacon's reading (noise-free sensor).
        expected = mm.range_bearing(pose, WORLD.beacon_positions(u.true_ids[real]))
        assert np.allclose(u.measurement.z[real], expected)
        orders.add(tuple(u.true_ids[real].tolist()))
    assert len(orders) > 1  # the row order no longer gives the IDs away
    # Nothing seen and no clutter: nothing to report; nothing seen but clutter: clutter only.
    assert cl.hide_ids(None, sensor, cl.ClutterSpec(0.0, max_range=5.0), np.random.default_rng(0)) is None
    lone = cl.hide_ids(None, sensor, cl.ClutterSpec(50.0, max_range=5.0), np.random.default_rng(0))
    assert lone is not None and np.all(lone.true_ids == cl.UNKNOWN_ID) and len(lone.measurement) > 0


def test_unknown_correspondence_is_deterministic_and_never_uses_the_global_rng():
    sensor = SensorSpec("beacons", "bearing", max_range=20.0)
    fix = Measurement("gps", "position", np.zeros((1, 2)), np.array([20, 21]))
    m = sense(sensor, np.array([0.0, 0.0, 0.0]), WORLD, np.random.default_rng(4))
    assert m is not None
    runs = []
    saved = np.random.get_state()
    try:
        for reseed in (1, 2):
            np.random.seed(reseed)  # a changed global RNG must not change anything
            out, truth = cl.hide_ids_all([fix, m], [sensor], {"beacons": cl.ClutterSpec(1.0)},
                                         np.random.default_rng(99))
            runs.append((out, truth))
    finally:
        np.random.set_state(saved)  # leave the global state as the other tests found it
    (a, ta), (b, tb) = runs
    assert [x.sensor for x in a] == ["beacons", "gps"]
    assert a[1] is fix  # fixes pass through
    assert np.array_equal(a[0].z, b[0].z) and np.array_equal(ta["beacons"], tb["beacons"])
    assert a[0].z.tobytes() == b[0].z.tobytes()


def test_look_alike_layouts():
    doors = cl.row_of_doors(0.0, 12.0, 2.0, 4, first_id=3)
    assert [b.id for b in doors] == [3, 4, 5, 6]
    assert [b.x for b in doors] == pytest.approx([0.0, 4.0, 8.0, 12.0]) and {b.y for b in doors} == {2.0}
    # A 6-fold ring: a robot turned by 60 degrees about the centre sees exactly the same readings.
    pose = np.array([1.0, 0.5, 0.2])
    c, s = math.cos(math.pi / 3), math.sin(math.pi / 3)
    turned = np.array([c * pose[0] - s * pose[1], s * pose[0] + c * pose[1], pose[2] + math.pi / 3])
    a = np.sort(mm.range_bearing(pose, WORLD.beacon_xy), axis=0)
    b = np.sort(mm.range_bearing(turned, WORLD.beacon_xy), axis=0)
    assert np.allclose(a, b, atol=1e-9)
    with pytest.raises(ValueError):
        cl.symmetric_ring(0.0, 0.0, 0.0, 3)


def test_the_docs_example_runs_as_written():
    """docs/association.md's Python block (the hand-built case) runs and its asserts hold."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "association.md").read_text(encoding="utf-8")
    blocks = [b.split("```", 1)[0] for b in text.split("```python\n")[1:]]
    assert len(blocks) == 1
    exec(compile(blocks[0], "docs/association.md", "exec"), {})
