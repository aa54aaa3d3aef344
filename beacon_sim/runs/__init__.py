"""Driving the simulation and the filters over time: a headless run, a live session, a
replay, the recorder, user commands, a MRCLAM run, and the scene a window draws."""
