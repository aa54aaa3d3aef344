"""Notes drawn over the world: the step view's legend (prior dashed, posterior solid, the
beacons the update used), the switched-off filters with their colour, and the banner (kidnap,
bump, screenshot saved). Each keeps off what it must not cover and says where it went.
"""

from __future__ import annotations

import pygame

from beacon_sim.app import palette
from beacon_sim.app.text import TextPainter, wrap_text


def switched_off_lines(session, colours) -> list[tuple[str, tuple]]:
    """A line ``(text, colour)`` per switched-off filter of ``session``, for the note on the
    world: why, and whether R brings it back (a filter that was built; one that could not be
    built stays off)."""
    out = []
    run = getattr(session, "filters_run", None)
    for name in session.names:
        why = session.status[name].failed
        if not why:
            continue
        built = run is not None and run.track(name, 0).filter is not None
        out.append((f"{name} switched off: {why}" + ("  (R: back on)" if built else ""), colours[name]))
    return out


class WorldNotes(TextPainter):
    """The step legend, the switched-off note and the banner (``step_box``, ``off_box``,
    ``banner_box``: where each was last drawn)."""

    def step_legend(self, surf, area: pygame.Rect, session, steps: bool, bound: bool,
                    avoid=(), world: pygame.Rect | None = None) -> pygame.Rect:
        """What the step view and the bound show, in a box at the bottom left of the world's
        area, or at its top left (or at the right of either), where it covers none of the
        rectangles ``avoid`` (the axis labels), never the robot (``session.true_pose`` on the
        room ``world``, the view's bounds in pixels) and, if it can, not the room; raised
        above the labels it would cover. Returns the box."""
        lines = []
        if steps:
            used = sorted(session.used_ids()) if hasattr(session, "used_ids") else []
            lines.append(f"tick {session.tick_count} (t = {session.time:.2f} s):  dashed = after "
                         "predict (prior),  solid = after update (posterior)")
            lines.append(("update used beacons " + ", ".join(map(str, used)) + " (ringed)") if used
                         else "no reading on this tick: the update changed nothing")
        if bound:
            lines.append("dotted black around the robot: best achievable 95 % (PCRB)")
        font = self.fonts["small"]
        out: list[str] = []
        for line in lines:
            out += wrap_text(font, line, area.width - 40)
        lh = font.get_linesize()
        w, h = max(font.size(t)[0] for t in out) + 20, lh * len(out) + 10
        low = pygame.Rect(area.left + 8, area.bottom - 6 - h, w, h)
        high = pygame.Rect(area.left + 8, area.top + lh + 14, w, h)  # under "grid 2 m"
        robot = self._robot_px(session, world)
        best = None
        for order, b in enumerate((low, high, low.move(area.right - 8 - low.right, 0),
                                   high.move(area.right - 8 - high.right, 0))):
            hits_label = b.collidelist(list(avoid)) >= 0
            covered = [r for r in avoid if r.colliderect(b)]
            if covered:
                b = b.move(0, min(r.top for r in covered) - 4 - b.bottom)
            key = (robot is not None and b.colliderect(robot), not area.contains(b), order >= 2, hits_label,
                   world is not None and b.colliderect(world), order)  # the right: for the robot
            if best is None or key < best[0]:
                best = (key, b)
        assert best is not None
        box = best[1]
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.PANEL, 225))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 2)
        for k, t in enumerate(out):
            self._blit(surf, t, "small", palette.TEXT, (box.left + 10, box.top + 5 + k * lh))
        self.step_box = box
        return box

    @staticmethod
    def _robot_px(session, world: pygame.Rect | None) -> pygame.Rect | None:
        """The driven robot on the screen [px], with a margin: its true position placed on
        ``world`` (the room's bounds on the screen), None when either is unknown."""
        pose = getattr(session, "true_pose", None)
        if world is None or pose is None or world.width <= 0 or world.height <= 0:
            return None
        x0, y0, x1, y1 = session.scenario.world.bounds
        px = world.left + (float(pose[0]) - x0) / (x1 - x0) * world.width
        py = world.bottom - (float(pose[1]) - y0) / (y1 - y0) * world.height
        r = max(session.scenario.robot_radius / (x1 - x0) * world.width, 14.0) * 2.0
        return pygame.Rect(int(px - r), int(py - r), int(2 * r), int(2 * r))

    def switched_off(self, surf, area: pygame.Rect, lines: list[tuple[str, tuple]],
                     avoid=(), keep_clear=()) -> pygame.Rect | None:
        """Switched-off filters said on the world, not only in the panel: a box at the bottom
        right of the world's area (bottom left where it would cover ``keep_clear``, the
        magnifier), a line per filter ``(text, colour)`` with a swatch of the
        filter's colour, raised above the axis labels (``avoid``) it would cover. Returns the
        box (None: no line)."""
        if not lines:
            return None
        font = self.fonts["small"]
        lh = font.get_linesize()
        sw = lh - 6  # the colour swatch [px]
        rows: list[tuple[str, tuple | None]] = []
        for text, colour in lines:
            for k, t in enumerate(wrap_text(font, text, area.width - 60 - sw)):
                rows.append((t, colour if k == 0 else None))
        w = max(font.size(t)[0] for t, _ in rows) + sw + 28
        h = lh * len(rows) + 10
        box = pygame.Rect(area.right - 8 - w, area.bottom - 6 - h, w, h)
        if box.collidelist(list(keep_clear)) >= 0:  # the magnifier there: the bottom left
            box.left = area.left + 8
        covered = [r for r in avoid if r.colliderect(box)]
        if covered:
            box.bottom = min(r.top for r in covered) - 4
        surf.fill(palette.PANEL, box)
        pygame.draw.rect(surf, palette.WARN, box, 3)
        for k, (t, swatch) in enumerate(rows):
            y = box.top + 5 + k * lh
            if swatch is not None:
                surf.fill(swatch, pygame.Rect(box.left + 10, y + 3, sw, sw))
            self._blit(surf, t, "small", palette.TEXT, (box.left + 18 + sw, y))
        self.off_box = box
        return box

    def banner(self, surf, area: pygame.Rect, text: str, avoid: pygame.Rect | None = None,
               keep_clear=()) -> None:
        """A large message across the top of the world view (kidnap, screenshot saved), or
        across its bottom when at the top it would cover ``avoid`` (the robot), else just
        under or over the robot. (Just under the robot it hid the beacons the robot was
        reading.) Of those places and those just under or over each of ``keep_clear`` (what
        is drawn over the world: the magnifier, the step view's legend, the switched-off
        note), the first that covers none of them, if there is one; never the robot where
        another place does not."""
        font = "banner" if self.fonts["banner"].size(text)[0] <= area.width - 60 else "hud"
        lines = wrap_text(self.fonts[font], text, area.width - 60)[:4]
        imgs = [self.fonts[font].render(line, True, palette.BANNER_TEXT) for line in lines]
        if not imgs:
            return
        lh = self.fonts[font].get_linesize()
        r = pygame.Rect(0, 0, max(i.get_width() for i in imgs), lh * len(imgs))
        clear = [pygame.Rect(k) for k in keep_clear]
        others = ([pygame.Rect(avoid)] if avoid is not None else []) + clear
        spots = [r.copy() for _ in range(2 + 2 * len(others))]
        spots[0].midtop = (area.centerx, area.top + 14)
        spots[1].midbottom = (area.centerx, area.bottom - 14)
        for k, other in enumerate(others):  # just under it, just over it
            spots[2 + 2 * k].midtop = (area.centerx, other.bottom + 16)
            spots[3 + 2 * k].midbottom = (area.centerx, other.top - 16)

        def cost(k: int) -> tuple:
            b = spots[k].inflate(36, 16)
            return (avoid is not None and b.colliderect(avoid), not area.contains(b),
                    b.collidelist(clear) >= 0, k)

        r = spots[min(range(len(spots)), key=cost)]
        box = r.inflate(36, 16)
        self.banner_box = box
        pygame.draw.rect(surf, palette.BANNER_BG, box, border_radius=10)
        pygame.draw.rect(surf, palette.TEXT, box, 3, border_radius=10)
        for k, img in enumerate(imgs):
            surf.blit(img, img.get_rect(midtop=(r.centerx, r.top + k * lh)))
