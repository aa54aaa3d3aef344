"""Errors a user sees as one line (the command exits with status 2, no traceback).

The layers below raise their own kinds (``ScenarioError``, ``FilterError``,
``RecordingError``, ``MrclamError``); the command line catches them all and prints the
message. :class:`UsageError` is a bad argument of the command line itself.
"""

from __future__ import annotations


class UsageError(Exception):
    """A bad command-line argument or option; the message is one line."""
