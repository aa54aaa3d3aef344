"""What the window writes over and beside the world, put together in ``Hud``: the side panel
(``panel``), a team's legend (``team_legend``), the notes over the world (``world_notes``:
step legend, switched-off filters, banner) and the help overlay (``help_overlay``), all on
``text.TextPainter``."""

from __future__ import annotations

import pygame

from beacon_sim.app.help_overlay import HelpOverlay
from beacon_sim.app.in_view import ids_text
from beacon_sim.app.panel import INSIDE_BOUND, Panel, inside_the_bound
from beacon_sim.app.team_legend import TeamLegend
from beacon_sim.app.text import wrap_text
from beacon_sim.app.world_notes import WorldNotes


class Hud(Panel, TeamLegend, WorldNotes, HelpOverlay):
    """Draws the panel, banner and help; remembers the help lines it drew (for tests)."""

    def __init__(self, fonts: dict[str, pygame.font.Font], mode: str = "play"):
        super().__init__(fonts)
        self.mode = mode


# The names the panel's callers imported from here before it was split.
__all__ = ["INSIDE_BOUND", "Hud", "ids_text", "inside_the_bound", "wrap_text"]
