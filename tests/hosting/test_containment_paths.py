"""The bubblewrap child sees its interpreter and the package wherever they are. A checkout
with its virtual environment under /tmp (as a CI clone may be: ``.ci-venv`` inside the
clone) was hidden by the sandbox's empty /tmp when that was mounted after the read-only
binds, and every graded filter died with "execvp ...: No such file or directory"."""

from __future__ import annotations

import io
import shutil
import subprocess

import pytest

from beacon_sim.hosting import containment
from beacon_sim.hosting.containment import Limits, launch


class _Stop(Exception):
    pass


def test_the_empty_tmp_is_mounted_before_every_bind(tmp_path, monkeypatch):
    """bubblewrap mounts in order: /tmp's tmpfs must come before any bind, so a bind under
    /tmp (a checkout, a venv, the package) is laid on top of it, not hidden by it."""
    venv, pkg = tmp_path / "clone" / ".ci-venv", tmp_path / "clone"
    (venv / "bin").mkdir(parents=True)
    (pkg / "beacon_sim").mkdir(exist_ok=True)
    monkeypatch.setattr(containment.sys, "prefix", str(venv))
    monkeypatch.setattr(containment, "package_root", lambda: pkg)
    monkeypatch.setattr(containment.shutil, "which", lambda name: "/usr/bin/bwrap")
    seen: list[list[str]] = []

    def popen(argv, **kwargs):
        seen.append(list(argv))
        raise _Stop

    monkeypatch.setattr(containment.subprocess, "Popen", popen)
    src = tmp_path / "student.py"
    src.write_text("class F: pass\n")
    with pytest.raises(_Stop):
        launch(src, io.BytesIO(), "bwrap", Limits())
    argv = seen[0]
    tmpfs = argv.index("--tmpfs")
    assert argv[tmpfs + 1] == "/tmp"
    binds = [i for i, a in enumerate(argv) if a in ("--ro-bind", "--bind")]
    under_tmp = [i for i in binds if argv[i + 1].startswith("/tmp")]
    assert str(venv) in [argv[i + 1] for i in binds], "the venv inside the checkout is bound"
    assert under_tmp and all(i > tmpfs for i in under_tmp), argv


@pytest.mark.skipif(containment.bwrap_problem() is not None, reason="bubblewrap cannot run here")
def test_a_file_bound_under_tmp_is_visible_in_the_sandbox(tmp_path):
    """The same on the real bubblewrap: a folder under /tmp bound after the tmpfs is seen."""
    (tmp_path / "seen.txt").write_text("here")
    exe = shutil.which("bwrap")
    assert exe
    r = subprocess.run([exe, "--unshare-all", "--die-with-parent", "--tmpfs", "/tmp",
                        "--ro-bind", "/usr", "/usr", "--symlink", "usr/bin", "/bin",
                        "--symlink", "usr/lib", "/lib", "--symlink", "usr/lib64", "/lib64",
                        "--ro-bind", str(tmp_path), str(tmp_path), "cat", str(tmp_path / "seen.txt")],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0 and r.stdout == "here", (r.returncode, r.stderr)
