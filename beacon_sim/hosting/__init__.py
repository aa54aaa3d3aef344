"""Running someone's filter: loading it by name, file or module, feeding it the simulation
(the runner and the team runner), judging what it returns (the guard), bounding its time
(the watchdog), reloading it when its file changes, and hosting it in a contained child
process of its own.

The layer stands between ``io`` and ``filters`` (docs/architecture.md, "hosting/"): it
imports the filters and the core, and everything above it (runs, evaluation, the window,
the CLI) runs a filter through it. The child protocol has one client,
:mod:`beacon_sim.hosting.client`; only this layer imports its wire format
(:mod:`beacon_sim.hosting.wire`).
"""
