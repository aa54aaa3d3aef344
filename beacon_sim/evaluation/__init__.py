"""Monte Carlo evaluation of filters: metrics beyond core.metrics, the posterior
Cramer-Rao bound, parallel runs, tables and plots (design.md section 6)."""
