"""The sections of docs/results.md, one module per group (``scripts/make_results.py`` runs them)."""
