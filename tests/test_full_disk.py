"""Writes that never destroy the last good copy: a full disk (a real 1 MiB tmpfs, mounted in
a private user and mount namespace where the machine allows it), a kill -9 in the middle of
a write, writers to one path at once, and a decompression bomb read back as an export.

Every front end that writes (export .npz / .csv / .mcap, eval --out, a recording of play,
new-filter, save_map, a screenshot, a GIF) leaves the previous file whole and loadable,
never a 0-byte one, and says in one line which file it could not write.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import sys
import textwrap
import threading
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.core.files import atomic_write
from beacon_sim.errors import BeaconSimError, FileReplacedWarning

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy", "PYTHONPATH": str(ROOT)}
CLI = [sys.executable, "-m", "beacon_sim"]


def _no_temporaries(folder: Path) -> None:
    assert not [p.name for p in folder.rglob("*.tmp")]


def _namespaces_work() -> bool:
    if shutil.which("unshare") is None or sys.platform != "linux":
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c",
                            "d=$(mktemp -d) && mount -t tmpfs -o size=64k none \"$d\""],
                           capture_output=True, timeout=30)
    return probe.returncode == 0


# ------------------------------------------------------------------ a real full disk
FULL_DISK_SCRIPT = r"""
set -u
D="$1"; OUT="$2"
mount -t tmpfs -o size=1m none "$D"
cd "$D"
bs() { "$@" > /dev/null 2> "$OUT/$name.err"; echo $? > "$OUT/$name.rc"; }
# the previous good copies, while there is room
for f in run.npz run.csv run.mcap; do
  $CLI export default --duration 1 --filter ekf --out "$D/$f" > /dev/null 2>&1 || exit 11
done
$CLI eval default --runs 2 --duration 1 --filter ekf --out "$D/ev" > /dev/null 2>&1 || exit 12
mkdir -p "$OUT/before" && cp -a "$D/." "$OUT/before/"
mkdir -p "$D/recordings"
# the disk filled to the last block
dd if=/dev/zero of="$D/filler" bs=4096 > /dev/null 2>&1
for f in run.npz run.csv run.mcap; do
  name="export-$f"; bs $CLI export default --duration 30 --filter ekf --out "$D/$f"
done
name=eval; bs $CLI eval default --runs 2 --duration 30 --filter ekf --out "$D/ev"
truncate -s -16384 "$D/filler"  # room for a recording's header and first ticks
name=play; bs $CLI play default --frames 3000 --autopilot --size 800x600
rm -f "$D/filler"
mkdir -p "$OUT/after" && cp -a "$D/." "$OUT/after/"
"""


@pytest.fixture(scope="module")
def full_disk(tmp_path_factory):
    if not _namespaces_work():
        pytest.skip("no user and mount namespaces here (unshare -rm): the simulated full disks of "
                    "tests/test_safe_files.py still run")
    base = tmp_path_factory.mktemp("fulldisk")
    (base / "mnt").mkdir()
    (base / "out").mkdir()
    script = base / "fill.sh"
    script.write_text(FULL_DISK_SCRIPT, encoding="utf-8")
    env = {**ENV, "CLI": " ".join([sys.executable, "-m", "beacon_sim"])}
    proc = subprocess.run(["unshare", "-rm", "sh", str(script), str(base / "mnt"), str(base / "out")],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return base / "out"


@pytest.mark.parametrize("name", ["run.npz", "run.csv", "run.mcap"])
def test_an_export_on_a_full_disk_keeps_the_previous_file(full_disk, name):
    from beacon_sim.io.export import load_export

    err = (full_disk / f"export-{name}.err").read_text()
    assert (full_disk / f"export-{name}.rc").read_text().strip() == "2"
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert name in err and "No space left" in err
    before, after = full_disk / "before" / name, full_disk / "after" / name
    assert after.stat().st_size > 0 and after.read_bytes() == before.read_bytes()
    if name != "run.mcap":
        assert "truth" in load_export(after)
    _no_temporaries(full_disk / "after")


def test_eval_out_on_a_full_disk_keeps_the_previous_files(full_disk):
    err = (full_disk / "eval.err").read_text()
    assert (full_disk / "eval.rc").read_text().strip() == "2"
    # progress lines (off a terminal, once the runs take over a second: a loaded machine) are
    # not error lines
    err = "\n".join(line for line in err.splitlines() if not re.match(r"eval \S+: \d+/\d+ runs", line))
    assert len(err.strip().splitlines()) <= 2 and "Traceback" not in err and "No space left" in err
    for f in (full_disk / "before" / "ev").iterdir():
        after = full_disk / "after" / "ev" / f.name
        assert after.stat().st_size > 0 and after.read_bytes() == f.read_bytes(), f.name
    _no_temporaries(full_disk / "after")


def test_a_recording_on_a_full_disk_names_the_file_and_replays(full_disk):
    from beacon_sim.io.recording import load_recording

    err = (full_disk / "play.err").read_text()
    assert (full_disk / "play.rc").read_text().strip() == "2", err
    assert len(err.strip().splitlines()) <= 2 and "Traceback" not in err
    files = list((full_disk / "after" / "recordings").glob("*.jsonl"))
    assert len(files) == 1 and files[0].name in err and "No space left" in err
    rec = load_recording(files[0])  # what fitted: a header and whole ticks
    assert rec.ticks and not rec.complete


# ------------------------------------------------------------------ kill -9 midway
KILLED = """
import os, signal, sys
import numpy as np
from beacon_sim.io import tables
from beacon_sim.evaluation import report

def die(*args, **kw):
    fh = args[0] if args and hasattr(args[0], "write") else None
    if fh is not None:
        fh.write(b"PK\\x03\\x04 half a file" if "b" in getattr(fh, "mode", "b") else "half,a,row")
        fh.flush()
    os.kill(os.getpid(), signal.SIGKILL)

if sys.argv[1] == "npz":
    np.savez_compressed = die
elif sys.argv[1] == "csv":
    real = tables._cell
    n = [0]
    def cell(v):
        n[0] += 1
        if n[0] == 40:
            die()
        return real(v)
    tables._cell = cell
elif sys.argv[1] == "eval":
    report.json.dump = die
from beacon_sim.cli.main import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("kind, args, name", [
    ("npz", ["export", "default", "--duration", "1", "--filter", "ekf", "--out", "{d}/run.npz"], "run.npz"),
    ("csv", ["export", "default", "--duration", "1", "--filter", "ekf", "--out", "{d}/run.csv"], "run.csv"),
    ("eval", ["eval", "default", "--runs", "2", "--duration", "1", "--filter", "ekf", "--out", "{d}"],
     "eval.json"),
])
def test_kill_9_in_the_middle_of_a_write_keeps_the_previous_file(tmp_path, kind, args, name):
    from beacon_sim.cli.main import main

    argv = [a.format(d=tmp_path) for a in args]
    assert main(argv) == 0
    before = (tmp_path / name).read_bytes()
    proc = subprocess.run([sys.executable, "-c", KILLED, kind, *argv], env=ENV, capture_output=True,
                          timeout=300)
    assert proc.returncode == -9, proc.stderr[-1000:]
    assert (tmp_path / name).read_bytes() == before and before
    # a kill may leave its hidden temporary file: never the target, and the next write is whole
    assert main(argv) == 0
    assert (tmp_path / name).stat().st_size > 0


# ------------------------------------------------------------------ writers at once
def test_writers_to_one_path_each_write_their_own_file_and_the_later_says_so(tmp_path):
    target = tmp_path / "run.csv"
    first_open = threading.Event()
    second_done = threading.Event()
    caught: list[warnings.WarningMessage] = []

    def first() -> None:
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            with atomic_write(target, "w", what="export") as fh:
                fh.write("first\n")
                first_open.set()
                second_done.wait(30)
            caught.extend(w)

    t = threading.Thread(target=first)
    t.start()
    first_open.wait(30)
    with atomic_write(target, "w", what="export") as fh:  # begun after, finished before
        fh.write("second\n")
    second_done.set()
    t.join(30)
    assert target.read_text() == "first\n"  # whole, never a mixture
    assert [str(w.message) for w in caught if issubclass(w.category, FileReplacedWarning)] == [
        f"{target}: another writer wrote this export while this one was being written; "
        "this one replaced it"]
    _no_temporaries(tmp_path)


def test_three_exports_at_once_each_land_whole_and_the_later_ones_say_so(tmp_path):
    out = tmp_path / "run.npz"
    procs = [subprocess.Popen([*CLI, "export", "default", "--duration", "3", "--filter", "ekf",
                               "--seed", str(s), "--out", str(out)], env=ENV,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for s in (1, 2, 3)]
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0]
    from beacon_sim.io.export import load_export

    assert "truth" in load_export(out)
    for e in errs:
        assert "Traceback" not in e and len(e.strip().splitlines()) <= 1
        if e.strip():
            assert e.startswith(f"beacon-sim: note: {out}: another writer wrote this export")
    _no_temporaries(tmp_path)


# ------------------------------------------------------------------ the other writers
def test_save_map_new_filter_screenshot_and_gif_keep_the_old_file_on_a_full_disk(tmp_path, monkeypatch):
    from beacon_sim.core import files
    from beacon_sim.core.occupancy import OccupancyGrid, save_map
    from beacon_sim.errors import UsageError

    real_open = open

    def full_open(path, mode="r", *a, **kw):
        fh = real_open(path, mode, *a, **kw)
        if "w" in mode:
            def write(data, _w=fh.write):
                _w(data[: len(data) // 2])
                raise OSError(28, "No space left on device")
            fh.write = write
        return fh

    grid = OccupancyGrid(np.zeros((4, 5), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    save_map(grid, tmp_path / "m.yaml")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    monkeypatch.setattr(files, "open", full_open, raising=False)
    with pytest.raises(BeaconSimError, match=r"m\.(pgm|yaml): cannot write the map .*No space left"):
        save_map(grid, tmp_path / "m.yaml")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before

    import argparse

    from beacon_sim.cli.new_filter import new_filter_command
    with pytest.raises(UsageError, match=r"mine\.py: cannot write the filter file: No space left"):
        new_filter_command(argparse.Namespace(path=str(tmp_path / "mine.py")))
    assert not (tmp_path / "mine.py").exists()
    _no_temporaries(tmp_path)


def test_a_screenshot_and_a_gif_are_written_whole(tmp_path, monkeypatch):
    pytest.importorskip("PIL")
    from beacon_sim.cli.main import main

    shot, gif = tmp_path / "shot.png", tmp_path / "run.gif"
    assert main(["play", "default", "--frames", "3", "--no-record", "--size", "800x600",
                 "--screenshot", str(shot), "--gif", str(gif)]) == 0
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and gif.read_bytes()[:6] == b"GIF89a"
    _no_temporaries(tmp_path)


# ------------------------------------------------------------------ reading an export back
def test_an_npz_that_would_unpack_past_the_cap_is_refused_before_unpacking(tmp_path, monkeypatch):
    from beacon_sim.io import export

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("truth.npy", b"\0" * (8 * 2**20))  # 8 MiB of zeros: a few KiB packed
    bomb = tmp_path / "bomb.npz"
    bomb.write_bytes(buf.getvalue())
    assert bomb.stat().st_size < 64 * 1024
    monkeypatch.setattr(export, "MAX_EXPORT_BYTES", 2**20)
    with pytest.raises(ValueError, match=r"bomb\.npz: unpacks to 8,388,608 bytes: an export holds at "
                                         r"most 1,048,576"):
        export.load_export(bomb)
    (tmp_path / "junk.npz").write_bytes(b"not a zip at all")
    with pytest.raises(ValueError, match=r"junk\.npz: not a \.npz export"):
        export.load_export(tmp_path / "junk.npz")


def test_an_mrclam_file_that_is_a_fifo_is_one_line(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("needs FIFOs")
    from beacon_sim.io.mrclam import MrclamError, read_table

    os.mkfifo(tmp_path / "Barcodes.dat")
    with pytest.raises(MrclamError, match=r"Barcodes\.dat: a FIFO \(named pipe\), not a MRCLAM data file"):
        read_table(tmp_path / "Barcodes.dat", 2, "subject barcode")


def test_the_kill_script_is_valid_python():
    compile(textwrap.dedent(KILLED), "killed", "exec")
