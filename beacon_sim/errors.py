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


class FileReplacedWarning(UserWarning):
    """A file beacon-sim wrote replaced one that another writer finished after this write
    began (two exports to one path at once): the later says so; the message is one line."""
