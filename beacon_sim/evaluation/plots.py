"""Plots of an evaluation (matplotlib, the optional ``plot`` extra).

The ``*_figure`` functions build and return a :class:`matplotlib.figure.Figure`; the
``plot_*`` functions write it to a PNG. Neither imports pyplot, switches matplotlib's
backend or leaves a figure open, so a notebook's or a script's own matplotlib setup is left
as it was. matplotlib is imported inside the functions: without it, :func:`available` is
False and the command says how to install it and skips the plots.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.files import atomic_output
from beacon_sim.core.optional import install_hint
from beacon_sim.runs.styles import BOUND_STYLE, filter_styles, hex_colour, plot_linestyle

INSTALL_HINT = "plots skipped: " + install_hint("matplotlib", "drawing plots")


def available() -> bool:
    """True when matplotlib can be imported."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _figure(figsize: tuple[float, float]):
    """A new figure owned by nobody but the caller (no pyplot, no backend switch)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, layout="tight")


def _styles(curves: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """matplotlib ``color`` and ``linestyle`` per filter: the window's colour and line style
    of its kind (runs/styles.py), so a filter looks the same in the window and the plots."""
    return {n: {"color": hex_colour(c), "linestyle": plot_linestyle(d)}
            for n, (c, d) in filter_styles(list(curves["filters"])).items()}


#: The PCRB's line: the window's bound style (black, dotted).
BOUND = {"color": hex_colour(BOUND_STYLE[0]), "linestyle": plot_linestyle(BOUND_STYLE[1], 0.4)}


def _mark_kidnaps(ax, curves: dict[str, Any]) -> None:
    """A dashed red line at each kidnap time [s]."""
    for k in curves["kidnap_times"]:
        ax.axvline(k, color="r", lw=0.8, ls="--")


def _save(fig, path: Path) -> Path:
    """Write the PNG (matplotlib's Agg renderer, whatever the current backend)."""
    with atomic_output(path, what="plot") as tmp:  # whole, or the previous file stays
        fig.savefig(tmp, dpi=110, format=Path(path).suffix.lstrip(".") or "png")
    return path


def trajectories_figure(scenario, curves: dict[str, Any]):
    """The first run's true path, each filter's estimate and the beacons [m], world frame."""
    fig = _figure((7, 5.5))
    ax = fig.subplots()
    b = scenario.world.beacon_xy
    ax.plot(b[:, 0], b[:, 1], "k^", ms=8, label="beacons")
    t = curves["truth0"]
    ax.plot(t[:, 0], t[:, 1], "k-", lw=2, label="truth")
    style = _styles(curves)
    for name, c in curves["filters"].items():
        if c["means0"] is not None:
            ax.plot(c["means0"][:, 0], c["means0"][:, 1], lw=1.2, label=name, **style[name])
    xmin, ymin, xmax, ymax = scenario.world.bounds
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{scenario.name}: trajectories (first run)")
    ax.legend(loc="best", fontsize=8)
    return fig


def errors_figure(scenario, curves: dict[str, Any]):
    """Error against time [s] per axis (first run) with each filter's +-3 sigma and the PCRB's."""
    fig = _figure((8, 7))
    axes = fig.subplots(3, 1, sharex=True)
    t = curves["time"]
    labels = ("x error [m]", "y error [m]", "heading error [rad]")
    style = _styles(curves)
    for name, c in curves["filters"].items():
        for i, ax in enumerate(axes):
            (line,) = ax.plot(t, c["err0"][:, i], lw=0.9, label=f"{name} error", **style[name])
            ax.fill_between(t, -3 * c["sigma0"][:, i], 3 * c["sigma0"][:, i],
                            color=line.get_color(), alpha=0.15, lw=0)
    for i, ax in enumerate(axes):
        ax.plot(t, 3 * curves["pcrb_sigma_t"][:, i], lw=0.8, **BOUND)
        ax.plot(t, -3 * curves["pcrb_sigma_t"][:, i], lw=0.8, **BOUND,
                label="+-3 sigma PCRB" if i == 0 else None)
        _mark_kidnaps(ax, curves)
        ax.set_ylabel(labels[i])
        span = max(np.nanmax(np.abs(c["err0"][:, i])) for c in curves["filters"].values()) \
            if curves["filters"] else 1.0
        if np.isfinite(span) and span > 0:
            ax.set_ylim(-1.5 * span, 1.5 * span)
    axes[0].legend(loc="upper right", fontsize=7)
    axes[0].set_title(f"{scenario.name}: error and +-3 sigma (shaded), first run")
    axes[-1].set_xlabel("time [s]")
    return fig


def nees_figure(scenario, curves: dict[str, Any], runs: int):
    """NEES averaged over ``runs`` runs against time [s], with the 95 % chi-square band."""
    fig = _figure((8, 4))
    ax = fig.subplots()
    t = curves["time"]
    lo, hi = curves["nees_band"]
    style = _styles(curves)
    for name, c in curves["filters"].items():
        ax.plot(t, c["nees_t"], lw=0.9, label=name, **style[name])
    ax.axhspan(lo, hi, color="g", alpha=0.15, label=f"95 % band ({runs} runs)")
    ax.axhline(3.0, color="g", lw=0.8)
    _mark_kidnaps(ax, curves)
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("NEES (mean over runs)")
    ax.set_title(f"{scenario.name}: NEES against time")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def rmse_pcrb_figure(scenario, curves: dict[str, Any]):
    """Position RMSE [m] over runs against time [s] beside the PCRB (best any unbiased filter)."""
    fig = _figure((8, 4))
    ax = fig.subplots()
    t = curves["time"]
    style = _styles(curves)
    for name, c in curves["filters"].items():
        ax.plot(t, c["rmse_t"], lw=1.0, label=name, **style[name])
    ax.plot(t, curves["pcrb_pos_t"], lw=1.2, label="PCRB", **BOUND)
    _mark_kidnaps(ax, curves)
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position RMSE [m]")
    ax.set_title(f"{scenario.name}: RMSE beside the posterior Cramer-Rao bound")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def plot_trajectories(scenario, curves: dict[str, Any], path: Path) -> Path:
    """:func:`trajectories_figure` as a PNG at ``path``."""
    return _save(trajectories_figure(scenario, curves), path)


def plot_errors(scenario, curves: dict[str, Any], path: Path) -> Path:
    """:func:`errors_figure` as a PNG at ``path``."""
    return _save(errors_figure(scenario, curves), path)


def plot_nees(scenario, curves: dict[str, Any], path: Path, runs: int) -> Path:
    """:func:`nees_figure` as a PNG at ``path``."""
    return _save(nees_figure(scenario, curves, runs), path)


def plot_rmse_pcrb(scenario, curves: dict[str, Any], path: Path) -> Path:
    """:func:`rmse_pcrb_figure` as a PNG at ``path``."""
    return _save(rmse_pcrb_figure(scenario, curves), path)


def plot_all(scenario, curves: dict[str, Any], out: Path, runs: int) -> list[Path]:
    """All four plots for one scenario into ``out``; returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    stem = scenario.name
    return [
        plot_trajectories(scenario, curves, out / f"{stem}_trajectories.png"),
        plot_errors(scenario, curves, out / f"{stem}_errors.png"),
        plot_nees(scenario, curves, out / f"{stem}_nees.png", runs),
        plot_rmse_pcrb(scenario, curves, out / f"{stem}_rmse_pcrb.png"),
    ]
