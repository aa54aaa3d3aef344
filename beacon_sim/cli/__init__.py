"""The ``beacon-sim`` command line (beacon_sim/cli/main.py); one module per subcommand."""
