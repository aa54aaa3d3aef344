"""``new-filter`` never replaces a file, even one made after its check that the name is free
(the name is taken with a hard link, which fails when it exists, or O_EXCL)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core import files
from beacon_sim.core.files import create_text_new
from beacon_sim.errors import UsageError


def _race(monkeypatch, target: Path, content: str) -> None:
    """The file appears between new-filter's check and its write: the check sees no file."""
    real_exists = Path.exists
    monkeypatch.setattr(Path, "exists", lambda p, *a, **k: False if p == target else real_exists(p, *a, **k))
    target.write_text(content)


def test_a_file_made_after_the_check_is_not_overwritten(tmp_path, monkeypatch, capsys):
    target = tmp_path / "mine.py"
    _race(monkeypatch, target, "# the student's own work\n")
    assert main(["new-filter", str(target)]) == 2
    err = capsys.readouterr().err
    assert "the file exists" in err and "Traceback" not in err
    assert target.read_text() == "# the student's own work\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.py"]   # no temporary left


def test_without_hard_links_the_create_is_exclusive_too(tmp_path, monkeypatch):
    def no_links(src, dst, *a, **k):
        raise OSError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(files.os, "link", no_links)
    target = tmp_path / "f.py"
    create_text_new(target, "new\n", error=UsageError)
    assert target.read_text() == "new\n"
    with pytest.raises(UsageError, match=r"f\.py: the file exists"):
        create_text_new(target, "other\n", error=UsageError)
    assert target.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.py"]


def test_the_new_file_is_whole_and_a_fresh_name_works(tmp_path):
    target = tmp_path / "g.py"
    assert main(["new-filter", str(target)]) == 0
    text = target.read_text()
    assert "class " in text and text.endswith("\n")
    assert os.stat(target).st_nlink == 1   # the temporary name is gone, only the file is left
