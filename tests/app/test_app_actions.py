"""Every key of every binding table has its handler (the window dispatches from
the controls table, ``App.act`` -> ``act_<action>``), and an action nobody handles is an
error, not a silent no-op."""

from __future__ import annotations

import pytest

from beacon_sim.app import controls
from beacon_sim.app.actions import DRIVE_KEYS
from beacon_sim.app.replay import ReplayApp
from beacon_sim.app.window import App

#: Actions the window handles in ``handle`` (mouse buttons and drags), not through ``act``.
MOUSE_ACTIONS = {"kidnap_click", "zoom", "pan", "seek_click"}


@pytest.mark.parametrize("mode", sorted(controls.TABLES))
def test_every_binding_has_a_handler(mode):
    cls = ReplayApp if mode == "replay" else App
    for b in controls.bindings(mode):
        if b.action in MOUSE_ACTIONS or b.action in DRIVE_KEYS:
            continue
        name = b.action.rstrip("*")
        assert callable(getattr(cls, f"act_{name}", None)), f"{mode}: no act_{name} for {b.keys}"


def test_an_unknown_action_raises():
    app = App.__new__(App)  # act needs no window for this
    with pytest.raises(ValueError, match="no handler for the action 'warp_drive'"):
        app.act("warp_drive")
