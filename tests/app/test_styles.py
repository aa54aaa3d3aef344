"""A filter kind has the same colour and line style in the window and in the evaluation's
plots: one table, ``runs/styles.py``, read by both."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.app import palette
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs import styles

NAMES = ["kf", "ekf", "ukf", "pf", "histogram", "dead_reckoning", "my_filter", "ekf'"]


def test_the_window_reads_the_shared_table():
    assert palette.KIND_STYLES is styles.KIND_STYLES
    assert palette.filter_styles(NAMES) == styles.filter_styles(NAMES)


def _curves(names, T=50):
    t = np.arange(1, T + 1) * 0.1
    path = np.stack([t, 0.5 * t, 0 * t], 1)
    one = {"means0": path + 0.01, "err0": np.full((T, 3), 0.01), "sigma0": np.full((T, 3), 0.02),
           "nees_t": np.full(T, 3.0), "rmse_t": np.full(T, 0.05)}
    return {"time": t, "truth0": path, "kidnap_times": [], "nees_band": (2.0, 4.0),
            "pcrb_sigma_t": np.full((T, 3), 0.01), "pcrb_pos_t": np.full(T, 0.02),
            "filters": {n: dict(one) for n in names}}


@pytest.mark.parametrize("which", ["trajectories", "errors", "nees", "rmse_pcrb"])
def test_plots_draw_each_filter_in_its_window_colour_and_dashes(which):
    pytest.importorskip("matplotlib")
    from matplotlib.colors import to_hex

    from beacon_sim.evaluation import plots

    sc = load_scenario("default")
    curves = _curves(NAMES)
    make = getattr(plots, f"{which}_figure")
    fig = make(sc, curves, 3) if which == "nees" else make(sc, curves)
    lines = {ln.get_label().removesuffix(" error"): ln for ln in fig.axes[0].get_lines()}
    want = styles.filter_styles(NAMES)
    for name in NAMES:
        colour, dash = want[name]
        line = lines[name]
        assert to_hex(line.get_color()) == styles.hex_colour(colour), name
        assert (line.get_linestyle() == "-") == (dash is None), name


def test_team_styles_follow_the_member_kind_and_never_repeat():
    from beacon_sim.runs.styles import KIND_STYLES, TEAM_STYLES, team_filter_styles

    names = ["independent:pf", "independent:histogram", "decentralised", "centralised", "ci",
             "independent", "independent:dead_reckoning", "naive", "mine", "yours"]
    styles = team_filter_styles(names)
    assert styles["independent:pf"] == KIND_STYLES["pf"]  # looks like the particle filter
    assert styles["centralised"] == TEAM_STYLES["centralised"]
    assert len(set(styles.values())) == len(names)  # no two look the same
    assert team_filter_styles(["decentralised"])["decentralised"] == TEAM_STYLES["decentralised"]
