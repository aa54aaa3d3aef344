"""The interactive simulator window (the only package that imports pygame)."""
