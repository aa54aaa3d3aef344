"""The strip chart (C key): for each filter, its position error [m] (thin line) and its
2-sigma [m] (thick, in the filter's line style) over the last ``span`` seconds of simulated
time, with the stretches when no beacon was in view shaded. A class sees 2-sigma climb in
the blind stretch and drop when beacons come back, and whether the error stays under it.

History is sampled from the scene after each tick (``record``), so it works for a live
session, a replay or an MRCLAM playback alike; going back in time (a seek) clears it.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.render import ipx, polyline

#: Seconds of history shown.
SPAN_S = 60.0
BLIND_SHADE = (255, 226, 204)  # a pale vermillion: "no beacon in view"


class StripChart:
    """A ring of the last ``span`` seconds: time [s], beacons in view, and per filter the
    position error [m] and the 2-sigma of position [m] (2 sqrt of the largest eigenvalue of
    the x-y covariance)."""

    def __init__(self, names: list[str], dt: float, span: float = SPAN_S):
        self.names = list(names)
        self.span = span
        self.cap = max(math.ceil(span / dt) + 2, 8)
        self._size = 2 * self.cap
        self.t = np.full(self._size, np.nan)
        self.blind = np.zeros(self._size, dtype=bool)
        self.err = {n: np.full(self._size, np.nan) for n in self.names}
        self.two_sigma = {n: np.full(self._size, np.nan) for n in self.names}
        self.n = 0

    def clear(self) -> None:
        self.n = 0

    def record(self, scene) -> None:
        """Sample the scene after a tick."""
        t = float(scene.time)
        if self.n and t < self.t[self.n - 1]:
            self.clear()  # a seek back
        if self.n == self._size:  # keep the newest ``cap`` samples
            keep = slice(self.n - self.cap, self.n)
            for arr in (self.t, self.blind, *self.err.values(), *self.two_sigma.values()):
                arr[: self.cap] = arr[keep]
            self.n = self.cap
        k = self.n
        self.t[k] = t
        self.blind[k] = not scene.seen_ids()
        for name in self.names:
            st = scene.status.get(name)
            ok = st is not None and not st.failed
            self.err[name][k] = st.pos_err if ok else np.nan
            self.two_sigma[name][k] = 2.0 * st.pos_sigma if ok else np.nan
        self.n += 1

    def window(self) -> slice:
        """The samples within the last ``span`` seconds."""
        if not self.n:
            return slice(0, 0)
        t = self.t[: self.n]
        first = int(np.searchsorted(t, t[-1] - self.span, side="left"))
        return slice(first, self.n)

    def draw(self, surf: pygame.Surface, rect: pygame.Rect, fonts, colours, dashes,
             visible) -> None:
        """Draw into ``rect``: axes, blind shading, each visible filter's two lines."""
        surf.fill(palette.PANEL, rect)
        pygame.draw.line(surf, palette.PANEL_EDGE, rect.topleft, rect.topright, 3)
        small = fonts["small"]
        lh = small.get_linesize()
        title = small.render("position error (thin) and 2 sigma (thick) [m];  shaded: no beacon"
                             " in view;  C hides", True, palette.TEXT)
        surf.blit(title, (rect.left + 10, rect.top + 4))
        plot = pygame.Rect(rect.left + 64, rect.top + lh + 10, rect.width - 84,
                           rect.height - 2 * lh - 18)
        if plot.width < 40 or plot.height < 20:
            return
        pygame.draw.rect(surf, palette.BACKGROUND, plot)
        w = self.window()
        t = self.t[w]
        t1 = float(t[-1]) if len(t) else 0.0
        t0 = t1 - self.span

        def xs(tt):
            return plot.left + (np.asarray(tt) - t0) / self.span * plot.width

        blind = self.blind[w]
        if blind.any():
            edges = np.flatnonzero(np.diff(np.concatenate([[0], blind.astype(np.int8), [0]])))
            for a, b in zip(edges[::2], edges[1::2], strict=True):
                xa, xb = ipx(xs(t[a])), ipx(xs(t[min(b, len(t) - 1)]))
                surf.fill(BLIND_SHADE, pygame.Rect(xa, plot.top, max(xb - xa, 1), plot.height))
        shown = [n for n in self.names if visible.get(n, True)]
        top = 0.2
        for n in shown:
            for arr in (self.err[n][w], self.two_sigma[n][w]):
                finite = arr[np.isfinite(arr)]
                if len(finite):
                    top = max(top, float(np.max(finite)))
        top = nice_top(top * 1.08)

        def ys(v):
            return plot.bottom - np.asarray(v) / top * plot.height

        for frac in (0.0, 0.5, 1.0):
            y = ipx(plot.bottom - frac * plot.height)
            pygame.draw.line(surf, palette.GRID_MAJOR, (plot.left, y), (plot.right, y), 1)
            lab = small.render(f"{frac * top:g}", True, palette.TEXT_DIM)
            surf.blit(lab, (plot.left - lab.get_width() - 6, y - lab.get_height() // 2))
        for sec in range(0, int(self.span) + 1, 10):
            x = ipx(plot.left + sec / self.span * plot.width)
            pygame.draw.line(surf, palette.GRID_MINOR, (x, plot.top), (x, plot.bottom), 1)
            lab = small.render(f"{sec - self.span:g} s" if sec < self.span else "now", True,
                               palette.TEXT_DIM)
            surf.blit(lab, (min(x - lab.get_width() // 2, plot.right - lab.get_width()),
                            plot.bottom + 2))
        old = surf.get_clip()
        surf.set_clip(plot.inflate(0, 4))
        step = max(1, len(t) // max(plot.width, 1))  # about one sample per pixel
        for n in shown:
            for arr, width, dash in ((self.two_sigma[n][w], 4, dashes.get(n)),
                                     (self.err[n][w], 2, None)):
                ok = np.isfinite(arr[::step])
                if ok.sum() < 2:
                    continue
                pts = np.stack([xs(t[::step][ok]), ys(np.minimum(arr[::step][ok], top * 1.02))], 1)
                polyline(surf, colours[n], pts, width, dash)
        surf.set_clip(old)
        pygame.draw.rect(surf, palette.GRID_MAJOR, plot, 1)


def nice_top(v: float) -> float:
    """The next 1-2-5 step at or above ``v`` (the chart's y range)."""
    e = math.floor(math.log10(v))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**e >= v - 1e-12:
            return m * 10.0**e
    return 10.0 ** (e + 1)
