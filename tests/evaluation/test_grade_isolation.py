"""A class is graded at the process level (no bubblewrap: its students' processes are not
isolated from each other) only when the teacher says so, and then the page and the terminal
say what a file could do; what a child writes in its own folder (its HOME and TMPDIR) does
not survive it, and under bubblewrap neither does what it writes in /tmp."""

from __future__ import annotations

import dataclasses
import os
import textwrap
from pathlib import Path

import pytest
from student_filters import write_class

from beacon_sim.cli.main import main
from beacon_sim.evaluation.grading import GradeConfig, GradeError, grade, write_outputs
from beacon_sim.hosting.containment import bwrap_problem

CONFIG = GradeConfig(scenarios=("two_rooms",), seeds=(0,), duration=2.0, time_limit=10.0)

WRITER = textwrap.dedent("""
    import os
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


    class Writer(ExtendedKalmanFilter):
        def reset(self, initial):
            super().reset(initial)
            path = os.path.join(os.environ["TMPDIR"], "left-behind")  # the child's own folder
            fd = os.open(path, os.O_WRONLY | os.O_CREAT, 0o600)
            os.write(fd, b"x")
            os.close(fd)
            print("TMPFILE", path, os.path.realpath(path), flush=True)
            try:
                with open("/tmp/NAME", "w") as fh:  # the machine's /tmp, or the sandbox's
                    fh.write("x")
                print("SHARED written", flush=True)
            except OSError as exc:
                print("SHARED refused", exc, flush=True)
""")


def test_a_class_at_the_process_level_needs_the_teachers_word_and_says_what_is_open(tmp_path, capsys):
    folder = write_class(tmp_path / "class", ["alice", "bob"])
    cfg = dataclasses.replace(CONFIG, sandbox="process")
    with pytest.raises(GradeError) as info:
        grade(folder, cfg, jobs=2)
    assert "not isolated" in str(info.value) and "allow_unisolated" in str(info.value)
    board = grade(folder, dataclasses.replace(cfg, allow_unisolated=True), jobs=2)
    assert board.not_isolated.startswith("NOT ISOLATED") and "/tmp" in board.not_isolated
    assert "signal" in board.not_isolated
    write_outputs(board, tmp_path / "out")
    assert "NOT ISOLATED" in (tmp_path / "out" / "grade.html").read_text(encoding="utf-8")
    conf = tmp_path / "g.toml"
    conf.write_text('scenarios = ["two_rooms"]\nseeds = [0]\nduration = 2.0\nsandbox = "process"\n')
    assert main(["grade", str(folder), "--config", str(conf), "--out", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err
    assert "allow_unisolated" in err and len(err.strip().splitlines()) == 1
    assert main(["grade", str(folder), "--config", str(conf), "--out", str(tmp_path / "o3"),
                 "--allow-unisolated"]) == 0
    assert "NOT ISOLATED" in capsys.readouterr().out
    one = write_class(tmp_path / "one", ["alice"])  # one student (autograde): no classmates
    assert not grade(one, cfg, jobs=1).rows[0]["failed_runs"]


@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_what_a_child_writes_does_not_survive_it(tmp_path, sandbox):
    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(f"no bubblewrap sandbox here: {bwrap_problem()}")
    name = f"beacon-sim-left-{os.getpid()}-{sandbox}"
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "writer.py").write_text(WRITER.replace("NAME", name), encoding="utf-8")
    shared = Path("/tmp") / name
    try:
        board = grade(folder, dataclasses.replace(CONFIG, sandbox=sandbox), jobs=1)
        log = board.logs["writer"]
        assert "TMPFILE" in log, log
        assert not board.rows[0]["failed_runs"], board.rows[0]["failures"]
        if sandbox == "process":  # the child's own folder is the grader's to remove
            line = next(x for x in log.splitlines() if x.startswith("TMPFILE"))
            path = Path(line.split()[2])
            assert not path.exists() and not path.parent.exists(), path
        else:  # the sandbox's /tmp is its own: nothing reaches the machine's
            assert "SHARED written" in log and not shared.exists()
    finally:
        if shared.exists():  # the process level's documented gap (the page says so)
            shared.unlink()
