"""beacon-sim: an interactive 2D simulator that teaches and tests robot localization.

Layers (see docs/architecture.md): ``beacon_sim.core`` (plain numpy, no pygame),
``beacon_sim.filters`` (Bayesian filters on top of the core) and the front end
(``beacon_sim.app`` and ``beacon_sim.cli``), the only place pygame is imported.
"""

__version__ = "0.1.0"
