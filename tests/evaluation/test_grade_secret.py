"""A grade is evidence.

1. Nothing a filter is given reveals the run's seed: a file that reads everything it is
   given (its context and generator, the global generators, its command line, environment
   and files) finds the seed of a public run (``run``: a brute force over small seeds, the
   documented limit of the public key) and returns the truth, but in ``grade``, whose
   streams are keyed by a secret the child never sees, it finds nothing and scores exactly
   as the honest EKF it wraps.
2. The secret is kept with the grade's outputs and taken back: a regrade with it, or one
   student graded alone with it, gives the same figures bit for bit (a filter that draws
   from ctx.rng included); a new secret moves that filter's figures.
3. Watched and scored look the same: what a file sees of its process under ``check`` is
   what it sees under a default grade; a file that fails a probe on purpose is shown
   failing.
4. One verdict path: an EKF that inflates P each step fails in run, eval, check and grade
   with one message.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.grading import SECRET_FILE, GradeConfig, grade, secret_fingerprint
from beacon_sim.hosting.conformance import run_checks
from beacon_sim.hosting.guard import DIVERGED
from beacon_sim.runs.headless import run_headless

ATTACKS = Path(__file__).parents[1] / "attacks"
SHORT = GradeConfig(scenarios=("default",), seeds=(0, 1), duration=4.0, time_limit=30.0)
FIGURES = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb",
           "failed_runs", "plot")

HONEST_PF = '''
from beacon_sim.filters.particle import ParticleFilter


class MyPf(ParticleFilter):
    """An honest particle filter: every draw from ctx.rng."""
'''

INFLATING = '''
from beacon_sim.filters.ekf import ExtendedKalmanFilter


class Inflating(ExtendedKalmanFilter):
    """A plausible student EKF: it inflates P each step "to stay safe"."""

    def predict(self, control, dt):
        super().predict(control, dt)
        self.p = tuple(10.0 * v for v in self.p)  # P *= 10
'''


def _klass(folder: Path, files: dict[str, str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")
    return folder


def _attack(stem: str) -> str:
    return (ATTACKS / f"{stem}.py").read_text(encoding="utf-8")


def _row(board, student):
    """A student's row of a grade (a GradeResult) or of the grade.json it wrote (a dict)."""
    rows = board["rows"] if isinstance(board, dict) else board.rows
    return next(r for r in rows if r["student"] == student)


def _figures(row):
    return {k: row[k] for k in FIGURES if k in row or k != "plot"}  # (grade.json has no plot)


def test_a_file_that_reads_everything_it_is_given_cannot_recover_the_seed_in_grade(tmp_path, capsys):
    path = tmp_path / "seed_recovery.py"
    path.write_text(_attack("seed_recovery"), encoding="utf-8")
    # The attack is real: in a public run (the public key, seed 3) it finds the seed by a
    # brute force over small seeds and returns the truth itself.
    res = run_headless(load_scenario("default"), [f"{path}:Recover"], seed=3, duration=4.0)
    assert "RECOVERED seed 3 via the public key's stream" in capsys.readouterr().out
    assert res.filter_summary()["Recover"]["pos_rmse_m"] == 0.0
    # In grade (small seeds 0 and 1, a shipped scenario: the easiest case for it) the streams
    # and the global generators are keyed by the grade's secret: nothing fits.
    klass = _klass(tmp_path / "class", {"seed_recovery.py": _attack("seed_recovery"),
                                        "honest.py": _attack("honest")})
    board = grade(klass, SHORT, jobs=2)
    log = board.logs["seed_recovery"]
    assert "RECOVERED" not in log and log.count("NOTHING") >= len(SHORT.seeds)
    cheat, honest = _row(board, "seed_recovery"), _row(board, "honest")
    assert cheat["failed_runs"] == 0 and not cheat["suspicious"]
    assert _figures(cheat) == _figures(honest)  # no better than the honest EKF it wraps
    assert cheat["rank"] > honest["rank"]  # the tie is broken by name: no attacker above


def test_the_kept_secret_regrades_bit_for_bit_in_class_and_alone(tmp_path, capsys):
    klass = _klass(tmp_path / "class", {"my_pf.py": HONEST_PF, "global_rng.py": _attack("global_rng")})
    config = tmp_path / "grade.toml"
    config.write_text('scenarios = ["default"]\nseeds = [0, 1]\nduration = 4.0\ntime_limit = 30.0\n')
    out = tmp_path / "out"
    args = ["grade", str(klass), "--config", str(config), "--jobs", "2", "--no-cache"]
    assert main([*args, "--out", str(out)]) == 0
    first = json.loads((out / "grade.json").read_text())
    kept = out / SECRET_FILE
    secret = bytes.fromhex(kept.read_text().strip())
    assert stat.S_IMODE(kept.stat().st_mode) == 0o600  # the grader's eyes only
    assert first["secret_sha256"] == secret_fingerprint(secret)
    assert secret.hex() not in (out / "grade.json").read_text()  # grade.json names it, never holds it
    assert "--secret-file" in capsys.readouterr().out
    # a regrade into the same folder takes the kept secret back: the same figures, bit for bit
    assert main([*args, "--out", str(out)]) == 0
    again = json.loads((out / "grade.json").read_text())
    assert again["secret_sha256"] == first["secret_sha256"]
    for name in ("my_pf", "global_rng"):
        assert _figures(_row(again, name)) == _figures(_row(first, name)), name
    # one student graded alone with the kept secret: the same figures again
    alone = _klass(tmp_path / "alone", {"my_pf.py": HONEST_PF})
    assert main(["grade", str(alone), "--config", str(config), "--out", str(tmp_path / "o2"),
                 "--secret-file", str(kept)]) == 0
    solo = json.loads((tmp_path / "o2" / "grade.json").read_text())
    assert _figures(_row(solo, "my_pf")) == _figures(_row(first, "my_pf"))
    # a new secret keys other streams: the particle filter's figures move (its draws are the
    # secret's), the truth does not
    assert main(["grade", str(alone), "--config", str(config), "--out", str(tmp_path / "o3"),
                 "--new-secret"]) == 0
    other = json.loads((tmp_path / "o3" / "grade.json").read_text())
    assert other["secret_sha256"] != first["secret_sha256"]
    assert _row(other, "my_pf")["pos_rmse_m"] != _row(first, "my_pf")["pos_rmse_m"]


def _lines(text: str, tag: str) -> list[str]:
    return sorted(line[len(tag) + 1:] for line in text.splitlines() if line.startswith(tag + " "))


def test_check_and_a_default_grade_look_the_same_to_the_file(tmp_path):
    """What a file can see of its process (command line, environment, folder, limits, the
    stack that builds it, the grader's objects in its process, its context and generator,
    how many copies are built and how each is called) is the same under check and under a
    grade with the default settings (five seeds of 60 s, a 60 s limit): only the data
    differ (other seeds, drawn afresh each time)."""
    path = tmp_path / "watched.py"
    path.write_text(_attack("watched"), encoding="utf-8")
    results = run_checks(f"{path}:Watched", load_scenario("default"))
    assert all(r.passed for r in results), [(r.name, r.message) for r in results if not r.passed]
    output = next(r for r in results if r.name == "output").message
    check_log = Path(re.search(r"see (\S+)$", output).group(1)).read_text()
    klass = _klass(tmp_path / "class", {"watched.py": _attack("watched")})
    board = grade(klass, GradeConfig(scenarios=("default",)), jobs=1)  # the default settings
    grade_log = board.logs["watched"]
    seen = _lines(check_log, "SEEN")
    assert len(seen) == 8  # five runs and the three probes, in one batch
    assert seen == _lines(grade_log, "SEEN")
    assert _lines(check_log, "CALLS") == _lines(grade_log, "CALLS")
    assert len(_lines(grade_log, "CALLS")) == 8


def test_a_file_that_fails_the_probes_on_purpose_is_failed(tmp_path):
    klass = _klass(tmp_path / "class", {"dodger.py": _attack("probe_dodger"), "honest.py": _attack("honest")})
    board = grade(klass, SHORT, jobs=2)
    row = _row(board, "dodger")
    assert row["failed_runs"] >= 1 and row["pos_rmse_m"] is None, row
    assert any("I have seen these readings before" in f["reason"] for f in row["failures"])
    assert row["rank"] > _row(board, "honest")["rank"]
    assert _row(board, "honest")["failures"] == []


def test_an_inflating_ekf_fails_run_eval_check_and_grade_with_one_message(tmp_path, capsys):
    path = tmp_path / "inflating.py"
    path.write_text(INFLATING, encoding="utf-8")
    spec = f"{path}:Inflating"
    # run: the guard stops it at the first estimate over the line
    assert main(["run", "default", "--filter", spec, "--seed", "0", "--duration", "25", "--json"]) == 0
    run = json.loads(capsys.readouterr().out)["filters"]["Inflating"]
    assert run["failed"] == DIVERGED and run["pos_rmse_m"] is None
    # eval: the same words, the same tick
    assert main(["eval", "default", "--filter", spec, "--runs", "1", "--duration", "25", "--json"]) == 0
    ev = json.loads(capsys.readouterr().out)["filters"]["Inflating"]
    assert ev["failed_runs"] == 1 and ev["failures"][0]["reason"] == DIVERGED
    assert ev["failures"][0]["time_s"] == run["failed_time_s"]
    # check: the "finite" check, the same words
    checked = {r.name: r for r in run_checks(spec, load_scenario("default"), seeds=[0])}
    assert not checked["finite"].passed and checked["finite"].message.endswith(DIVERGED)
    assert [r.name for r in checked.values() if not r.passed] == ["finite"]
    # grade: FAILED, never ranked above a working filter, with the same words
    klass = _klass(tmp_path / "class", {"inflating.py": INFLATING, "honest.py": _attack("honest")})
    board = grade(klass, GradeConfig(scenarios=("default",), seeds=(0,), duration=25.0, time_limit=30.0),
                  jobs=2)
    row = _row(board, "inflating")
    assert row["failed_runs"] == 1 and row["failures"][0]["reason"] == DIVERGED
    assert row["failures"][0]["time_s"] == run["failed_time_s"]
    assert row["rank"] > _row(board, "honest")["rank"] and row["pos_rmse_m"] is None


def test_a_singular_covariance_is_never_ok(tmp_path, capsys):
    """A covariance that rules out the error it has (a zero variance where the estimate is
    off: an infinite NEES) fails the run in run, eval and grade with one message, and its
    NEES is infinite at that step alone (it used to make every step's NEES infinite)."""
    import numpy as np

    from beacon_sim.core.metrics import nees
    from beacon_sim.hosting.guard import NEES_NOT_FINITE

    values = nees(np.ones((3, 3)), np.array([np.eye(3), np.diag([1.0, 0.0, 1.0]), np.eye(3)]))
    assert values[0] == 3.0 and values[1] == np.inf and values[2] == 3.0
    path = tmp_path / "certain.py"
    path.write_text("import numpy as np\nfrom beacon_sim.filters.ekf import ExtendedKalmanFilter\n\n\n"
                    "class Certain(ExtendedKalmanFilter):\n    def estimate(self):\n"
                    "        mean, cov = super().estimate()\n        cov[2, :] = cov[:, 2] = 0.0\n"
                    "        return mean, cov\n", encoding="utf-8")
    assert main(["run", "default", "--filter", f"{path}:Certain", "--seed", "0", "--duration", "3",
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["filters"]["Certain"]["failed"] == NEES_NOT_FINITE
    klass = _klass(tmp_path / "class", {"certain.py": path.read_text(), "honest.py": _attack("honest")})
    board = grade(klass, GradeConfig(scenarios=("default",), seeds=(0,), duration=3.0, time_limit=30.0),
                  jobs=2)
    row = _row(board, "certain")
    assert row["failures"][0]["reason"] == NEES_NOT_FINITE and row["anees"] is None
    assert row["rank"] > _row(board, "honest")["rank"]


def test_nothing_of_the_secret_reaches_the_child():
    """The bytes the grader sends a child (every request of a graded class) hold neither the
    grade's secret nor a run's key, and the run's seed is not the entropy of any stream."""
    import pickle

    from beacon_sim.evaluation.montecarlo import simulate_run
    from beacon_sim.hosting.client import hosted_context

    secret = os.urandom(32)
    sr = simulate_run(load_scenario("default"), 1, 1.0, probe=True, secret=secret)
    ctx = hosted_context(sr.scenario, sr.stream_key, "MyEkf", None)
    assert sr.extra is not None and sr.extra.frames_other is not None  # the probes' extra run
    extra = hosted_context(sr.extra.scenario, sr.extra.stream_key, "MyEkf", None)
    sent = (pickle.dumps((ctx, extra)) + b"".join(sr.frames) + b"".join(sr.extra.frames)
            + b"".join(sr.extra.frames_other))
    assert secret not in sent and sr.stream_key not in sent and sr.extra.stream_key not in sent
    assert sr.extra.seed != sr.seed and sr.extra.truth_checksum != sr.truth_checksum  # its own truth
    entropy = ctx.rng.bit_generator.seed_seq.entropy
    assert entropy != 1 and entropy.bit_length() > 200  # a hash, not the seed
    assert sr.global_seed("MyEkf") not in (1, 1 % 2**32)
