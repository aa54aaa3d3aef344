"""The old import path of the histogram (grid Bayes) filter, which now lives in
:mod:`beacon_sim.filters.grid.histogram` (the grid family, docs/architecture.md).

Files written against ``beacon_sim.filters.histogram`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.grid.histogram import TWO_PI, HistogramFilter

__all__ = ["TWO_PI", "HistogramFilter"]
