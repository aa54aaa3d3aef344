"""The simulation core: value types, models, sensors, events, scenarios and the simulation.

Plain numpy and the standard library only; never imports pygame (a test checks it).
World frame: metres, x right, y up, heading counter-clockwise from +x in radians.
"""
