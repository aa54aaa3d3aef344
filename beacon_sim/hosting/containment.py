"""How a student's child process is started and contained (docs/grading.md, "What grading
protects against").

Two levels:

- ``process``: a fresh interpreter (``python -s -B -m beacon_sim.hosting.child``), an empty
  temporary working directory, the pipes on stdin and stdout (moved by the child to fresh
  descriptors, stdin then closed and stdout and stderr to the student's log, cut at
  ``log_bytes``), a scrubbed environment, its own session (so the whole group can be
  stopped), resource limits (address space, CPU seconds, file size, no core files) set by
  the child before any student code runs, a system call filter refusing new processes,
  signals to other processes and tracing (:mod:`beacon_sim.hosting.syscall_filter`), and a
  user of its own when the grader is root (:mod:`beacon_sim.hosting.child_users`).
- ``bwrap``: the same inside bubblewrap (Debian's ``bubblewrap``): no network, new PID,
  IPC and UTS namespaces, an unprivileged user namespace, a read-only view of the system,
  the Python installation and the ``beacon_sim`` package alone, the student's own file
  read-only, and nothing else of the machine (no other student's file, no grading output).

``auto`` chooses ``bwrap`` when it works on this machine, else ``process``.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:
    from beacon_sim.hosting.child_users import UidLease

SANDBOXES = ("auto", "bwrap", "process")
NOBODY = 65534
#: Where the child sees its working directory and its file inside bubblewrap.
BOX_WORK = "/sandbox/work"
BOX_SRC = "/sandbox/submission"
#: What the child is asked to load for a module filter: this, then the module's name.
MODULE_PREFIX = "module:"


class SandboxError(ValueError):
    """A sandbox level that cannot work here (one line, exit status 2)."""


@dataclass(frozen=True)
class ModuleSource:
    """A filter named by module (``pkg.mod:Class``, or an entry point's module): the module's
    dotted name and the files of its top-level package (its folders, or its one file),
    which the child gets as a read-only copy in its own folder, first on its import path."""

    module: str
    roots: tuple[Path, ...]

    @property
    def name(self) -> str:
        return self.module

    def origin(self) -> Path | None:
        """The module's own file in the grader's copy (None: not found), read without
        running it."""
        parts = self.module.split(".")
        for root in self.roots:
            if root.is_file():
                return root if len(parts) == 1 else None
            base = root.joinpath(*parts[1:])
            for p in (base / "__init__.py", base.with_suffix(".py")):
                if p.is_file():
                    return p
        return None


def module_source(module: str) -> ModuleSource | None:
    """Where the module ``module`` comes from, found without running any of its code (only
    its top-level package is looked up); None when it is not importable from a file."""
    top = module.partition(".")[0]
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    if spec.submodule_search_locations:
        roots = tuple(Path(p) for p in spec.submodule_search_locations if Path(p).is_dir())
    elif spec.origin and Path(spec.origin).is_file():
        roots = (Path(spec.origin),)
    else:
        return None
    return ModuleSource(module, roots) if roots else None


def _copy_module(source: ModuleSource, dest: Path) -> None:
    """Copy the module's top-level package into ``dest`` (no byte code), read-only."""
    for root in source.roots:
        if root.is_dir():
            shutil.copytree(root, dest / root.name, ignore=shutil.ignore_patterns("__pycache__"),
                            dirs_exist_ok=True)
        else:
            shutil.copyfile(root, dest / root.name)
    for d, dirs, files in os.walk(dest):
        for f in files:
            os.chmod(os.path.join(d, f), 0o444)
        for sub in dirs:
            os.chmod(os.path.join(d, sub), 0o555)


@dataclass(frozen=True)
class Limits:
    """A child's limits: address space [GB] (0: none), CPU time of the whole child [s]
    (None: none), the size of any file it writes [bytes], its log [bytes], all it may
    write [bytes] (under bubblewrap the sizes of its RAM file systems: half for its
    working folder, a quarter each for /tmp and /dev/shm; at the process level measured
    by :func:`disk_used`)."""

    memory_gb: float = 4.0
    cpu_s: float | None = None
    fsize_bytes: int = 8 << 20
    log_bytes: int = 256 << 10
    disk_bytes: int = 64 << 20


@functools.lru_cache(maxsize=1)
def bwrap_problem() -> str | None:
    """Why bubblewrap cannot run a sandbox here (not installed, no user namespaces), or None."""
    exe = shutil.which("bwrap")
    if exe is None:
        return "bwrap is not installed (Debian: apt-get install bubblewrap)"
    try:
        r = subprocess.run([exe, "--unshare-all", "--die-with-parent", "--ro-bind", "/", "/",
                            "--dev", "/dev", "--proc", "/proc", "true"],
                           capture_output=True, timeout=30, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"bwrap does not run: {exc}"
    if r.returncode != 0:
        err = r.stderr.decode("utf-8", "replace").strip().splitlines()
        return f"bwrap does not work here: {err[0] if err else 'status ' + str(r.returncode)}"
    return None


def resolve_sandbox(choice: str) -> str:
    """``auto`` -> ``bwrap`` where it works, else ``process``; ``bwrap`` where it cannot
    work raises :class:`SandboxError` naming why."""
    if choice not in SANDBOXES:
        raise SandboxError(f"--sandbox {choice}: expected one of {', '.join(SANDBOXES)}")
    if choice == "process":
        return "process"
    why = bwrap_problem()
    if why is None:
        return "bwrap"
    if choice == "bwrap":
        raise SandboxError(f"--sandbox bwrap: {why}")
    return "process"


def unisolated_warning(root: bool | None = None, kernel: str | None = "?") -> str:
    """What the process level does not stop, in words for the page and the terminal.
    ``root``: the grader is root (each child then runs as a user of its own, default: this
    process's user); ``kernel``: why the child's system call filter is not installed
    (:func:`~beacon_sim.hosting.syscall_filter.unavailable`; None: it is)."""
    from beacon_sim.hosting.syscall_filter import unavailable

    if root is None:
        root = hasattr(os, "geteuid") and os.geteuid() == 0
    if kernel == "?":
        kernel = unavailable()
    head = "NOT ISOLATED: graded at the process level, without bubblewrap. "
    tail = ". Install bubblewrap (Debian: apt-get install bubblewrap) for isolated grades."
    if root:
        return (head + "Each student's process ran as a user of its own (from a reserved range), so "
                "classmates could not signal, read or write each other's processes and files, and what "
                "one left in /tmp and /dev/shm was removed after it"
                + ("; the kernel refused it new processes and tracing" if kernel is None else
                   f"; but no system call filter here ({kernel}): a process it starts by undoing the "
                   "grader's subreaper could outlive its grade until its user is swept")
                + ". Still open: the network, and everything on the machine that any user may read" + tail)
    return (head + "Every student's process ran as the grader's own user, so a file could read what that "
            "user can read (the grader's memory through /proc, the grade's secret and the other "
            "submissions) and leave files in /tmp and /dev/shm for later students"
            + ("; the kernel refused it new processes, signals to other processes and tracing"
               if kernel is None else ", signal, slow or kill its classmates' processes, and start a "
               "process that outlives its grade by undoing the grader's subreaper")
            + tail)


def package_root() -> Path:
    """The folder that holds the ``beacon_sim`` package this grader runs."""
    return Path(__file__).resolve().parents[2]  # beacon_sim/hosting/containment.py


def child_env(home: str, extra_path: str | None = None) -> dict[str, str]:
    """The child's whole environment: nothing of the grader's but what Python needs
    (``extra_path``: a module filter's copy, after the package on the import path)."""
    path = str(package_root()) + (os.pathsep + extra_path if extra_path else "")
    return {"PATH": "/usr/local/bin:/usr/bin:/bin", "PYTHONPATH": path,
            "HOME": home, "TMPDIR": home, "LANG": "C.UTF-8", "PYTHONHASHSEED": "0",
            "PYTHONDONTWRITEBYTECODE": "1", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
            "MKL_NUM_THREADS": "1"}


def _ro_binds() -> list[str]:
    """bubblewrap arguments binding the system, the Python installation and the package
    read-only (each path once, the package alone of its folder)."""
    args: list[str] = []
    for top in ("/usr", "/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"):
        p = Path(top)
        if p.is_symlink():
            args += ["--symlink", os.readlink(p), top]
        elif p.is_dir():
            args += ["--ro-bind", top, top]
    for f in ("/etc/ld.so.cache", "/etc/localtime", "/etc/passwd", "/etc/group"):
        if Path(f).exists():
            args += ["--ro-bind", f, f]
    root = package_root()
    prefixes = {Path(sys.base_prefix).resolve(), Path(sys.prefix).resolve()}
    checkout = not any(root.is_relative_to(x) for x in prefixes)
    seen: list[Path] = []
    for p in [*prefixes, *(Path(q).resolve() for q in sys.path if q and Path(q).is_dir())]:
        in_prefix = any(p.is_relative_to(x) for x in prefixes)  # the interpreter, its site-packages
        if checkout and not in_prefix and (root.is_relative_to(p) or p.is_relative_to(root)):
            continue  # a checkout (the package's folder, its tests): only the package is bound
        # (a virtual environment inside the checkout, as CI's .ci-venv, is bound: the child
        # needs its interpreter and site-packages; the rest of the checkout stays unseen)
        if p == Path("/") or str(p).startswith(("/usr", "/bin", "/lib", "/proc", "/dev")):
            continue
        if any(p.is_relative_to(q) for q in seen):
            continue
        seen = [q for q in seen if not q.is_relative_to(p)] + [p]
    for p in seen:
        args += ["--ro-bind", str(p), str(p)]
    exe = Path(sys.executable)
    if exe.is_symlink():  # the venv's python points into the base installation
        target = exe.resolve()
        if not any(target.is_relative_to(s) for s in seen):
            args += ["--ro-bind", str(target), str(target)]
    args += ["--ro-bind", str(root / "beacon_sim"), str(root / "beacon_sim")]
    return args


def hide_memory() -> bool:
    """Make this process (the one that starts children: the grader or its worker, which
    hold the truth) not dumpable (Linux ``PR_SET_DUMPABLE`` 0), so that a child of the same
    user cannot open its ``/proc/<pid>/mem``, ``maps`` or ``environ``; whether it is so."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(4, 0, 0, 0, 0) == 0  # PR_SET_DUMPABLE
    except (OSError, AttributeError):
        return False


@dataclass
class Launched:
    """A started child: the process, the grader's ends of the pipes, its temporary folder
    and what it was started with."""

    proc: subprocess.Popen[bytes]
    to_child: int
    from_child: int
    tmp: Path
    sandbox: str
    source_in_child: str
    #: The child's own user (a root grader at the process level), given back by ``close``.
    lease: UidLease | None = None


def launch(source: Path | ModuleSource, log: IO[bytes], sandbox: str, limits: Limits) -> Launched:
    """Start a child for the filter file ``source`` (copied read-only into the child's own
    folder), or the module filter's package (copied the same way, imported by name), with
    stdout and stderr to ``log``. ``sandbox``: ``bwrap`` or ``process``."""
    tmp = Path(tempfile.mkdtemp(prefix="beacon-sim-child-"))
    src, work = tmp / "src", tmp / "work"
    src.mkdir()
    work.mkdir()
    module = isinstance(source, ModuleSource)
    if isinstance(source, ModuleSource):
        _copy_module(source, src)
        copy = src
    else:
        copy = src / source.name
        shutil.copyfile(source, copy)
        os.chmod(copy, 0o444)
    root = hasattr(os, "geteuid") and os.geteuid() == 0
    os.chmod(src, 0o555)
    os.chmod(tmp, 0o755)
    drop = root and sandbox == "process"
    if sandbox == "process":
        hide_memory()
    lease = None
    if drop:  # a user of its own: classmates cannot read, write, signal or trace it
        from beacon_sim.hosting.child_users import give_to, lease_uid

        lease = lease_uid()
        give_to(lease.uid, tmp, src, work)
    r_child, w_parent = os.pipe()
    r_parent, w_child = os.pipe()
    cfg: dict[str, Any] = {
        "memory_bytes": int(limits.memory_gb * 2**30) if limits.memory_gb > 0 else 0,
        "cpu_s": int(limits.cpu_s) + 1 if limits.cpu_s else 0,
        "fsize_bytes": limits.fsize_bytes, "log_bytes": limits.log_bytes, "drop_user": drop,
        "uid": lease.uid if lease is not None else NOBODY}
    # The pipes are the child's stdin (requests) and stdout (replies), which it moves to
    # fresh descriptors before any student code runs: its command line holds no descriptor
    # numbers of the grader's (they told one grading process from another).
    child = [sys.executable, "-s", "-B", "-m", "beacon_sim.hosting.child", json.dumps(cfg)]
    if sandbox == "bwrap":
        env = child_env(BOX_WORK, BOX_SRC if module else None)
        argv = [shutil.which("bwrap") or "bwrap", "--unshare-all", "--die-with-parent",
                # an empty /tmp first: a bind made before it (a checkout or a virtual
                # environment under /tmp, as a CI clone may be) would be hidden by it
                "--new-session", "--clearenv", "--size", str(max(limits.disk_bytes // 4, 4096)),
                "--tmpfs", "/tmp", *_ro_binds(),
                "--dev", "/dev", "--proc", "/proc",
                # what it writes is in RAM, capped (nothing reaches the machine's disk)
                "--size", str(max(limits.disk_bytes // 4, 4096)), "--tmpfs", "/dev/shm",
                "--size", str(max(limits.disk_bytes // 2, 4096)), "--tmpfs", BOX_WORK,
                "--ro-bind", str(src), BOX_SRC,
                "--chdir", BOX_WORK, "--uid", str(NOBODY), "--gid", str(NOBODY)]
        for k, v in env.items():
            argv += ["--setenv", k, v]
        argv += child
        source_in_child = f"{BOX_SRC}/{source.name}"
        popen_env = {"PATH": "/usr/bin:/bin"}
    else:
        argv = child
        source_in_child = str(copy)
        popen_env = child_env(str(work), str(src) if module else None)
    if module:
        source_in_child = MODULE_PREFIX + source.name
    try:
        proc = subprocess.Popen(argv, stdin=r_child, stdout=w_child, stderr=log,
                                cwd=str(work), env=popen_env, start_new_session=True, close_fds=True)
    except BaseException:
        if lease is not None:
            lease.release()
        raise
    finally:
        os.close(r_child)
        os.close(w_child)
    return Launched(proc, w_parent, r_parent, tmp, sandbox, source_in_child, lease)


def disk_used(work: Path, uid: int | None = None) -> int:
    """What a child at the process level has written [bytes, allocated]: its working
    folder, and with its own user ``uid`` (a root grader) what that user owns at the top of
    ``/dev/shm`` and ``/var/tmp`` (``/tmp``, often crowded, is not measured: what the user
    left there is removed when the child ends)."""

    def walk(p: str) -> int:
        total = 0
        try:
            st = os.lstat(p)
        except OSError:
            return 0
        total += st.st_blocks * 512
        if os.path.isdir(p) and not os.path.islink(p):
            try:
                names = os.listdir(p)
            except OSError:
                return total
            for n in names:
                total += walk(os.path.join(p, n))
        return total

    used = walk(str(work))
    if uid is not None:
        for top in ("/dev/shm", "/var/tmp"):
            try:
                entries = list(os.scandir(top))
            except OSError:
                continue
            for e in entries:
                try:
                    if e.stat(follow_symlinks=False).st_uid == uid:
                        used += walk(e.path)
                except OSError:
                    continue
    return used


def exit_reason(returncode: int | None, sandbox: str, limits: Limits) -> str:
    """Why a child ended, in words: its exit status, its signal (and the limit that sends
    it), or that it was stopped."""
    import signal

    if returncode is None:
        return "the filter's process did not answer and was stopped"
    sig = -returncode if returncode < 0 else (returncode - 128 if sandbox == "bwrap" and returncode > 128
                                               else 0)
    if sig > 0:
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = f"signal {sig}"
        extra = {"SIGXCPU": f" (its CPU time limit, {limits.cpu_s:g} s)" if limits.cpu_s else
                 " (its CPU time limit)",
                 "SIGXFSZ": f" (its file size limit, {limits.fsize_bytes} bytes: an output flood?)",
                 "SIGKILL": (f" (killed: its memory limit is {limits.memory_gb:g} GB, or it was stopped)"
                             if limits.memory_gb else " (killed)"),
                 "SIGSEGV": " (a crash in compiled code, or its memory limit)"}.get(name, "")
        return f"the filter's process was killed by {name}{extra}"
    return f"the filter's process exited with status {returncode}"


__all__ = ["MODULE_PREFIX", "SANDBOXES", "Launched", "Limits", "ModuleSource", "SandboxError",
           "bwrap_problem", "child_env", "disk_used", "exit_reason", "hide_memory", "launch", "module_source",
           "package_root", "resolve_sandbox", "unisolated_warning"]
