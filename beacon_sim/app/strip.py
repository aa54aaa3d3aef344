"""The strip chart (C key): for each filter, its position error [m] (thin line) and its
2-sigma [m] (thick, in the filter's line style) over the last ``span`` seconds of simulated
time, with the stretches when no beacon was in view shaded. A class sees 2-sigma climb in
the blind stretch and drop when beacons come back, and whether the error stays under it.

History is sampled from the scene after each tick (``record``), so it works for a live
session, a replay or an MRCLAM playback alike; going back in time (a seek) clears it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.strokes import polyline
from beacon_sim.app.view import ipx
from beacon_sim.runs.styles import filter_kind

#: The filter kind that does not set the chart's scale (see :meth:`StripChart.y_range`).
DEAD_RECKONING_KIND = "dead_reckoning"

#: Seconds of history shown.
SPAN_S = 60.0
#: The chart is rendered again at most this often [s of the window's clock] ...
REDRAW_S = 0.1
#: ... and on a frame that also runs simulation ticks only once it is this old [s].
STALE_S = 0.25
BLIND_SHADE = (255, 226, 204)  # a pale vermillion: "no beacon in view"


@dataclass
class _Rendered:
    """The chart as last rendered off screen: what it showed (``key``), the samples'
    ``version``, the image, and the window's clock ``at`` [s] when it was rendered."""

    key: tuple
    version: int
    image: pygame.Surface
    at: float


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
        self.version = 0  # bumped by every change of the data (the render cache's key)
        self._cache: _Rendered | None = None
        self._static_cache: tuple | None = None

    def clear(self) -> None:
        self.n = 0
        self.version += 1

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
        self.version += 1

    def y_range(self, shown) -> float:
        """The largest error or 2-sigma [m] (at least 0.2) of the filters that set the scale:
        the shown ones except dead reckoning (its error grows without bound and would flatten
        every other line; its line is cut at the top), unless it is all that is shown."""
        scaled = [n for n in shown if filter_kind(n) != DEAD_RECKONING_KIND] or list(shown)
        w = self.window()
        top = 0.2
        for n in scaled:
            for arr in (self.err[n][w], self.two_sigma[n][w]):
                finite = arr[np.isfinite(arr)]
                if len(finite):
                    top = max(top, float(np.max(finite)))
        return top

    def window(self) -> slice:
        """The samples within the last ``span`` seconds."""
        if not self.n:
            return slice(0, 0)
        t = self.t[: self.n]
        first = int(np.searchsorted(t, t[-1] - self.span, side="left"))
        return slice(first, self.n)

    def draw(self, surf: pygame.Surface, rect: pygame.Rect, fonts, colours, dashes,
             visible, now: float | None = None, busy: bool = False) -> None:
        """Blit the chart into ``rect``, re-rendering it only when it is stale.

        The chart is rendered off screen (:meth:`render`) and blitted; it is rendered again
        when new samples arrived, at most every ``REDRAW_S`` seconds of the window's clock
        ``now`` [s], and preferably on a frame without simulation ticks (``busy`` False),
        so that its cost does not land on the frames that also run the filters (a ``busy``
        frame re-renders only once the picture is ``STALE_S`` old). A change of size,
        fonts, colours or shown filters re-renders at once. ``now`` None: every call."""
        shown = tuple(n for n in self.names if visible.get(n, True))
        key = (tuple(rect), id(fonts), shown, tuple(sorted(colours.items())),
               tuple(sorted((k, v) for k, v in dashes.items() if k in shown)))
        c = self._cache
        fresh = c is not None and c.key == key
        if c is not None and fresh and c.version != self.version and now is not None:
            age = now - c.at
            fresh = age < REDRAW_S or (busy and age < STALE_S)
        elif fresh and c is not None and c.version != self.version:
            fresh = False
        if c is None or not fresh:
            image = c.image if c is not None and c.image.get_size() == rect.size else \
                pygame.Surface(rect.size)
            self.render(image, fonts, colours, dashes, shown)
            c = self._cache = _Rendered(key, self.version, image, now if now is not None else 0.0)
        surf.blit(c.image, rect)

    def _static(self, size: tuple[int, int], fonts, top: float) -> tuple[pygame.Surface, pygame.Rect]:
        """The chart without data (title, axes, grid, labels) for a y range ``top`` [m],
        rendered once per size, fonts and range; and the plot's rectangle in it."""
        key = (size, id(fonts), top)
        if self._static_cache is not None and self._static_cache[0] == key:
            return self._static_cache[1], self._static_cache[2]
        w, h = size
        layer = pygame.Surface(size)
        layer.fill(palette.PANEL)
        pygame.draw.line(layer, palette.PANEL_EDGE, (0, 0), (w, 0), 3)
        small = fonts["small"]
        lh = small.get_linesize()
        title = small.render("position error (thin) and 2 sigma (thick) [m];  shaded: no beacon"
                             " in view;  C hides", True, palette.TEXT)
        layer.blit(title, (10, 4))
        lab_w = small.size("0.05")[0] + 14
        plot = pygame.Rect(lab_w, lh + 10, w - lab_w - 20, h - 2 * lh - 18)
        if plot.width >= 40 and plot.height >= 20:
            pygame.draw.rect(layer, palette.BACKGROUND, plot)
            for frac in (0.0, 0.5, 1.0):
                y = ipx(plot.bottom - frac * plot.height)
                pygame.draw.line(layer, palette.GRID_MAJOR, (plot.left, y), (plot.right, y), 1)
                lab = small.render(f"{frac * top:g}", True, palette.TEXT_DIM)
                layer.blit(lab, (plot.left - lab.get_width() - 6, y - lab.get_height() // 2))
            for sec in range(0, int(self.span) + 1, 10):
                x = ipx(plot.left + sec / self.span * plot.width)
                pygame.draw.line(layer, palette.GRID_MINOR, (x, plot.top), (x, plot.bottom), 1)
                lab = small.render(f"{sec - self.span:g} s" if sec < self.span else "now", True,
                                   palette.TEXT_DIM)
                layer.blit(lab, (min(x - lab.get_width() // 2, plot.right - lab.get_width()),
                                 plot.bottom + 2))
        self._static_cache = (key, layer, plot)
        return layer, plot

    def render(self, image: pygame.Surface, fonts, colours, dashes, shown) -> None:
        """Draw the whole chart into ``image`` (its own coordinates): the static layer, the
        blind shading, and each shown filter's two lines, about one point per 3 px."""
        w = self.window()
        t = self.t[w]
        top = nice_top(self.y_range(shown) * 1.08)
        layer, plot = self._static(image.get_size(), fonts, top)
        image.blit(layer, (0, 0))
        if plot.width < 40 or plot.height < 20 or not len(t):
            return
        t1 = float(t[-1])
        t0 = t1 - self.span

        def xs(tt):
            return plot.left + (np.asarray(tt) - t0) / self.span * plot.width

        blind = self.blind[w]
        if blind.any():
            edges = np.flatnonzero(np.diff(np.concatenate([[0], blind.astype(np.int8), [0]])))
            for a, b in zip(edges[::2], edges[1::2], strict=True):
                xa, xb = ipx(xs(t[a])), ipx(xs(t[min(b, len(t) - 1)]))
                image.fill(BLIND_SHADE, pygame.Rect(xa, plot.top, max(xb - xa, 1), plot.height))
            for frac in (0.0, 0.5, 1.0):  # the grid lines over the shading
                y = ipx(plot.bottom - frac * plot.height)
                pygame.draw.line(image, palette.GRID_MAJOR, (plot.left, y), (plot.right, y), 1)
        image.set_clip(plot.inflate(0, 4))
        step = max(1, math.ceil(len(t) / max(plot.width / 3, 1)))  # ~one point per 3 px
        tx = xs(t[::step])
        for n in shown:
            for arr, width, dash in ((self.two_sigma[n][w], 4, dashes.get(n)),
                                     (self.err[n][w], 2, None)):
                v = arr[::step]
                ok = np.isfinite(v)
                if ok.sum() < 2:
                    continue
                pts = np.stack([tx[ok], plot.bottom - np.minimum(v[ok], top * 1.02) / top * plot.height], 1)
                polyline(image, colours[n], pts, width, dash)
        image.set_clip(None)
        pygame.draw.rect(image, palette.GRID_MAJOR, plot, 1)


def nice_top(v: float) -> float:
    """The next 1-2-5 step at or above ``v`` (the chart's y range)."""
    e = math.floor(math.log10(v))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**e >= v - 1e-12:
            return m * 10.0**e
    return 10.0 ** (e + 1)
