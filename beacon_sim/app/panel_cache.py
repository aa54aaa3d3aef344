"""The side panel's picture kept between frames (:class:`KeptPanel`).

The panel is first written as a list of drawing operations (:class:`PanelOps`: fills, text
images, lines, rectangles, clips, in order); only when that list differs from the last
frame's is it drawn for real, into a kept surface of the panel's size; every frame blits the
kept picture. Text images come from ``text.TextPainter``'s cache, so the same words are the
same image: a panel that says the same is the same list. What changes every frame whatever
the state (the FPS figure) is written apart (:meth:`PanelOps.volatile`) and drawn over the
kept picture, as is what reaches outside the panel (its left edge, over the world's last
column); the pixels are those of drawing the list straight onto the screen.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pygame


class PanelOps:
    """A stand-in for the screen that records what is drawn on it, inside ``rect`` [px]."""

    def __init__(self, rect: pygame.Rect):
        self.rect = pygame.Rect(rect)
        self.ops: list[tuple] = []  # what the kept picture is drawn from (and its key)
        self.boxes: list[pygame.Rect | None] = []  # the pixels each one may touch (clips: None)
        self.apart: list[tuple] = []  # (clip, op, box): drawn over the picture every frame
        self._clip: tuple | None = None  # None: the whole surface
        self._volatile = False

    def get_clip(self) -> tuple | None:
        return self._clip

    def set_clip(self, rect) -> None:
        self._clip = None if rect is None else tuple(pygame.Rect(rect))
        self.ops.append(("clip", self._clip))
        self.boxes.append(None)

    def fill(self, colour, rect=None) -> None:
        self._add(("fill", tuple(colour), None if rect is None else tuple(pygame.Rect(rect))), rect)

    def blit(self, img: pygame.Surface, at) -> None:
        pos = (int(at[0]), int(at[1]))
        self._add(("blit", img, pos), img.get_rect(topleft=pos))

    def line(self, colour, a, b, width: int) -> None:
        x0, y0, x1, y1 = int(a[0]), int(a[1]), int(b[0]), int(b[1])
        box = pygame.Rect(min(x0, x1) - width, min(y0, y1) - width, abs(x1 - x0) + 2 * width + 1,
                          abs(y1 - y0) + 2 * width + 1)
        self._add(("line", tuple(colour), (x0, y0), (x1, y1), width), box)

    def outline(self, colour, rect, width: int) -> None:
        r = pygame.Rect(rect)
        self._add(("rect", tuple(colour), tuple(r), width), r.inflate(2 * width, 2 * width))

    @contextmanager
    def volatile(self) -> Iterator[None]:
        """What is drawn inside this block changes every frame: drawn apart, not kept."""
        self._volatile = True
        try:
            yield
        finally:
            self._volatile = False

    def _add(self, op: tuple, box) -> None:
        box = self.rect if box is None else pygame.Rect(box)
        if self._volatile:
            self.apart.append((self._clip, op, box))
            return
        self.ops.append(op)
        self.boxes.append(box)
        if not self.rect.contains(box):  # reaches outside the panel
            self.apart.append((self._clip, op, box))


def draw_line(surf, colour, a, b, width: int) -> None:
    """``pygame.draw.line`` on a surface, or recorded on :class:`PanelOps`."""
    if isinstance(surf, PanelOps):
        surf.line(colour, a, b, width)
    else:
        pygame.draw.line(surf, colour, a, b, width)


def draw_outline(surf, colour, rect, width: int) -> None:
    """``pygame.draw.rect`` (an outline ``width`` px wide) on a surface, or recorded."""
    if isinstance(surf, PanelOps):
        surf.outline(colour, rect, width)
    else:
        pygame.draw.rect(surf, colour, rect, width)


@contextmanager
def volatile(surf) -> Iterator[None]:
    """:meth:`PanelOps.volatile` on a recorder; nothing on a real surface."""
    if isinstance(surf, PanelOps):
        with surf.volatile():
            yield
    else:
        yield


def replay(ops, surf: pygame.Surface, dx: int, dy: int) -> None:
    """Draw the recorded ``ops`` onto ``surf``, moved by (dx, dy) [px]."""
    for op in ops:
        kind = op[0]
        if kind == "blit":
            surf.blit(op[1], (op[2][0] + dx, op[2][1] + dy))
        elif kind == "fill":
            surf.fill(op[1], None if op[2] is None else pygame.Rect(op[2]).move(dx, dy))
        elif kind == "line":
            pygame.draw.line(surf, op[1], (op[2][0] + dx, op[2][1] + dy),
                             (op[3][0] + dx, op[3][1] + dy), op[4])
        elif kind == "rect":
            pygame.draw.rect(surf, op[1], pygame.Rect(op[2]).move(dx, dy), op[3])
        else:  # clip
            surf.set_clip(None if op[1] is None else pygame.Rect(op[1]).move(dx, dy))


class KeptPanel:
    """The panel's kept picture and the list it was drawn from.

    When the list changes only in some operations (a figure, the clock), only the parts of
    the picture those cover (before and after) are drawn again: every operation that
    touches them, in order, clipped to them. ``redraws`` counts the pictures drawn whole,
    ``partial`` those drawn in part, ``blits`` the times the picture was put on the screen
    whole.

    ``intact``: the window sets it False after a frame that drew over the panel (the help,
    a replay's timeline), and True after one that did not; while the screen still shows the
    kept picture, only its parts drawn again and what is drawn apart are put on the screen
    (the parts under the latter restored from the picture first)."""

    def __init__(self) -> None:
        self.ops: list[tuple] | None = None  # what the picture was drawn from
        self.boxes: list[pygame.Rect | None] = []  # each operation's pixels [px]
        self.head: tuple | None = None  # the panel's rectangle, the surface's size and depth
        self.picture: pygame.Surface | None = None
        self.redraws = self.partial = self.blits = 0
        self.intact = False
        self._shown: tuple | None = None  # (surface, head) the screen shows the picture on
        self._apart_boxes: list[pygame.Rect] = []  # what was drawn apart on it [px]

    def show(self, surf: pygame.Surface, rect: pygame.Rect, draw: Callable[[object], None]) -> None:
        """The panel that ``draw(target)`` draws, onto ``surf`` in ``rect`` [px]: recorded,
        drawn into the kept picture where it changed, put on the screen. A surface clipped
        to less than itself is drawn on straight (the recorder's clips start from the whole
        surface)."""
        rect = pygame.Rect(rect)
        if surf.get_clip() != surf.get_rect() or not surf.get_rect().contains(rect):
            draw(surf)
            return
        rec = PanelOps(rect)
        draw(rec)
        head = (tuple(rect), surf.get_size(), surf.get_bitsize())
        pic = self.picture
        dirty: list[pygame.Rect] = []  # the picture's parts drawn again
        whole = pic is None or head != self.head or self.ops is None or len(self.ops) != len(rec.ops)
        if not whole and self.ops != rec.ops:
            for old, new, a, b in zip(self.ops or (), rec.ops, self.boxes, rec.boxes, strict=True):
                if old != new:
                    if a is None or b is None:  # a clip changed: all of it
                        whole = True
                        break
                    dirty.append(a.union(b).clip(rect))
        if pic is None or pic.get_size() != rect.size or pic.get_bitsize() != surf.get_bitsize():
            pic = self.picture = pygame.Surface(rect.size, 0, surf)
            whole = True
        if whole:
            replay(rec.ops, pic, -rect.x, -rect.y)
            pic.set_clip(None)
            self.redraws += 1
        elif dirty:
            dirty = [_redraw(rec.ops, rec.boxes, pic, part, rect) for part in dirty]
            self.partial += 1
        self.ops, self.boxes, self.head = rec.ops, rec.boxes, head
        if self.intact and self._shown == (surf, head) and not whole:
            # the screen shows the picture: put on it what changed and what is drawn apart
            for box in dirty + self._apart_boxes + [b for _, _, b in rec.apart]:
                part = box.clip(rect)
                if part.width and part.height:
                    surf.blit(pic, part, part.move(-rect.x, -rect.y))
        else:
            surf.blit(pic, rect)
            self.blits += 1
        for clip, op, _ in rec.apart:
            surf.set_clip(None if clip is None else pygame.Rect(clip))
            replay((op,), surf, 0, 0)
        surf.set_clip(None)
        self._shown = (surf, head)
        self._apart_boxes = [b for _, _, b in rec.apart]
        self.intact = False  # until the window says that nothing was drawn over it


def _redraw(ops, boxes, pic: pygame.Surface, part: pygame.Rect, rect: pygame.Rect) -> pygame.Rect:
    """The operations that touch ``part`` (screen px) drawn again onto the picture ``pic`` of
    ``rect``, in order, clipped to ``part`` (and to the clips the operations were drawn in);
    returns the part drawn. An outline rectangle is never cut (``pygame.draw.rect`` outlines
    the rectangle left inside the clip): the part grows to hold it."""
    if not (part.width and part.height):
        return part
    grown = None
    while grown != part:
        grown = part
        for op, box in zip(ops, boxes, strict=True):
            if op[0] == "rect" and box.colliderect(part) and not part.contains(box):
                part = part.union(box)
    clip: tuple | None = None
    for op, box in zip(ops, boxes, strict=True):
        if op[0] == "clip":
            clip = op[1]
            continue
        if not box.colliderect(part):
            continue
        area = part if clip is None else part.clip(pygame.Rect(clip))
        if area.width and area.height:
            pic.set_clip(area.move(-rect.x, -rect.y))
            replay((op,), pic, -rect.x, -rect.y)
    pic.set_clip(None)
    return part


__all__ = ["KeptPanel", "PanelOps", "draw_line", "draw_outline", "replay", "volatile"]
