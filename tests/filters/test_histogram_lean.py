"""The lean histogram filter: the blur, the heading roll and the estimate work in
place or in one pass over the grid, with the results of the plain full-grid forms - the
grid bit for bit, the moments to 1e-9."""

import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.base import GaussianBelief
from beacon_sim.filters.grid import histogram
from beacon_sim.hosting.loading import build_filter


def _random_grid(hf, seed):
    rng = np.random.default_rng(seed)
    g = rng.random(hf.grid.shape) ** 8
    hf.grid[:] = g / g.sum()
    hf.offset[:] = rng.uniform(-0.5, 0.5, hf.offset.shape) * hf.cell
    hf.phi = float(rng.uniform(-0.5, 0.5) * hf.bin)
    hf._cache = None
    hf._rows = None


def _plain_blur_xy(g, var_cells):
    g = g.copy()
    while var_cells > 1e-12:
        a = min(var_cells / 2.0, 1.0 / 3.0)
        var_cells -= 2.0 * a
        for axis in (1, 2):
            lo = np.take(g, [0], axis=axis)
            hi = np.take(g, [g.shape[axis] - 1], axis=axis)
            prev = np.concatenate([lo, np.delete(g, -1, axis=axis)], axis=axis)
            nxt = np.concatenate([np.delete(g, 0, axis=axis), hi], axis=axis)
            g = g * (1.0 - 2.0 * a) + (prev + nxt) * a
    return g


def _plain_blur_th(g, var_bins):
    g = g.copy()
    while var_bins > 1e-12:
        a = min(var_bins / 2.0, 1.0 / 3.0)
        var_bins -= 2.0 * a
        g = g * (1.0 - 2.0 * a) + (np.roll(g, 1, axis=0) + np.roll(g, -1, axis=0)) * a
    return g


def _plain_shift_pile(block, sx, sy):
    """Shift ``block`` (k, nx, ny) by (sx, sy) cells into a new array; what would leave piles
    up at the wall."""
    out = block
    for axis, s in ((1, sx), (2, sy)):
        if s == 0:
            continue
        a = np.moveaxis(out, axis, -1)
        n = a.shape[-1]
        s = max(-(n - 1), min(n - 1, s))
        moved = np.zeros_like(a)
        if s > 0:
            moved[..., s:] = a[..., : n - s]
            moved[..., n - 1] += a[..., n - s:].sum(axis=-1)
        else:
            moved[..., : n + s] = a[..., -s:]
            moved[..., 0] += a[..., :-s].sum(axis=-1)
        out = np.moveaxis(moved, -1, axis)
    return out


def _plain_moments(hf):
    """Mean and covariance straight from every cell's pose and probability."""
    p = hf.grid / hf.grid.sum()
    th = hf.theta[:, None, None]
    x = hf.xc[None, :, None] + hf.offset[:, 0, None, None]
    y = hf.yc[None, None, :] + hf.offset[:, 1, None, None]
    mx, my = float((p * x).sum()), float((p * y).sum())
    P = p.sum(axis=(1, 2))
    mth = math.atan2(float(P @ np.sin(hf.theta)), float(P @ np.cos(hf.theta)))
    et = wrap(th - mth)
    d = [x - mx, y - my, et]
    cov = np.array([[float((p * a * b).sum()) for b in d] for a in d])
    cov += np.diag([hf.cell**2 / 12] * 2 + [hf.bin**2 / 12])
    return np.array([mx, my, wrap(mth)]), cov


def test_blur_and_roll_match_the_plain_forms_bit_for_bit():
    sc = load_scenario("default")
    hf = build_filter("histogram", sc, 0)
    for seed in range(3):
        _random_grid(hf, seed)
        for var in (0.03, 0.4, 1.7):
            g0 = hf.grid.copy()
            hf._blur_xy(var)
            assert np.array_equal(hf.grid, _plain_blur_xy(g0, var))
            g0 = hf.grid.copy()
            hf._blur_th(var)
            assert np.array_equal(hf.grid, _plain_blur_th(g0, var))
        out = np.empty_like(hf.grid)
        for k in (1, -1, 3, -40, 37):
            assert np.array_equal(histogram._roll_into(hf.grid, k, out), np.roll(hf.grid, k, axis=0))


def test_in_place_slab_shift_matches_the_copying_shift_bit_for_bit():
    rng = np.random.default_rng(1)
    for shape in ((60, 40), (3, 2), (1, 5), (5, 1), (1, 1)):
        for sx in range(-5, 6):
            for sy in range(-5, 6):
                g = rng.random(shape)
                want = _plain_shift_pile(g[None].copy(), sx, sy)[0]
                histogram._shift_pile_inplace(g, sx, sy)
                assert np.array_equal(g, want), (shape, sx, sy)


def test_one_pass_moments_match_the_full_grid_ones():
    sc = load_scenario("default")
    hf = build_filter("histogram", sc, 0)
    for seed in range(5):
        _random_grid(hf, seed)
        mean, cov = hf.estimate()
        ref_mean, ref_cov = _plain_moments(hf)
        np.testing.assert_allclose(mean, ref_mean, rtol=0, atol=1e-9)
        np.testing.assert_allclose(cov, ref_cov, rtol=0, atol=1e-9)


def test_a_run_gives_the_plain_moments_at_every_step():
    sc = load_scenario("default")
    hf = build_filter("histogram", sc, 0)
    hf.reset(GaussianBelief(np.array([2.5, 2.2, 0.0]), np.diag([0.01, 0.01, 0.0025])))
    for i, st in enumerate(Simulation(sc, 0).run(20.0)):
        hf.predict(st.control, st.dt)
        hf.update(st.measurements)
        mean, cov = hf.estimate()
        if i % 25 == 0:
            ref_mean, ref_cov = _plain_moments(hf)
            np.testing.assert_allclose(mean, ref_mean, rtol=0, atol=1e-9)
            np.testing.assert_allclose(cov, ref_cov, rtol=0, atol=1e-9)


def _plain_update(hf, measurements):
    """The update from its formula over the whole grid, reading by reading (beacon readings
    without outliers, as on `default`): L = sum over readings of kappa cos(z_b - alpha + theta)
    - kappa - (r - z_r)^2 / (2 sr^2), peak subtracted, exp, product, normalised, floor;
    returns the new grid (the filter's grid is left as it is)."""
    cell_var = hf.cell**2 / 6.0
    th = hf.theta[:, None, None]
    L = np.zeros(hf.grid.shape)
    for m in measurements:
        spec = hf.ctx.sensor(m.sensor)
        assert m.kind in ("bearing", "range_bearing") and spec.outlier_rate == 0
        std = spec.reading_std()
        for row, b in zip(np.asarray(m.z), hf.ctx.world.beacon_index(m.beacon_ids), strict=True):
            bx, by = hf.ctx.world.beacon_xy[b]
            dx = bx - hf.xc[:, None]
            dy = by - hf.yc[None, :]
            r = np.hypot(dx, dy)
            alpha = np.arctan2(dy, dx)
            kappa = 1.0 / (std[-1] ** 2 + hf.bin**2 / 12 + cell_var / np.maximum(r, hf.cell) ** 2)
            L += kappa * (np.cos(row[-1] - alpha + th) - 1.0)
            if m.kind == "range_bearing":
                L -= 0.5 * (r - row[0]) ** 2 / (std[0] ** 2 + cell_var)
    L -= L.max()
    _plain_update.rows_clipped_whole += int(np.any(np.max(L, axis=(0, 2)) < -600.0))
    L = np.exp(np.maximum(L, -600.0))
    g = hf.grid * L
    g = g / g.sum()
    eps = hf.params["floor"]
    return g * (1 - eps) + eps / g.size


_plain_update.rows_clipped_whole = 0     # updates in which some x rows are below the clip


def test_update_matches_the_plain_formula_and_keeps_the_moments():
    """Several steps of `default` from the initial belief and from a kidnap-like spread grid:
    the grid to 1e-9 relative of the plain full-grid update, the moments (kept from the
    update's own pass) to 1e-9 of the plain ones. Readings combined as one product over
    per-beacon arrays, x rows below the clip multiplied by exp(-600) without their exp."""
    sc = load_scenario("default")
    steps = Simulation(sc, 3).run(6.0)
    hf = build_filter("histogram", sc, 0)
    hf.reset(GaussianBelief(np.array(sc.initial_pose), np.diag([0.1, 0.1, 0.05]) ** 2))
    checked = 0
    for i, st in enumerate(steps):
        if i == 60:
            _random_grid(hf, 7)               # a spread belief: most cells far from the readings
        hf.predict(st.control, st.dt)
        if not [m for m in st.measurements if len(m)]:
            continue
        want = _plain_update(hf, st.measurements)
        hf.update(st.measurements)
        assert np.allclose(hf.grid, want, rtol=1e-9, atol=0.0)
        m1, c1 = hf.estimate()
        hf._rows, hf._cache = None, None       # the same grid, moments from a fresh pass
        m2, c2 = _plain_moments(hf)
        d = np.abs(m1 - m2)
        d[2] = min(d[2], 2 * math.pi - d[2])
        assert d.max() < 1e-9 and np.abs(c1 - c2).max() < 1e-9
        checked += 1
    assert checked > 30 and _plain_update.rows_clipped_whole > 10
