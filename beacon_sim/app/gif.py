"""An animated GIF of the window, small enough to paste into a slide (``play --gif``,
``replay --gif``).

Every ``every``-th window frame is scaled down to ``width`` pixels wide, mapped onto one
palette (the first captured frame's colours plus every colour the window draws with, so
the colours do not flicker between frames) and kept zlib-compressed in memory until
:meth:`GifRecorder.save`. Pillow (the ``gif`` extra) writes the file; it stores only the
part of each frame that changed, and merges a frame identical to the previous one into it
(a paused stretch costs nothing).

At the window's 60 frames per second, ``every = 6`` gives 10 GIF frames per second of the
window's time, played back in real time (100 ms each). 10 s at 640 px wide is typically a
few hundred KB.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import pygame

from beacon_sim.app import palette
from beacon_sim.core.files import atomic_write
from beacon_sim.core.optional import install_hint

#: Default: one GIF frame every 6 window frames (10 per second at 60 FPS).
EVERY = 6
#: Default width of the GIF [px]; the height keeps the window's aspect ratio.
WIDTH = 640
#: Stop capturing after this many GIF frames (10 minutes at 10 per second).
MAX_FRAMES = 6000
#: Palette index kept free for "unchanged since the previous frame".
TRANSPARENT = 255
INSTALL_HINT = install_hint("PIL", "--gif")


def pillow_available() -> bool:
    try:
        import PIL  # noqa: F401
    except ImportError:
        return False
    return True


def _known_colours() -> list[tuple[int, int, int]]:
    """Every colour the window draws with (and the pale shades of the filter colours), so
    that a colour that appears only later (a banner, a heat map) keeps its hue."""
    from beacon_sim.runs.styles import KIND_STYLES, OTHER_STYLES

    out = [v for v in vars(palette).values()
           if isinstance(v, tuple) and len(v) == 3 and all(isinstance(c, int) for c in v)]
    for colour, _ in (*KIND_STYLES.values(), *OTHER_STYLES):
        out += [colour, *(palette.lighten(colour, a) for a in (0.3, 0.6, 0.8))]
    return out


class GifRecorder:
    """Captures window frames and writes them as an animated GIF.

    Parameters
    ----------
    path : str or Path
        The ``.gif`` file to write.
    every : int
        Capture one window frame in ``every``.
    width : int
        GIF width [px] (frames are scaled down, never up).
    frame_s : float
        Wall (or scripted) time of one window frame [s]; a GIF frame lasts ``every * frame_s``.
    """

    def __init__(self, path: str | Path, every: int = EVERY, width: int = WIDTH,
                 frame_s: float = 1.0 / 60.0):
        self.path = Path(path)
        self.every = max(int(every), 1)
        self.width = int(width)
        self.duration_ms = max(round(1000.0 * self.every * frame_s), 20)
        self.frames: list[bytes] = []  # zlib-compressed palette indices, one per GIF frame
        self.size: tuple[int, int] | None = None
        self._palette = None  # a PIL "P" image holding the shared palette
        self._seen = 0
        self.full = False

    def offer(self, surf: pygame.Surface) -> None:
        """Called once per window frame (after drawing); keeps every ``every``-th."""
        k, self._seen = self._seen, self._seen + 1
        if k % self.every == 0:
            self.capture(surf)

    def capture(self, surf: pygame.Surface) -> None:
        """Keep ``surf`` as the next GIF frame (scaled down and palette-mapped)."""
        from PIL import Image

        if len(self.frames) >= MAX_FRAMES:
            self.full = True
            return
        w, h = surf.get_size()
        if self.size is None:
            tw = min(self.width, w)
            self.size = (tw, max(round(h * tw / w), 1))
        small = surf if (w, h) == self.size else pygame.transform.smoothscale(surf, self.size)
        img = Image.frombytes("RGB", self.size, pygame.image.tobytes(small, "RGB"))
        if self._palette is None:
            self._palette = self._make_palette(img)
        q = img.quantize(palette=self._palette, dither=Image.Dither.NONE)
        self.frames.append(zlib.compress(q.tobytes(), 1))

    @staticmethod
    def _make_palette(img):
        """255 colours: the window's own colours, then the first frame's most common ones;
        index ``TRANSPARENT`` stays free (unchanged pixels of later frames)."""
        from PIL import Image

        known = list(dict.fromkeys(_known_colours()))[:128]
        adaptive = img.quantize(colors=TRANSPARENT - len(known), method=Image.Quantize.MEDIANCUT)
        rest = adaptive.getpalette()[: 3 * (TRANSPARENT - len(known))]
        flat = [c for rgb in known for c in rgb] + rest
        flat += [0] * (768 - len(flat))
        pal = Image.new("P", (1, 1))
        pal.putpalette(flat)
        return pal

    def save(self) -> int:
        """Write the GIF (looping); returns the number of frames captured. Writes nothing
        when no frame was captured."""
        from PIL import Image

        if not self.frames or self.size is None or self._palette is None:
            return 0
        pal = self._palette.getpalette()
        images = []
        for data in self.frames:
            im = Image.frombytes("P", self.size, zlib.decompress(data))
            im.putpalette(pal)
            images.append(im)
        if self.path.parent and not self.path.parent.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
        # optimize: each frame keeps only the box that changed, unchanged pixels in it
        # transparent (long runs of one index: LZW packs them into little).
        with atomic_write(self.path, "wb", what="GIF") as fh:  # the previous file stays on an error
            images[0].save(fh, format="GIF", save_all=True, append_images=images[1:], loop=0,
                           duration=self.duration_ms, optimize=True, disposal=1,
                           transparency=TRANSPARENT)
        return len(images)


__all__ = ["EVERY", "INSTALL_HINT", "WIDTH", "GifRecorder", "pillow_available"]
