"""No absolute path of one machine in what the project ships: the code, tests,
docs, README, scripts, benchmarks, examples and scenarios name no checkout, home or shared
folder. Data sets are found through BEACON_SIM_MRCLAM (docs/mrclam.md), files by paths
relative to the checkout or the package. System paths (/proc, /dev, /tmp, /usr, /etc,
/opt, ...) are fine: every machine has them, and the attack tests name them on purpose."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: What is searched: folders (every text file in them) and single files of the checkout.
SEARCHED = ("beacon_sim", "tests", "docs", "scripts", "benchmarks", "examples", "scenarios",
            "assets", ".ci", "README.md", "CHANGELOG.md", "pyproject.toml")
#: Never searched: caches and environments that a run leaves in the checkout.
SKIPPED_FOLDERS = {"__pycache__", ".venv", ".ci-venv", ".mypy_cache", ".ruff_cache",
                   ".pytest_cache", ".import_linter_cache"}

#: A path in front of which stands a letter, digit, dot, tilde or hyphen is part of
#: something else (a URL's path, ``a/home/b``): not a path from the root.
_START = r"(?<![\w.~-])"
#: Absolute paths of one machine's folders, and what they are.
MACHINE_PATHS = {
    "a checkout or the shared folder on the project's machines": _START + r"/(?:work|workspace)/",
    "a user's home (Linux)": _START + r"/home/[\w.-]+",
    "root's home": _START + r"/root(?![\w.-])",
    "a user's home (macOS)": _START + r"/Users/[\w.-]+",
    "a mounted disk": _START + r"/(?:mnt|media)/[\w.-]+",
    "a user's home (Windows)": r"\b[A-Za-z]:(?:\\{1,2}|/)Users\b",
    "a folder in a home, by tilde": r"(?<![\w~])~[\w.-]*/[\w.-]*",
}
PATTERN = re.compile("|".join(f"(?:{p})" for p in MACHINE_PATHS.values()))

#: What may match, and why; keep it small. (file relative to the checkout, the text matched)
ALLOWED: dict[tuple[str, str], str] = {
    # A tool's per-user configuration folder: the same place on every machine, not one
    # machine's folder (Dask reads its worker settings there).
    ("docs/performance.md", "~/.config"): "dask's configuration folder",
}
#: Files not searched, and why.
ALLOWED_FILES = {
    # this file spells the patterns out
    "tests/project/test_no_machine_paths.py",
    # Recordings written by earlier versions, kept as they were written (the format tests
    # read them byte for byte): their header's "scenario_source" is the path of the
    # scenario on the machine that recorded it, as the recorder wrote it then.
    "tests/data/old_recordings/v1_sparse_kidnap.jsonl",
    "tests/data/old_recordings/v2_sparse_kidnap.jsonl",
    "tests/data/old_recordings/v2_team_sparse.jsonl",
    "tests/data/old_recordings/v3_sparse_kidnap.jsonl",
    "tests/data/old_recordings/v3_team_sparse.jsonl",
}


def _text_files() -> list[Path]:
    files: list[Path] = []
    for name in SEARCHED:
        top = ROOT / name
        if top.is_file():
            files.append(top)
        elif top.is_dir():
            files += [f for f in top.rglob("*") if f.is_file()
                      and not SKIPPED_FOLDERS & set(f.relative_to(ROOT).parts)]
    return sorted(files)


def machine_paths(text: str) -> list[tuple[int, str]]:
    """(line number, text matched) of each absolute path of a machine's folder in ``text``."""
    return [(n, m.group(0)) for n, line in enumerate(text.splitlines(), 1)
            for m in PATTERN.finditer(line)]


def test_the_patterns_catch_machine_paths_and_spare_system_paths():
    caught = ["/work/main/tests", "see /workspace/x", "/home/alice/data", "/root/.pyenv",
              "'/root'", "/Users/bob/mrclam", "/mnt/data/Dataset6", r"C:\Users\carol", "C:/Users/x",
              "~/mrclam/Dataset6", "~alice/data"]
    spared = ["/proc/self/status", "/dev/null", "/tmp/x", "/usr/bin/python", "/etc/passwd",
              "/opt/python", "/sandbox/work", "../shared/data/mrclam", "https://example.org/home/a",
              "tests/data/x", "a/root/b", "/rootfs", "x = ~mask", "~~struck~~"]
    assert all(machine_paths(s) for s in caught), [s for s in caught if not machine_paths(s)]
    assert not any(machine_paths(s) for s in spared), [s for s in spared if machine_paths(s)]


def test_no_absolute_path_of_a_machine_in_the_project():
    files = _text_files()
    assert len(files) > 100 and ROOT / "README.md" in files
    hits = []
    for f in files:
        rel = f.relative_to(ROOT).as_posix()
        if rel in ALLOWED_FILES:
            continue
        try:
            text = f.read_text(encoding="utf-8")
        except UnicodeDecodeError:  # images, pickles: not text
            continue
        hits += [f"{rel}:{n}: {what}" for n, what in machine_paths(text) if (rel, what) not in ALLOWED]
    assert not hits, ("absolute paths of one machine (use a path relative to the checkout, "
                      "BEACON_SIM_MRCLAM, or a placeholder such as DIR):\n" + "\n".join(hits))


def test_the_allow_list_is_still_needed():
    """An allowed file or text that no longer holds a match is taken off the list."""
    for rel in ALLOWED_FILES - {"tests/project/test_no_machine_paths.py"}:
        assert machine_paths((ROOT / rel).read_text(encoding="utf-8")), rel
    for (rel, what), _why in ALLOWED.items():
        assert what in [w for _, w in machine_paths((ROOT / rel).read_text(encoding="utf-8"))], rel
