"""The estimated map of each SLAM filter in the window (docs/slam.md): every landmark's 95 %
ellipse in the filter's colour and line style, with a small cross at its mean, drawn beside
the true beacons (the squares the renderer draws from the scenario).

A filter is drawn here when it has a ``landmarks()`` method (``filters.base.MappingFilter``).
What it returns is read once per tick and filter (the window draws many frames per tick);
a ``landmarks()`` that raises or returns something unusable switches the filter off with
the reason, as a bad ``belief()`` does.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.core.geometry import CHI2_2DOF
from beacon_sim.filters.base import LandmarkMap

#: The squared Mahalanobis radius of the 95 % ellipse of a 2-D Gaussian.
ELLIPSE_95 = CHI2_2DOF[0.95]
#: Half the size of the cross at a landmark's mean [px].
CROSS_PX = 5


def checked_map(value: Any) -> LandmarkMap | str:
    """The value as a :class:`LandmarkMap` with finite means (M, 2) and covariances
    (M, 2, 2), or the reason it cannot be drawn."""
    try:
        means = np.asarray(value.means, dtype=float).reshape(-1, 2)
        covs = np.asarray(value.covs, dtype=float).reshape(-1, 2, 2)
    except (AttributeError, TypeError, ValueError) as exc:
        return f"landmarks(): expected a LandmarkMap (means (M, 2), covs (M, 2, 2)): {exc}"
    if means.shape[0] != covs.shape[0]:
        return f"landmarks(): {means.shape[0]} means but {covs.shape[0]} covariances"
    if not (np.all(np.isfinite(means)) and np.all(np.isfinite(covs))):
        return "landmarks(): a mean or covariance that is not a finite number"
    return LandmarkMap(getattr(value, "ids", None), means, covs)


class MapLayer:
    """Draws the maps; remembers each filter's map for the tick it was read at."""

    def __init__(self) -> None:
        self._cache: dict[str, tuple[int, object, LandmarkMap]] = {}

    def maps(self, session: Any, names: list[str]) -> dict[str, LandmarkMap]:
        """The current map of each named filter that makes one."""
        filters = getattr(session, "filters", None) or {}
        out = {}
        for name in names:
            flt = filters.get(name)
            if flt is None or not callable(getattr(flt, "landmarks", None)):
                continue
            hit = self._cache.get(name)
            if hit is not None and hit[0] == session.tick_count and hit[1] is flt:
                out[name] = hit[2]
                continue
            try:
                got = checked_map(flt.landmarks())
            except Exception as exc:  # a student's landmarks(): show it, keep the window alive
                got = f"landmarks(): {type(exc).__name__}: {exc}"
            if isinstance(got, str):
                session.status[name].failed = got
                continue
            self._cache[name] = (session.tick_count, flt, got)
            out[name] = got
        return out

    def draw(self, surf: pygame.Surface, view, session: Any, names: list[str], colours, dashes,
             lw: int, polyline: Callable[..., None]) -> None:
        """Every landmark of every visible SLAM filter: its 95 % ellipse and a cross.
        ``polyline``: the renderer's dashed-line function (``render.polyline``)."""
        width = max(2, lw // 2)
        for name, lmap in self.maps(session, names).items():
            if not len(lmap.means):
                continue
            colour = colours[name]
            cross = palette.darken(colour, 0.2)
            dash = dashes.get(name)
            outlines = view.to_px(ellipses(lmap.means, lmap.covs).reshape(-1, 2)).reshape(
                len(lmap.means), -1, 2)
            for outline, (x, y) in zip(outlines, view.to_px(lmap.means), strict=True):
                small = float(np.ptp(outline[:, 0]) + np.ptp(outline[:, 1])) < 40.0
                if dash is None or small:  # a dash pattern does not show on a tiny ellipse
                    pygame.draw.lines(surf, colour, True, outline, width)
                else:
                    polyline(surf, colour, outline, width, dash, closed=True)
                c = CROSS_PX
                pygame.draw.line(surf, cross, (x - c, y - c), (x + c, y + c), 2)
                pygame.draw.line(surf, cross, (x - c, y + c), (x + c, y - c), 2)


def ellipses(means: np.ndarray, covs: np.ndarray, n: int = 32) -> np.ndarray:
    """The 95 % ellipses of M 2-D Gaussians at once, shape (M, n, 2) [m] (as
    ``core.geometry.covariance_ellipse`` for each; one batched eigendecomposition)."""
    covs = 0.5 * (covs + covs.transpose(0, 2, 1))
    vals, vecs = np.linalg.eigh(covs)
    radii = np.sqrt(np.clip(vals, 0.0, None) * ELLIPSE_95)          # (M, 2)
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    unit = np.stack([np.cos(t), np.sin(t)], axis=1)                  # (n, 2)
    return means[:, None, :] + (unit[None] * radii[:, None, :]) @ vecs.transpose(0, 2, 1)
