"""A particle filter's belief in the world: each particle as a small block of pixels written
straight into the surface, in the filter's colour (paler for the light ones).
"""

from __future__ import annotations

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.view import View


class ParticleLayer(Canvas):
    """Particle clouds (no state of their own)."""

    def particles(self, surf: pygame.Surface, view: View, poses: np.ndarray, colour,
                  weights: np.ndarray | None = None) -> None:
        """Each particle as a 3x3 pixel block (2x2 above 20,000 particles), written through a
        pixel array (no draw calls), in the filter's colour darkened to a contrast of 4.5:1
        against the floor (``palette.particle_colours``).

        With ``weights``, particles below half the mean weight (1 / 2N) are drawn in a
        lighter shade (still 3:1) first, so that the ones carrying the belief stand out.
        """
        clip = surf.get_clip()
        poses = np.asarray(poses)
        ax, ay, w, h = view.area
        s = view.scale
        # Pixel coordinates as float32 (to_px in float64 costs more at 100k particles).
        fx = (poses[:, 0] - view.centre[0]).astype(np.float32) * np.float32(s) + np.float32(ax + w / 2)
        fy = (poses[:, 1] - view.centre[1]).astype(np.float32) * np.float32(-s) + np.float32(ay + h / 2)
        ix = fx.astype(np.int32)
        iy = fy.astype(np.int32)
        ok = (ix >= clip.left) & (ix < clip.right - 1) & (iy >= clip.top) & (iy < clip.bottom - 1)
        heavy, pale = palette.particle_colours(colour)  # >= 4.5:1 and 3:1 against the floor
        layers = [(ok, heavy)]
        if weights is not None and len(weights) == len(poses):
            light = np.asarray(weights) < 0.5 / max(len(poses), 1)
            if light.any():
                layers = [(ok & light, pale), (ok & ~light, heavy)]
        # Blocks of 3x3 px up to 20,000 particles (visible on a projector), 2x2 above.
        big = len(poses) <= 20_000
        if big:
            ok &= (ix < clip.right - 2) & (iy < clip.bottom - 2)
            layers = [(m & ok, c) for m, c in layers]
        offsets = [(0, 0), (1, 0), (0, 1), (1, 1)]
        if big:
            offsets += [(2, 0), (2, 1), (0, 2), (1, 2), (2, 2)]
        arr = pygame.surfarray.pixels2d(surf)
        try:
            rows = arr.T  # (height, width): C-ordered when the pitch is 4 px a pixel
            if rows.flags.c_contiguous:  # one index per particle, a constant per offset
                flat, width = rows.reshape(-1), rows.shape[1]
                every = iy.astype(np.intp) * width + ix  # then one masked pick per layer
                for mask, col in layers:
                    at = every[mask]
                    value = surf.map_rgb(col)
                    for dx, dy in offsets:
                        flat[at + (dy * width + dx)] = value
            else:
                for mask, col in layers:
                    x, y = ix[mask], iy[mask]
                    value = surf.map_rgb(col)
                    for dx, dy in offsets:
                        arr[x + dx, y + dy] = value
        finally:
            del arr
