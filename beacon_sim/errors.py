"""Errors a user sees as one line (the command exits with status 2, no traceback).

Every error of the project is a :class:`BeaconSimError`, itself a ``ValueError`` so that
code written as ``except ValueError`` keeps working. The layers raise their own kinds
(``ScenarioError``, ``FilterError`` and ``FilterLoadError``, ``RecordingError`` and
``ReplayMismatch``, ``MrclamError``, ``GradeError``); the command line catches them all and
prints the message, the Python API lets them through (``beacon_sim`` exports them).
:class:`UsageError` is a bad argument of the command line or of an API call.
"""

from __future__ import annotations


class BeaconSimError(ValueError):
    """The base of every error beacon-sim raises on purpose; the message is one line."""


class UsageError(BeaconSimError):
    """A bad command-line option or API argument (seed, duration, ...); the message is one line."""


class ArgumentTypeError(UsageError, TypeError):
    """An API argument of the wrong type (``run(scenario=5)``): a :class:`UsageError` that is
    also a ``TypeError``, so both ``except ValueError`` and ``except TypeError`` catch it."""


class FileReplacedWarning(UserWarning):
    """A file beacon-sim wrote replaced one that another writer finished after this write
    began (two exports to one path at once): the later says so; the message is one line."""


def short_repr(value: object) -> str:
    """``repr(value)`` for a one-line message: at most 60 characters, and a huge integer by
    its size (``10**400`` is "<a 1329-bit int>", not 401 digits)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**40:
        return f"<a {value.bit_length()}-bit int>"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
