"""The kernel refuses a student's child a new process, a signal to another process and
tracing (:mod:`beacon_sim.hosting.syscall_filter`), even after the file undoes the
subreaper setting, while threads (Python's, numpy's BLAS threads) still start.

The filter's program is checked on both architectures it knows by running it (a BPF
interpreter of its few instructions); the kernel's refusal in a real process that installs
it (a grandchild of the test, so that the "parent" it tries to kill is a disposable one);
and a graded file that tries everything through ctypes."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import textwrap

import pytest

from beacon_sim.evaluation.grading import GradeConfig, grade
from beacon_sim.hosting.syscall_filter import AUDIT_ARCH, NUMBERS, program, run_program, unavailable

ALLOW = 0x7FFF0000
EPERM = 0x00050000 | errno.EPERM
ENOSYS = 0x00050000 | errno.ENOSYS
PID = 4242
CLONE_THREAD_FLAGS = 0x3D0F00  # what the C library passes for a thread
SIGCHLD = 17


@pytest.mark.parametrize("arch", sorted(AUDIT_ARCH))
def test_the_program_refuses_processes_signals_and_tracing_and_allows_threads(arch):
    prog = program(arch, PID)
    col = 0 if arch == "x86_64" else 1
    a = AUDIT_ARCH[arch]

    def ask(name, *args):
        return run_program(prog, NUMBERS[name][col], a, args)

    for name in ("execve", "execveat", "ptrace", "process_vm_readv", "process_vm_writev", "tkill",
                 "pidfd_send_signal", "pidfd_getfd", "perf_event_open"):
        assert ask(name) == EPERM, name
    if arch == "x86_64":
        assert ask("fork") == EPERM and ask("vfork") == EPERM
    else:
        assert NUMBERS["fork"][1] is None  # aarch64 forks through clone
    assert ask("clone", SIGCHLD) == EPERM  # a process
    assert ask("clone", CLONE_THREAD_FLAGS) == ALLOW  # a thread
    assert ask("clone3") == ENOSYS  # the C library falls back to clone
    assert ask("kill", PID, 9) == ALLOW and ask("tgkill", PID, 7, 10) == ALLOW  # itself
    for pid in (1, PID + 1, 0, 2**32 - 1):  # the parent, a classmate, its group, everyone (-1)
        assert ask("kill", pid, 9) == EPERM, pid
        assert ask("rt_sigqueueinfo", pid, 9) == EPERM, pid
    assert ask("prlimit64", 0) == ALLOW and ask("prlimit64", PID) == ALLOW and ask("prlimit64", 77) == EPERM
    assert ask("sched_setaffinity", 0) == ALLOW and ask("sched_setaffinity", 77) == EPERM
    assert ask("setpriority", 0, 0, 5) == ALLOW  # itself
    assert ask("setpriority", 0, 77, 5) == EPERM and ask("setpriority", 2, 0, 19) == EPERM  # a user's
    assert run_program(prog, 0, a) == ALLOW  # an ordinary call (read on x86_64, io_setup on aarch64)
    other = 0x40000003  # i386's arch word: the 32-bit calls of an x86_64 process
    assert run_program(prog, 2, other) == EPERM
    if arch == "x86_64":
        assert run_program(prog, 0x40000000 + 57, a) == EPERM  # x32's fork


ATTACK = textwrap.dedent("""
    import ctypes, json, os, signal, sys, threading
    from beacon_sim.hosting.syscall_filter import NUMBERS, install, machine

    why = install()
    assert why is None, why
    libc = ctypes.CDLL(None, use_errno=True)
    col = 0 if machine() == "x86_64" else 1
    ppid = os.getppid()
    out = {}

    def sc(name, *args):
        nr = NUMBERS[name][col]
        if nr is None:
            return None
        ctypes.set_errno(0)
        rc = libc.syscall(ctypes.c_long(nr), *[ctypes.c_long(x) for x in args])
        if rc == 0 and name in ("fork", "clone"):
            os._exit(0)  # a child: the filter failed (the parent's answer says so)
        return [rc, ctypes.get_errno()]

    out["undo_subreaper"] = libc.prctl(36, 0, 0, 0, 0)
    ctypes.set_errno(0)
    out["undo_no_new_privs"] = [libc.prctl(38, 0, 0, 0, 0), ctypes.get_errno()]
    out["fork"] = sc("fork")
    out["clone_process"] = sc("clone", signal.SIGCHLD, 0, 0, 0, 0)
    out["clone3"] = sc("clone3", 0, 0)
    argv = (ctypes.c_char_p * 2)(b"/bin/true", None)
    ctypes.set_errno(0)
    out["execve"] = [libc.execve(b"/bin/true", argv, argv), ctypes.get_errno()]
    out["ptrace_parent"] = sc("ptrace", 16, ppid, 0, 0)  # PTRACE_ATTACH
    out["read_parent_memory"] = sc("process_vm_readv", ppid, 0, 0, 0, 0, 0)
    out["kill_parent"] = sc("kill", ppid, signal.SIGKILL)
    out["kill_itself"] = sc("kill", os.getpid(), 0)
    try:
        os.fork()
        out["os_fork"] = "forked"
    except PermissionError as exc:
        out["os_fork"] = str(exc)
    import numpy as np  # its BLAS threads start here, under the filter
    a = np.random.default_rng(1).standard_normal((400, 400))
    out["blas"] = bool(np.allclose(a @ np.linalg.inv(a), np.eye(400), atol=1e-8))
    done = []
    ts = [threading.Thread(target=lambda: done.append(sum(range(10000)))) for _ in range(4)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    out["python_threads"] = len(done)
    out["threads_now"] = len(os.listdir("/proc/self/task"))
    print(json.dumps(out))
""")
PARENT = textwrap.dedent("""
    import os, subprocess, sys
    r = subprocess.run([sys.executable, "-c", sys.argv[1]], capture_output=True, text=True,
                       env={**os.environ, "OPENBLAS_NUM_THREADS": "4"})
    print(r.stdout.strip())
    print(r.stderr.strip()[-2000:], file=sys.stderr)
    print("parent alive")
""")


@pytest.mark.skipif(unavailable() is not None, reason=f"no system call filter here: {unavailable()}")
def test_the_kernel_refuses_a_process_a_signal_and_tracing_after_the_subreaper_is_undone():
    r = subprocess.run([sys.executable, "-c", PARENT, ATTACK], capture_output=True, text=True, timeout=300,
                       check=False)
    lines = r.stdout.strip().splitlines()
    assert lines and lines[-1] == "parent alive", (r.stdout, r.stderr)
    out = json.loads(lines[-2])
    assert out["undo_subreaper"] == 0  # undone: the kernel's refusal does not depend on it
    assert out["undo_no_new_privs"][0] == -1  # no_new_privs is for good
    for key in ("fork", "clone_process", "execve", "ptrace_parent", "read_parent_memory", "kill_parent"):
        if out[key] is not None:
            assert out[key] == [-1, errno.EPERM], (key, out[key])
    assert out["clone3"] == [-1, errno.ENOSYS]
    assert out["kill_itself"] == [0, 0]
    assert "Operation not permitted" in out["os_fork"]  # the kernel refused Python's fork too
    assert out["blas"] is True and out["python_threads"] == 4
    # OpenBLAS starts a thread per CPU beside the main one, 4 at most here
    assert out["threads_now"] >= min(4, os.cpu_count() or 1), "numpy's BLAS threads did not start"


STUDENT = textwrap.dedent("""
    import ctypes
    import os
    import signal

    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    libc = ctypes.CDLL(None, use_errno=True)


    def attempt(fn):
        ctypes.set_errno(0)
        rc = fn()
        if rc == 0 and os.getpid() != PID:
            os._exit(0)
        return f"{rc}/{ctypes.get_errno()}"


    PID = os.getpid()


    class Escapes(ExtendedKalmanFilter):
        def __init__(self, ctx):
            super().__init__(ctx)
            libc.prctl(36, 0, 0, 0, 0)  # undo the subreaper
            got = {"fork": attempt(libc.fork),
                   "kill_parent": attempt(lambda: libc.kill(os.getppid(), 0)),
                   "ptrace_parent": attempt(lambda: libc.ptrace(16, os.getppid(), 0, 0))}
            raise RuntimeError("ESCAPES " + " ".join(f"{k}={v}" for k, v in got.items()))
""")


@pytest.mark.skipif(unavailable() is not None, reason=f"no system call filter here: {unavailable()}")
@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_a_graded_file_is_refused_by_the_kernel_at_every_level(tmp_path, sandbox):
    from beacon_sim.hosting.containment import bwrap_problem

    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(bwrap_problem())
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "escapes.py").write_text(STUDENT)
    cfg = GradeConfig(scenarios=("two_rooms",), seeds=(0,), duration=2.0, time_limit=10.0, sandbox=sandbox,
                      allow_unisolated=True)
    row = grade(folder, cfg, jobs=1, secret=bytes(32)).rows[0]
    reason = row["failures"][0]["reason"]
    assert "ESCAPES" in reason, reason
    assert f"fork=-1/{errno.EPERM}" in reason and f"kill_parent=-1/{errno.EPERM}" in reason, reason
    assert f"ptrace_parent=-1/{errno.EPERM}" in reason, reason
    assert os.getpid() > 0  # the grader (this process) is alive
