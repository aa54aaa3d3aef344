"""Driving in a live session (``runs/live.Session`` is made of :class:`SessionDriving`): the
driven robot's command from the keyboard (W/S/A/D/X) or its own driver (the autopilot, M),
Tab to drive the next robot of a team, and the keyboard taking over without a jolt.
"""

from __future__ import annotations

from typing import Any

from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.types import Control


class SessionDriving:
    """Who drives the driven robot, and with what command (see the module docstring). The
    session holds ``autopilot``, ``driven``, ``keyboard``, ``last_controls``, ``sim``,
    ``scenario``, ``n_robots`` and ``robot_names``."""

    autopilot: bool
    driven: int
    keyboard: Any
    last_controls: list[Control]
    sim: Any
    scenario: Any
    n_robots: int
    robot_names: list[str]

    @property
    def has_autopilot(self) -> bool:
        """Whether the driven robot has a driver of its own to hand over to (M)."""
        return not isinstance(self.scenario.driver, KeyboardSpec)

    def drive(self, key: str) -> None:
        """W/S/A/D/X on the driven robot's command; driving by hand switches the autopilot off."""
        if self.autopilot:
            self.autopilot = False
            self._take_over()
        self.keyboard.press(key)

    def toggle_autopilot(self) -> None:
        self.autopilot = self.has_autopilot and not self.autopilot
        if not self.autopilot:
            self._take_over()

    def _take_over(self) -> None:
        """The keyboard starts from the driven robot's last command (no jolt): see
        :func:`taken_over`."""
        self.keyboard.v, self.keyboard.omega = taken_over(self.last_controls[self.driven],
                                                          self.keyboard.limits)

    def next_robot(self, step: int = 1) -> str:
        """Tab: drive the next robot (the one driven so far goes back to its driver); the
        keyboard takes over the new one's last command. Returns its name."""
        self.driven = (self.driven + step) % self.n_robots
        if self.autopilot and not self.has_autopilot:
            self.autopilot = False
        if not self.autopilot:
            self._take_over()
        return self.robot_names[self.driven]

    def next_control(self) -> Control:
        """The driven robot's command for the next tick."""
        if self.autopilot:
            sim = self.sim.sims[self.driven]
            return sim.driver.control(sim.time, sim.pose)
        return self.keyboard.control

    @property
    def drive_mode(self) -> str:
        """Who drives, for the panel."""
        return "AUTOPILOT (M)" if self.autopilot else "keyboard WASD, X stop"


def taken_over(c: Control, limits: KeyboardLimits) -> tuple[float, float]:
    """``(v, omega)`` the keyboard starts from when it takes over command ``c``: each rounded
    to the nearest multiple of its step (``v_step``, ``omega_step``), clamped to the limits."""
    v = round(c.v / limits.v_step) * limits.v_step
    w = round(c.omega / limits.omega_step) * limits.omega_step
    v = round(min(max(v, limits.v_min), limits.v_max), 9)
    w = round(min(max(w, -limits.omega_max), limits.omega_max), 9)
    return v + 0.0, w + 0.0
