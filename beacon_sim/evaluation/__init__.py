"""Monte Carlo evaluation of filters: metrics beyond core.metrics, the posterior
Cramer-Rao bound, parallel runs, tables and plots (docs/evaluation.md)."""
