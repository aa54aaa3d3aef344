"""The program's version, one place (pyproject.toml reads it for the package)."""

__version__ = "0.1.0"
