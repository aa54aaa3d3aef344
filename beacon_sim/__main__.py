"""``python -m beacon_sim`` is the same as the ``beacon-sim`` command."""

from beacon_sim.cli.main import main

raise SystemExit(main())
