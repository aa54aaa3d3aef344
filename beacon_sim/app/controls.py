"""The ONE table of key and mouse bindings: the event handler and the help overlay both
read it, so the help can never disagree with what the keys do.

``actions_for_event(event)`` turns a pygame event into action names; the window decides
what each action does. Driving keys (W/S/A/D) repeat while held; the others fire once per
press.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import pygame


@dataclass(frozen=True)
class Binding:
    """One line of the help: ``keys`` as shown, the pygame key codes, the action, a text.

    ``action`` names ending in ``*`` take the filter number from the key (1-9).
    Mouse bindings have no key codes; the handler matches them by action name.
    """

    keys: str
    codes: tuple[int, ...]
    action: str
    description: str
    repeat: bool = False
    group: str = "Drive"
    button: int = 0  # mouse button (1 left, 3 right, 4 wheel) for mouse bindings


def _k(*names: str) -> tuple[int, ...]:
    return tuple(getattr(pygame, n) for n in names)


FILTER_KEYS = _k("K_1", "K_2", "K_3", "K_4", "K_5", "K_6", "K_7", "K_8", "K_9")

BINDINGS: tuple[Binding, ...] = (
    Binding("W / Up", _k("K_w", "K_UP"), "faster", "speed v up one step (held: repeats)", True),
    Binding("S / Down", _k("K_s", "K_DOWN"), "slower", "speed v down one step / reverse", True),
    Binding("A / Left", _k("K_a", "K_LEFT"), "left", "steer left (omega up one step)", True),
    Binding("D / Right", _k("K_d", "K_RIGHT"), "right", "steer right (omega down one step)", True),
    Binding("X", _k("K_x"), "stop", "stop: v = omega = 0"),
    Binding("M", _k("K_m"), "autopilot",
            "autopilot: the scenario's driver on / off (a driving key takes over)"),
    Binding("Space", _k("K_SPACE"), "pause", "pause / run", group="Time"),
    Binding(".", _k("K_PERIOD"), "step", "one tick while paused", group="Time"),
    Binding("+", _k("K_PLUS", "K_EQUALS", "K_KP_PLUS"), "speed_up",
            "faster simulation (up to x8)", group="Time"),
    Binding("-", _k("K_MINUS", "K_KP_MINUS"), "speed_down", "slower simulation (down to x0.1)",
            group="Time"),
    Binding("K", _k("K_k"), "kidnap_random", "kidnap the robot to a random pose", group="World"),
    Binding("Left click", (), "kidnap_click", "kidnap to that point (drag: heading)",
            group="World", button=1),
    Binding("R", _k("K_r"), "reset", "filters back to the initial belief (clears trails)",
            group="Filters"),
    Binding("G", _k("K_g"), "global_reset", "global (uniform) belief where possible",
            group="Filters"),
    Binding("1-9", FILTER_KEYS, "toggle*", "show / hide filter 1-9", group="Filters"),
    Binding("P", _k("K_p"), "particles", "particles on / off", group="Show"),
    Binding("T", _k("K_t"), "trails", "trails on / off", group="Show"),
    Binding("Backspace / Delete", _k("K_BACKSPACE", "K_DELETE"), "clear_trails", "clear the trails",
            group="Show"),
    Binding("E", _k("K_e"), "ellipses", "95 % ellipses and heading wedges on / off",
            group="Show"),
    Binding("C", _k("K_c"), "chart", "strip chart: error and 2 sigma over the last 60 s",
            group="Show"),
    Binding("V", _k("K_v"), "step_view",
            "while paused: last tick's prior (dashed) and posterior (solid) on / off", group="Show"),
    Binding("B", _k("K_b"), "bound", "best achievable 95 % ellipse (PCRB, dotted) on / off",
            group="Show"),
    Binding("L", _k("K_l"), "field",
            "map worlds: the likelihood field (distance to the nearest wall) on / off",
            group="Show"),
    Binding("O", _k("K_o"), "hdop",
            "distance beacons: the floor shaded by the beacons' HDOP, with its key, on / off",
            group="Show"),
    Binding("Wheel", (), "zoom", "zoom at the mouse", group="View", button=4),
    Binding("Right drag", (), "pan", "pan the view", group="View", button=3),
    Binding("F", _k("K_f"), "fit", "fit the world to the window", group="View"),
    Binding("F12", _k("K_F12"), "screenshot", "save a screenshot (PNG)", group="View"),
    Binding("H / F1", _k("K_h", "K_F1"), "help", "help: every key, on / off", group="View"),
    Binding("F11", _k("K_F11"), "fullscreen", "fullscreen on / off", group="View"),
    Binding("Esc / Q", _k("K_ESCAPE", "K_q"), "quit", "quit (press twice: asks first)",
            group="View"),
)

#: Replaying a recording: the run is fixed, so driving, kidnaps and resets are gone; the
#: arrows and the timeline seek. The display keys are the same objects as in ``BINDINGS``.
_REPLAY_ONLY: tuple[Binding, ...] = (
    Binding("Left", _k("K_LEFT"), "seek_back", "seek 5 s back (re-simulates)",
            True, group="Timeline"),
    Binding("Right", _k("K_RIGHT"), "seek_forward", "seek 5 s forward", True, group="Timeline"),
    Binding("Home", _k("K_HOME"), "seek_start", "back to the start", group="Timeline"),
    Binding("Click timeline", (), "seek_click", "seek there (drag: scrub)", group="Timeline",
            button=1),
)
_NOT_IN_REPLAY = {"faster", "slower", "left", "right", "stop", "autopilot", "kidnap_random",
                  "kidnap_click", "reset", "global_reset"}
REPLAY_BINDINGS: tuple[Binding, ...] = tuple(
    b for b in BINDINGS if b.group == "Time") + _REPLAY_ONLY + tuple(
    b for b in BINDINGS if b.group != "Time" and b.action not in _NOT_IN_REPLAY)

#: A team scenario: the play keys act on the driven robot, Tab switches which;
#: the keys of single-robot features a team window does not have (uniform belief, particles,
#: strip chart, step view, PCRB) are left out.
_NEXT_ROBOT = Binding("Tab", _k("K_TAB"), "next_robot",
                      "drive the next robot (the others follow their drivers)")
_NOT_IN_TEAM = {"global_reset", "particles", "chart", "step_view", "bound"}
_TEAM_TEXT = {"autopilot": "autopilot: the driven robot's own driver on / off",
              "kidnap_random": "kidnap the driven robot to a random pose",
              "kidnap_click": "kidnap the driven robot to that point (drag: heading)",
              "reset": "team filters back to the initial beliefs (clears trails)",
              "toggle*": "show / hide team filter 1-9",
              "ellipses": "95 % ellipses on / off"}


def _team_table() -> tuple[Binding, ...]:
    out: list[Binding] = []
    for b in BINDINGS:
        if b.action in _NOT_IN_TEAM:
            continue
        out.append(replace(b, description=_TEAM_TEXT.get(b.action, b.description)))
        if b.action == "stop":
            out.append(_NEXT_ROBOT)
    return tuple(out)


TEAM_BINDINGS: tuple[Binding, ...] = _team_table()

#: The tables by window mode.
TABLES: dict[str, tuple[Binding, ...]] = {"play": BINDINGS, "replay": REPLAY_BINDINGS,
                                          "team": TEAM_BINDINGS}


def bindings(mode: str = "play") -> tuple[Binding, ...]:
    """The binding table of a window mode ("play", "replay" or "team")."""
    return TABLES[mode]


def _by_code(table: tuple[Binding, ...]) -> dict[int, Binding]:
    out: dict[int, Binding] = {}
    for b in table:
        for c in b.codes:
            out.setdefault(c, b)
    return out


_BY_CODE = {mode: _by_code(table) for mode, table in TABLES.items()}


def binding_for_key(code: int, mode: str = "play") -> Binding | None:
    return _BY_CODE[mode].get(code)


def mouse_action(button: int, mode: str = "play") -> str | None:
    """The action of a mouse button (1 left, 3 right) in the mode's table, or None."""
    for b in TABLES[mode]:
        if b.button == button:
            return b.action
    return None


class KeyHandler:
    """Key events -> actions, with repeat only for the bindings that allow it.

    pygame's key repeat sends repeated KEYDOWN events while a key is held; a key whose
    binding does not repeat is ignored until its KEYUP.
    """

    def __init__(self, mode: str = "play") -> None:
        self.mode = mode
        self._held: set[int] = set()

    def actions(self, event) -> list[str]:
        """Action names for one pygame event (``toggle3`` for the key 3)."""
        if event.type == pygame.KEYUP:
            self._held.discard(event.key)
            return []
        if event.type != pygame.KEYDOWN:
            return []
        b = binding_for_key(event.key, self.mode)
        if b is None:
            return []
        if event.key in self._held and not b.repeat:
            return []
        self._held.add(event.key)
        if b.action.endswith("*"):
            return [b.action[:-1] + str(FILTER_KEYS.index(event.key) + 1)]
        return [b.action]


def markdown_table(mode: str = "play") -> str:
    """The mode's bindings as the Markdown table README.md and docs/window.md show (a test
    checks that they do): one row per binding, in table order."""
    rows = ["| keys | action |", "|---|---|"]
    rows += [f"| `{b.keys}` | {b.description} |" for b in TABLES[mode]]
    return "\n".join(rows) + "\n"


def help_lines(mode: str = "play") -> list[tuple[str, str, str]]:
    """``(group, keys, description)`` for every binding the overlay lists, in table order."""
    return [(b.group, b.keys, b.description) for b in TABLES[mode]]
