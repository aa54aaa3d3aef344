"""Files are read as what they are, writes are atomic.

Reading: a FIFO, ``/dev/zero`` or ``/dev/urandom`` named as a scenario, a map YAML, a map
image, a recording or a grade config, a PNG header claiming 30,000 x 30,000 pixels, a
scenario nested thousands deep and a grade config with a 5,000-digit seed each give one
line naming the file, exit status 2, through the command line, the Python API and the Gym
env (the project's error). The cases run in one child process with a generous time-out, so
a hang fails the test instead of blocking the suite.

Writing: an export (.npz, .csv, .mcap), eval's and grade's outputs that fail midway leave the
previous file as it was, and no temporary file behind.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.core.files import atomic_write, read_user_bytes, write_text_atomic
from beacon_sim.errors import BeaconSimError

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs (POSIX)")

ROOT = Path(__file__).resolve().parents[2]
OFFICE_YAML = (ROOT / "assets" / "maps" / "office.yaml").read_text(encoding="utf-8")


def _png_header(width: int, height: int) -> bytes:
    """A PNG file of only its signature, IHDR and IEND (no pixels): what the header claims."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


def _map_scenario(folder: Path, image: str | None, yaml_fifo: bool = False) -> Path:
    """office.toml in ``folder`` with its map YAML beside it naming ``image``."""
    folder.mkdir()
    text = (ROOT / "scenarios" / "office.toml").read_text(encoding="utf-8")
    (folder / "o.toml").write_text(text.replace('"../assets/maps/office.yaml"', '"m.yaml"'),
                                   encoding="utf-8")
    if yaml_fifo:
        os.mkfifo(folder / "m.yaml")
    else:
        yaml = "\n".join(f"image: {image}" if line.startswith("image:") else line
                         for line in OFFICE_YAML.splitlines())
        (folder / "m.yaml").write_text(yaml + "\n", encoding="utf-8")
    return folder / "o.toml"


@pytest.fixture(scope="module")
def cases(tmp_path_factory) -> dict[str, tuple[str, list[str]]]:
    """name -> (the file the message must name, the CLI arguments)."""
    tmp = tmp_path_factory.mktemp("hostile_files")
    os.mkfifo(tmp / "fifo.toml")
    os.mkfifo(tmp / "fifo.jsonl")
    os.mkfifo(tmp / "cfg.toml")
    (tmp / "subs").mkdir()
    (tmp / "deep.toml").write_text("x = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    (tmp / "seed.toml").write_text("seeds = [" + "7" * 5000 + "]\n", encoding="utf-8")
    (tmp / "deepcfg.toml").write_text("seeds = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    (tmp / "bomb.png").write_bytes(_png_header(30000, 30000))
    os.mkfifo(tmp / "fifo.pgm")
    sc = {
        "image_fifo": _map_scenario(tmp / "a", str(tmp / "fifo.pgm")),
        "image_zero": _map_scenario(tmp / "b", "/dev/zero"),
        "image_urandom": _map_scenario(tmp / "c", "/dev/urandom"),
        "image_bomb": _map_scenario(tmp / "d", str(tmp / "bomb.png")),
        "yaml_fifo": _map_scenario(tmp / "e", None, yaml_fifo=True),
    }
    out = str(tmp / "out")
    c: dict[str, tuple[str, list[str]]] = {
        "scenario_fifo": ("fifo.toml", ["run", str(tmp / "fifo.toml"), "--duration", "1"]),
        "scenario_zero": ("/dev/zero", ["run", "/dev/zero", "--duration", "1"]),
        "scenario_urandom": ("/dev/urandom", ["run", "/dev/urandom", "--duration", "1"]),
        "scenario_deep": ("deep.toml", ["run", str(tmp / "deep.toml"), "--duration", "1"]),
        "check_scenario_fifo": ("fifo.toml", ["check", "ekf", "--scenario", str(tmp / "fifo.toml")]),
        "recording_fifo": ("fifo.jsonl", ["replay", str(tmp / "fifo.jsonl")]),
        "recording_zero": ("/dev/zero", ["replay", "/dev/zero"]),
        "recording_urandom": ("/dev/urandom", ["replay", "/dev/urandom"]),
        "grade_config_fifo": ("cfg.toml", ["grade", str(tmp / "subs"), "--config", str(tmp / "cfg.toml"),
                                           "--out", out]),
        "grade_config_zero": ("/dev/zero", ["grade", str(tmp / "subs"), "--config", "/dev/zero",
                                            "--out", out]),
        "grade_config_urandom": ("/dev/urandom", ["grade", str(tmp / "subs"), "--config", "/dev/urandom",
                                                  "--out", out]),
        "grade_config_seed_digits": ("seed.toml", ["grade", str(tmp / "subs"), "--config",
                                                   str(tmp / "seed.toml"), "--out", out]),
        "grade_config_deep": ("deepcfg.toml", ["grade", str(tmp / "subs"), "--config",
                                               str(tmp / "deepcfg.toml"), "--out", out]),
    }
    for name, path in sc.items():
        named = {"image_fifo": "fifo.pgm", "image_zero": "/dev/zero", "image_urandom": "/dev/urandom",
                 "image_bomb": "bomb.png", "yaml_fifo": "m.yaml"}[name]
        c[f"map_{name}"] = (named, ["run", str(path), "--duration", "1"])
    return c


DRIVER = textwrap.dedent("""
    import contextlib, io, json, sys
    from beacon_sim.cli.main import main
    cases = json.loads(sys.argv[1])
    out = {}
    for name, (named, argv) in cases.items():
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
        out["cli:" + name] = [rc, err.getvalue()]
    # the Python API and the Gym env: the project's error, not a traceback
    import beacon_sim.api as api
    from beacon_sim.errors import BeaconSimError
    def attempt(label, fn):
        try:
            fn()
            out[label] = ["no error", ""]
        except BeaconSimError as exc:
            out[label] = ["BeaconSimError", str(exc)]
        except BaseException as exc:
            out[label] = [type(exc).__name__, str(exc)[:200]]
    for name, (named, argv) in cases.items():
        if argv[0] == "run":
            attempt("api:" + name, lambda p=argv[1]: api.run(p, duration=1.0))
        elif argv[0] == "replay":
            attempt("api:" + name, lambda p=argv[1]: api.replay(p))
    try:
        from beacon_sim.gym import BeaconEnv
    except ImportError:
        BeaconEnv = None
    if BeaconEnv is not None:
        for name, (named, argv) in cases.items():
            if argv[0] == "run":
                attempt("gym:" + name, lambda p=argv[1]: BeaconEnv(p).reset(seed=1))
    print(json.dumps(out))
""")


@pytest.fixture(scope="module")
def outcomes(cases) -> dict[str, list]:
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}
    proc = subprocess.run([sys.executable, "-c", DRIVER, json.dumps(cases)], capture_output=True,
                          text=True, timeout=120, env=env)  # a hang fails here, it does not block
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


CLI_CASES = ["scenario_fifo", "scenario_zero", "scenario_urandom", "scenario_deep", "check_scenario_fifo",
             "recording_fifo", "recording_zero", "recording_urandom", "grade_config_fifo",
             "grade_config_zero", "grade_config_urandom", "grade_config_seed_digits", "grade_config_deep",
             "map_image_fifo", "map_image_zero", "map_image_urandom", "map_image_bomb", "map_yaml_fifo"]


@pytest.mark.parametrize("name", CLI_CASES)
def test_cli_refuses_in_one_line(name, cases, outcomes):
    rc, err = outcomes[f"cli:{name}"]
    named = cases[name][0]
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert named in err and "Traceback" not in err


@pytest.mark.parametrize("name", [n for n in CLI_CASES if n.startswith(("scenario_", "map_", "recording_"))])
def test_api_and_gym_raise_the_projects_error(name, cases, outcomes):
    named = cases[name][0]
    for front in ("api", "gym"):
        key = f"{front}:{name}"
        if key not in outcomes:
            continue
        kind, message = outcomes[key]
        assert kind == "BeaconSimError", (key, kind, message)
        assert named in message and "\n" not in message.strip()


def test_the_bomb_message_names_the_cap(outcomes):
    err = outcomes["cli:map_image_bomb"][1]
    assert "30000x30000" in err and "16777216" in err


def test_special_files_are_refused_without_reading(tmp_path):
    os.mkfifo(tmp_path / "p")
    for path in (tmp_path / "p", Path("/dev/zero"), tmp_path):
        with pytest.raises(BeaconSimError, match="only regular files are read"):
            read_user_bytes(path, what="thing", cap=10)
    (tmp_path / "big").write_bytes(b"x" * 11)
    with pytest.raises(BeaconSimError, match="a thing holds at most 10"):
        read_user_bytes(tmp_path / "big", what="thing", cap=10)


# -- atomic writes ------------------------------------------------------------------------------

def _no_temporaries(folder: Path) -> None:
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old", encoding="utf-8")
    with pytest.raises(RuntimeError), atomic_write(target, "w") as fh:
        fh.write("half of the new")
        raise RuntimeError("killed midway")
    assert target.read_text(encoding="utf-8") == "old"
    _no_temporaries(tmp_path)
    write_text_atomic(target, "new")
    assert target.read_text(encoding="utf-8") == "new"
    _no_temporaries(tmp_path)


def test_a_full_disk_names_the_file_and_keeps_the_old_one(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(BeaconSimError, match=r"out\.bin: cannot write the export: No space left"), \
            atomic_write(target, "wb", what="export") as fh:
        fh.write(b"some bytes")
        raise OSError(28, "No space left on device")
    assert target.read_bytes() == b"old"
    _no_temporaries(tmp_path)


def _arrays():
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.io.export import filter_arrays, step_arrays
    from beacon_sim.runs.headless import run_headless

    scenario = load_scenario("default")
    result = run_headless(scenario, ["ekf"], seed=3, duration=1.0)
    arrays = step_arrays(scenario, result.steps)
    arrays.update(filter_arrays(result.runner.tracks, len(result.steps)))
    return scenario, arrays


@pytest.fixture(scope="module")
def run_arrays():
    return _arrays()


def test_npz_export_failing_midway_keeps_the_old_file(tmp_path, run_arrays, monkeypatch):
    from beacon_sim.io import export

    _, arrays = run_arrays
    out = tmp_path / "run.npz"
    export.write_export(arrays, out)
    before = out.read_bytes()

    def full_disk(fh, **kw):
        fh.write(b"PK\x03\x04 partial")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(np, "savez_compressed", full_disk)
    with pytest.raises(BeaconSimError, match=r"run\.npz: .*No space left"):
        export.write_export(arrays, out)
    assert out.read_bytes() == before
    monkeypatch.undo()
    assert "truth" in export.load_export(out)
    _no_temporaries(tmp_path)


def test_csv_export_failing_midway_keeps_the_old_file(tmp_path, run_arrays, monkeypatch):
    from beacon_sim.io import export, tables

    _, arrays = run_arrays
    out = tmp_path / "run.csv"
    export.write_export(arrays, out)
    before = out.read_bytes()
    calls = {"n": 0}
    real = tables._cell

    def dies(v):
        calls["n"] += 1
        if calls["n"] > 50:
            raise OSError(28, "No space left on device")
        return real(v)
    monkeypatch.setattr(tables, "_cell", dies)
    with pytest.raises(BeaconSimError, match=r"run\.csv: .*No space left"):
        export.write_export(arrays, out)
    assert out.read_bytes() == before
    _no_temporaries(tmp_path)


def test_mcap_export_failing_midway_keeps_the_old_file(tmp_path, run_arrays, monkeypatch):
    pytest.importorskip("foxglove")
    from beacon_sim.io import foxglove as fg
    from beacon_sim.io.mcap import write_mcap

    scenario, arrays = run_arrays
    out = tmp_path / "run.mcap"
    write_mcap(out, scenario, arrays)
    before = out.read_bytes()
    real = fg.Publisher.tick

    def dies(self, k, *args, **kw):
        if k == 5:
            raise OSError(28, "No space left on device")
        return real(self, k, *args, **kw)
    monkeypatch.setattr(fg.Publisher, "tick", dies)
    with pytest.raises(BeaconSimError, match=r"run\.mcap: .*No space left"):
        write_mcap(out, scenario, arrays)
    assert out.read_bytes() == before
    _no_temporaries(tmp_path)


def test_eval_and_grade_outputs_failing_midway_keep_the_old_files(tmp_path):
    from beacon_sim.evaluation import grading, report

    (tmp_path / "eval.csv").write_text("old eval", encoding="utf-8")
    with pytest.raises(KeyError):  # the first row is broken: nothing of the new table lands
        report.write_outputs(tmp_path, [(None, {"filters": {"ekf": {}}}, None)], {})
    assert (tmp_path / "eval.csv").read_text(encoding="utf-8") == "old eval"
    (tmp_path / "grade.csv").write_text("old grade", encoding="utf-8")
    with pytest.raises(KeyError):  # the header is written, then a row fails
        grading.write_csv({"rows": [{}]}, tmp_path / "grade.csv")
    assert (tmp_path / "grade.csv").read_text(encoding="utf-8") == "old grade"
    _no_temporaries(tmp_path)
