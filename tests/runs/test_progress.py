"""Long work shows progress on stderr; short work prints nothing."""

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs import progress
from beacon_sim.runs.headless import run_headless


def test_short_work_prints_nothing(capsys):
    bar = progress.Progress(50, "run x", True, unit="ticks")
    for _ in range(50):
        bar.advance()
    assert capsys.readouterr().err == ""


class _Terminal:
    """A stderr that says it is a terminal."""

    def __init__(self):
        import io
        self.buf = io.StringIO()

    def isatty(self):
        return True

    def write(self, text):
        return self.buf.write(text)

    def flush(self):
        pass


def test_a_long_run_draws_a_bar_that_ends_at_the_total(monkeypatch):
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)   # as if every tick took a long time
    monkeypatch.setattr(progress, "REDRAW_EVERY_S", 0.0)
    term = _Terminal()
    monkeypatch.setattr("sys.stderr", term)
    run_headless(load_scenario("default"), ["ekf"], duration=2.0, progress=True)
    err = term.buf.getvalue()
    assert "run default [" in err and err.rstrip().endswith("s")
    assert "40/40 ticks" in err and err.endswith("\n")


def test_disabled_prints_nothing(capsys, monkeypatch):
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    run_headless(load_scenario("default"), ["ekf"], duration=2.0, progress=False)
    assert capsys.readouterr().err == ""


def test_off_a_terminal_progress_is_plain_lines(monkeypatch):
    import io

    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    log = io.StringIO()
    bar = progress.Progress(3, "eval x", True, stream=log)
    for _ in range(3):
        bar.advance()
    lines = log.getvalue().splitlines()
    assert lines[0].startswith("eval x: 1/3 runs, ") and "eta" in lines[0]
    assert lines[-1].startswith("eval x: 3/3 runs, ") and lines[-1].endswith("(done)")
    assert "\r" not in log.getvalue()


def _to_a_log_file(path, argv):
    import contextlib

    from beacon_sim.cli.main import main

    with open(path, "w", encoding="utf-8") as log, contextlib.redirect_stderr(log):
        code = main(argv)
    return code, path.read_text(encoding="utf-8").splitlines()


def test_eval_and_grade_write_progress_lines_to_a_log_file(tmp_path, monkeypatch):
    from student_filters import write_class

    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)   # as if each run took long
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    code, lines = _to_a_log_file(tmp_path / "eval.log", ["eval", "default", "--filter", "ekf", "--runs", "3",
                                                          "--duration", "2", "--jobs", "1",
                                                          "--out", str(tmp_path / "ev")])
    assert code == 0
    ours = [ln for ln in lines if ln.startswith("eval default: ")]
    assert [ln.split(",")[0] for ln in ours] == [f"eval default: {k}/3 runs" for k in (1, 2, 3)]
    assert ours[-1].endswith("(done)")
    klass = write_class(tmp_path / "class", ["alice", "bob"])
    cfg = tmp_path / "grade.toml"
    cfg.write_text('scenarios = ["default"]\nseeds = [3, 4]\nduration = 2.0\ntime_limit = 5.0\n')
    code, lines = _to_a_log_file(tmp_path / "grade.log", ["grade", str(klass), "--config", str(cfg),
                                                           "--out", str(tmp_path / "o"), "--jobs", "1"])
    ours = [ln for ln in lines if ln.startswith("grade: ")]
    assert ours and ours[-1].startswith("grade: ") and ours[-1].endswith("(done)")
    total = ours[-1].split(",")[0].split("/")[1].split()[0]
    assert ours[-1].startswith(f"grade: {total}/{total} runs")


def test_mrclam_writes_progress_lines_to_a_log_file_and_keeps_its_results(tmp_path, monkeypatch):
    """``beacon-sim mrclam --headless`` off a terminal: plain ``mrclam: k/N s of data`` lines,
    the last one ``(done)``; the run's figures are the same as without progress, bit for bit."""
    import json

    import numpy as np
    from mrclam_helpers import make_folder

    from beacon_sim.io.mrclam import load_mrclam
    from beacon_sim.runs.mrclam import run_mrclam

    folder = tmp_path / "SyntheticSet"
    make_folder(folder, seconds=20.0)
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)   # as if the data took long to feed
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    code, lines = _to_a_log_file(tmp_path / "mrclam.log", ["mrclam", str(folder), "--robot", "1",
                                                           "--headless", "--filter", "ekf",
                                                           "--duration", "10", "--json"])
    assert code == 0
    ours = [ln for ln in lines if ln.startswith("mrclam: ")]
    assert len(ours) >= 3 and "\r" not in "".join(lines)
    assert ours[-1].startswith("mrclam: 10/10 s of data, ") and ours[-1].endswith("(done)")
    done = [int(ln.split(": ")[1].split("/")[0]) for ln in ours]
    assert done == sorted(done) and len(set(done)) == len(done)
    data = load_mrclam(folder, 1)
    quiet = run_mrclam(data, ["ekf"], duration=10.0, calibration="self")
    loud = run_mrclam(data, ["ekf"], duration=10.0, calibration="self", progress=True)

    def figures(run):  # every figure but the wall-clock ones
        d = run.as_json()
        d.pop("wall_s")
        for row in d["filters"].values():
            row.pop("us_per_step")
        return json.dumps(d, default=float, sort_keys=True)

    assert figures(quiet) == figures(loud)
    a, b = quiet.tracks["ekf"], loud.tracks["ekf"]
    assert np.array_equal(a.times, b.times)
    assert np.array_equal(a.means, b.means, equal_nan=True)
    assert np.array_equal(a.covs, b.covs, equal_nan=True)
