"""The keyboard's control state as plain logic (the window feeds it key presses).

W / S raise / lower v by ``v_step``; A / D steer left / right (raise / lower omega by
``omega_step``); X stops. Values are clamped to the limits.
"""

from __future__ import annotations

from dataclasses import dataclass

from beacon_sim.core.types import Control


@dataclass(frozen=True)
class KeyboardLimits:
    """Steps and limits: ``v_step``, ``v_max`` [m/s], ``v_min`` [m/s] (negative: reverse),
    ``omega_step``, ``omega_max`` [rad/s]."""

    v_step: float = 0.1
    v_max: float = 1.0
    v_min: float = -0.5
    omega_step: float = 0.2
    omega_max: float = 2.0


@dataclass
class KeyboardDrive:
    """Current command set from the keyboard."""

    limits: KeyboardLimits = KeyboardLimits()
    v: float = 0.0
    omega: float = 0.0

    def _clamp(self) -> None:
        lim = self.limits
        self.v = round(min(max(self.v, lim.v_min), lim.v_max), 9)
        self.omega = round(min(max(self.omega, -lim.omega_max), lim.omega_max), 9)

    def faster(self) -> None:
        """W: raise v by one step."""
        self.v += self.limits.v_step
        self._clamp()

    def slower(self) -> None:
        """S: lower v by one step."""
        self.v -= self.limits.v_step
        self._clamp()

    def left(self) -> None:
        """A: turn more to the left (counter-clockwise), omega up one step."""
        self.omega += self.limits.omega_step
        self._clamp()

    def right(self) -> None:
        """D: turn more to the right, omega down one step."""
        self.omega -= self.limits.omega_step
        self._clamp()

    def stop(self) -> None:
        """X: v = omega = 0."""
        self.v = 0.0
        self.omega = 0.0

    def press(self, key: str) -> bool:
        """Apply one of ``"w", "s", "a", "d", "x"``; returns False for any other key."""
        action = {"w": self.faster, "s": self.slower, "a": self.left, "d": self.right,
                  "x": self.stop}.get(key.lower())
        if action is None:
            return False
        action()
        return True

    @property
    def control(self) -> Control:
        return Control(self.v, self.omega)
