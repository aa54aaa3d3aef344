"""CSV cells a spreadsheet will not run: every CSV the program writes goes through
:func:`csv_writer` / :func:`csv_dict_writer`, which neutralise a text cell a spreadsheet would
take as a formula (CSV or formula injection: a student's file named ``=2+3*cmd|...`` in
``grade.csv``).

A text cell that starts with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return (and is
not a plain number such as ``-1.5``) is written with a ``'`` in front, which spreadsheets
show as text; so is a cell that already starts with ``'`` before such a character, so that
:func:`unguard_cell` undoes it exactly when the program reads its own CSV back.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Mapping, Sequence
from typing import IO, Any

#: The first characters a spreadsheet takes as the start of a formula.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def needs_guard(text: str) -> bool:
    """Whether a text cell would be taken as a formula (or is one already guarded)."""
    if text[:1] == "'":
        return needs_guard(text[1:])
    return text[:1] in FORMULA_STARTS and not _is_number(text)


def guard_cell(value: Any) -> Any:
    """``value`` as a CSV cell: a text a spreadsheet would run gets a ``'`` in front; numbers
    and other text as they are."""
    if isinstance(value, str) and value and needs_guard(value):
        return "'" + value
    return value


def unguard_cell(text: str) -> str:
    """The text :func:`guard_cell` guarded, as it was."""
    return text[1:] if text[:1] == "'" and needs_guard(text[1:]) else text


class _Guarded:
    """A ``csv.writer`` whose rows' text cells are guarded."""

    def __init__(self, fh: IO[str], **kwargs: Any):
        self._w = csv.writer(fh, **kwargs)

    def writerow(self, row: Iterable[Any]) -> Any:
        return self._w.writerow([guard_cell(v) for v in row])

    def writerows(self, rows: Iterable[Iterable[Any]]) -> None:
        for row in rows:
            self.writerow(row)


class _GuardedDict:
    """A ``csv.DictWriter`` whose rows' text cells (and header) are guarded."""

    def __init__(self, fh: IO[str], fieldnames: Sequence[str], **kwargs: Any):
        self.fieldnames = list(fieldnames)
        self._w = csv.DictWriter(fh, fieldnames=self.fieldnames, **kwargs)
        self._fh = fh

    def writeheader(self) -> Any:
        return _Guarded(self._fh).writerow(self.fieldnames)

    def writerow(self, row: Mapping[str, Any]) -> Any:
        return self._w.writerow({k: guard_cell(v) for k, v in row.items()})


def csv_writer(fh: IO[str], **kwargs: Any) -> _Guarded:
    """``csv.writer(fh)`` with every text cell guarded (:func:`guard_cell`)."""
    return _Guarded(fh, **kwargs)


def csv_dict_writer(fh: IO[str], fieldnames: Sequence[str], **kwargs: Any) -> _GuardedDict:
    """``csv.DictWriter(fh, fieldnames)`` with every text cell guarded (:func:`guard_cell`)."""
    return _GuardedDict(fh, fieldnames, **kwargs)
