"""The chi-square quantiles every consistency band and ellipse comes from, against printed
tables (Abramowitz and Stegun, table 26.8; five significant digits)."""

import math

import numpy as np
import pytest

from beacon_sim.core.geometry import CHI2_2DOF
from beacon_sim.core.metrics import anees_band, chi2_cdf, chi2_quantile
from beacon_sim.runs.scene import NEES_BAND

TABLE = [  # (p, dof, quantile)
    (0.025, 1, 0.00098207), (0.975, 1, 5.0239), (0.99, 1, 6.6349),
    (0.025, 3, 0.21580), (0.975, 3, 9.3484), (0.95, 2, 5.9915),
    (0.05, 10, 3.9403), (0.95, 10, 18.307), (0.025, 100, 74.222), (0.975, 100, 129.56),
]


@pytest.mark.parametrize(("p", "dof", "q"), TABLE)
def test_quantiles_match_the_tables(p, dof, q):
    assert chi2_quantile(p, dof) == pytest.approx(q, rel=2e-4)


def test_cdf_inverts_the_quantile_and_matches_a_sample():
    for dof in (1, 3, 7.5, 300, 6000):
        for p in (0.001, 0.3, 0.975):
            assert chi2_cdf(chi2_quantile(p, dof), dof) == pytest.approx(p, abs=1e-9)
    rng = np.random.default_rng(1)
    x = rng.chisquare(3, 200_000)
    assert np.mean(x <= chi2_quantile(0.9, 3)) == pytest.approx(0.9, abs=0.003)


def test_every_band_uses_it():
    """The HUD's single-step band, the ANEES band and the drawn ellipse share one source."""
    assert NEES_BAND == anees_band(1, dof=3) == pytest.approx((0.21580, 9.3484), rel=1e-4)
    assert CHI2_2DOF[0.95] == pytest.approx(-2 * math.log(0.05))
    lo, hi = anees_band(50)
    assert (lo, hi) == pytest.approx((chi2_quantile(0.025, 150) / 50, chi2_quantile(0.975, 150) / 50))
    with pytest.raises(ValueError):
        chi2_quantile(1.0, 3)
