"""beacon-sim: an interactive 2D simulator that teaches and tests robot localization.

Layers (see docs/architecture.md): ``beacon_sim.core`` (plain numpy, no pygame),
``beacon_sim.filters`` (Bayesian filters on top of the core) and the front end
(``beacon_sim.app`` and ``beacon_sim.cli``), the only place pygame is imported.

The Python API (docs/python-api.md) is the names in ``__all__``, defined in
``beacon_sim.api`` and loaded on first use, so ``import beacon_sim.core`` stays light and the
lower layers never load the upper ones::

    import beacon_sim as bs
    run = bs.run("default", ["ekf", "pf"], seed=3, duration=30)
"""

from beacon_sim.version import __version__

#: The public API (docs/python-api.md): the run functions and their results, what a filter
#: author needs (``FilterBase``, the beliefs, ``Control`` / ``Measurement``, and the modules
#: ``motion``, ``measurement_models`` and ``angles``; for a Gauss-Newton step of one's own,
#: ``FactorGraph``, ``GraphSolver`` and ``StepReport``) and the errors, all ``BeaconSimError``
#: (a ``ValueError``).
__all__ = ["BeaconSimError", "Control", "Evaluation", "ExtendedKalmanFilter", "FactorGraph", "Filter",
           "FilterBase", "FilterContext", "FilterError", "FilterLoadError", "GaussianBelief", "GradeError",
           "GraphSolver", "GridBelief",
           "LandmarkMap", "LikelihoodField", "Measurement", "MrclamError", "ParticleBelief",
           "RangeModelParams", "RecordingError", "ReplayMismatch", "Run", "ScenarioError", "StepReport",
           "TeamRun",
           "UsageError", "__version__", "angles", "broad_gaussian", "evaluate", "load_scenario",
           "load_tables", "load_team_scenario", "measurement_models", "motion", "replay", "run",
           "run_team", "systematic", "wrap"]


def __getattr__(name: str):
    if name in __all__:  # PEP 562: the API is imported on first use
        from beacon_sim import api

        return getattr(api, name)
    raise AttributeError(f"module 'beacon_sim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
