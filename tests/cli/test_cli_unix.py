"""The command line as a Unix tool: quiet when the reader of its output leaves
(``beacon-sim list | head``), and every option and argument has a help text."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from beacon_sim.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[2]


def _run_into_a_closed_pipe(argv: list[str]) -> subprocess.CompletedProcess:
    """Run ``beacon-sim ARGV`` with stdout a pipe whose reader has already gone (what
    ``| head`` leaves once it has its lines): every write fails with EPIPE."""
    read, write = os.pipe()
    os.close(read)
    try:
        env = {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy"}
        return subprocess.run([sys.executable, "-m", "beacon_sim.cli.main", *argv], stdout=write,
                              stderr=subprocess.PIPE, text=True, env=env, timeout=300)
    finally:
        os.close(write)


def test_list_into_a_closed_pipe_is_quiet():
    out = _run_into_a_closed_pipe(["list"])
    assert out.stderr == ""                  # no "Broken pipe", no traceback
    assert out.returncode in (0, 141)         # 141 = 128 + SIGPIPE, as head's writers


def test_list_piped_into_head_shell(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = f"{sys.executable} -m beacon_sim.cli.main list 2>{tmp_path / 'err'} | head -n 2"
    out = subprocess.run(["bash", "-c", cmd + "; echo status ${PIPESTATUS[0]}"], capture_output=True,
                         text=True, env=env, timeout=300)
    lines = out.stdout.splitlines()
    assert len(lines) == 3 and lines[0] == "scenarios:"  # head's two lines, then the status
    assert lines[-1] in ("status 0", "status 141")
    assert (tmp_path / "err").read_text() == ""


def _actions(parser: argparse.ArgumentParser, prefix: str = ""):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _actions(sub, f"{prefix}{name} ")
        elif not isinstance(action, argparse._HelpAction | argparse._VersionAction):
            yield prefix, action


def test_every_option_and_argument_has_a_help_text():
    missing = [f"{cmd}{a.option_strings[0] if a.option_strings else a.dest}"
               for cmd, a in _actions(build_parser()) if not a.help]
    assert missing == []
