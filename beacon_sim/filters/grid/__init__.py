"""The grid family: discrete Bayes filters, a probability per cell.

- ``histogram.py``: the grid Bayes filter over x, y and heading (``--filter histogram``),
  vectorised over the whole grid;
- ``corridor.py``: seed 004's corridor, the discrete Bayes filter in its smallest form
  (``--filter corridor``, on the corridor scenario's scans).

They import the shared home (``filters/base.py``, ``filters/association/``) and the core,
never another family (an import-linter contract in pyproject.toml).
"""
