"""The class: one :class:`Student` per filter file of the folder (:func:`find_students`) and
the filter class each file holds (:func:`find_class`, read from its source, never run).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

from beacon_sim.core.files import (
    MAX_SOURCE_BYTES,
    read_user_text,
)
from beacon_sim.evaluation.grading.config import GradeError
from beacon_sim.hosting.loading import FILTER_METHODS, FUNCTIONS


@dataclass(frozen=True)
class Student:
    """One file: the student (the file's stem), the filter spec, or why it has none."""

    name: str
    path: Path
    spec: str | None
    problem: str | None = None
    class_name: str | None = None


def find_class(path: Path, class_name: str | None = None) -> str | None:
    """The filter class of a student's file, read without running it (``ast``): the one
    named ``class_name``; else the last top-level class defining all of reset, predict,
    update and estimate; else None (the class that implements the interface, perhaps by
    inheritance, or the file's module-level functions: chosen in the student's own child
    process, :func:`~beacon_sim.hosting.loading.choose_filter`). Raises GradeError (syntax
    error, no such class)."""
    text = read_user_text(path, what="filter file", cap=MAX_SOURCE_BYTES, error=GradeError)
    try:
        tree = ast.parse(text, str(path))
    except (SyntaxError, UnicodeDecodeError, OSError, ValueError) as exc:
        raise GradeError(f"does not import: {type(exc).__name__}: {exc}") from None
    classes = [n for n in tree.body if isinstance(n, ast.ClassDef)]
    if class_name is not None:
        if any(c.name == class_name for c in classes) or class_name == FUNCTIONS:
            return class_name
        raise GradeError(f"no class {class_name!r}")
    full = [c for c in classes if {f.name for f in c.body if isinstance(f, ast.FunctionDef)}
            >= set(FILTER_METHODS)]
    return full[-1].name if full else None


def find_students(folder: str | Path, class_name: str | None = None) -> list[Student]:
    """Every ``*.py`` file of ``folder`` (sorted, ``_``-prefixed files left out)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise GradeError(f"{folder}: not a folder")
    out = []
    for path in sorted(folder.glob("*.py")):
        if path.name.startswith("_"):
            continue
        try:
            cls = find_class(path, class_name)
        except GradeError as exc:
            out.append(Student(path.stem, path, None, str(exc)))
            continue
        out.append(Student(path.stem, path, f"{path.resolve()}:{cls}" if cls else str(path.resolve()),
                           class_name=cls))
    if not out:
        raise GradeError(f"{folder}: no filter files (*.py)")
    return out
