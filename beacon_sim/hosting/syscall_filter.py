"""The kernel's refusal of new processes, signals and tracing in a student's child (Linux
seccomp, x86_64 and aarch64): installed by the child before any student code runs, it
cannot be undone by the file (``PR_SET_NO_NEW_PRIVS`` and a seccomp filter are one-way,
inherited by every thread). Pure Python through ``ctypes``.

What the filter refuses (the system call fails with ``EPERM``; nothing is started, sent or
read):

- a new process: ``fork``, ``vfork``, ``clone`` without ``CLONE_THREAD`` (a thread is
  allowed: numpy's and Python's threads work), ``execve``, ``execveat``; ``clone3`` fails
  with ``ENOSYS`` (its flags are out of the filter's reach), so the C library falls back
  to ``clone`` for a thread;
- a signal to another process: ``kill``, ``tgkill``, ``rt_sigqueueinfo`` and
  ``rt_tgsigqueueinfo`` to any process but itself, ``tkill``, ``pidfd_send_signal``;
- reading or steering another process: ``ptrace``, ``process_vm_readv``,
  ``process_vm_writev``, ``pidfd_getfd``, ``process_madvise``, ``perf_event_open``;
  ``prlimit64``, ``sched_setaffinity``, ``sched_setscheduler``, ``sched_setparam``,
  ``sched_setattr`` of any process but itself; ``setpriority`` and ``ioprio_set`` but of
  itself (a classmate's limits, CPUs and priority are out of reach);
- a system call of another ABI (x86_64's 32-bit and x32 calls), whose numbers the filter
  does not list.

Elsewhere (macOS, another architecture, a kernel without seccomp) :func:`install` says why
it did not install, and the process level falls back on detection
(:mod:`beacon_sim.hosting.processes`).
"""

from __future__ import annotations

import ctypes
import errno
import os
import platform
import struct
import sys
from typing import Any

#: seccomp's ``arch`` word of each architecture the filter knows.
AUDIT_ARCH = {"x86_64": 0xC000003E, "aarch64": 0xC00000B7}
#: System call numbers per architecture (None: the call does not exist there).
NUMBERS: dict[str, tuple[int | None, int | None]] = {
    # name: (x86_64, aarch64)
    "fork": (57, None), "vfork": (58, None), "clone": (56, 220), "clone3": (435, 435),
    "execve": (59, 221), "execveat": (322, 281),
    "kill": (62, 129), "tkill": (200, 130), "tgkill": (234, 131),
    "rt_sigqueueinfo": (129, 138), "rt_tgsigqueueinfo": (297, 240), "pidfd_send_signal": (424, 424),
    "ptrace": (101, 117), "process_vm_readv": (310, 270), "process_vm_writev": (311, 271),
    "pidfd_getfd": (438, 438), "process_madvise": (440, 440), "perf_event_open": (298, 241),
    "prlimit64": (302, 261), "sched_setaffinity": (203, 122), "sched_setscheduler": (144, 119),
    "sched_setparam": (142, 118), "sched_setattr": (314, 274),
    "setpriority": (141, 140), "ioprio_set": (251, 30),
    "seccomp": (317, 277),
}
#: What each listed call is allowed: ``deny`` never; ``enosys`` never, as if it did not
#: exist; ``thread`` only with CLONE_THREAD in its first argument; ``self`` only when its
#: first argument is this process (or 0, "myself", for the scheduling calls); ``who-self``
#: only for a process (first argument 0) that is this one (second argument 0 or its pid).
RULES = {
    "fork": "deny", "vfork": "deny", "execve": "deny", "execveat": "deny", "clone3": "enosys",
    "clone": "thread", "kill": "self", "tgkill": "self", "rt_sigqueueinfo": "self",
    "rt_tgsigqueueinfo": "self", "tkill": "deny", "pidfd_send_signal": "deny", "ptrace": "deny",
    "process_vm_readv": "deny", "process_vm_writev": "deny", "pidfd_getfd": "deny",
    "process_madvise": "deny", "perf_event_open": "deny", "prlimit64": "self0",
    "sched_setaffinity": "self0", "sched_setscheduler": "self0", "sched_setparam": "self0",
    "sched_setattr": "self0", "setpriority": "who-self", "ioprio_set": "who-self",
}
CLONE_THREAD = 0x00010000
X32_SYSCALL_BIT = 0x40000000
PRIO_PROCESS = 0
IOPRIO_WHO_PROCESS = 1

# classic BPF
_LD_W_ABS = 0x20
_JEQ_K = 0x15
_JGE_K = 0x35
_JSET_K = 0x45
_RET_K = 0x06
RET_ALLOW = 0x7FFF0000
RET_ERRNO = 0x00050000
#: seccomp_data: nr (u32), arch (u32), instruction pointer (u64), args (6 x u64); the low
#: word of argument i at ARGS + 8 i (little-endian).
OFF_NR, OFF_ARCH, OFF_ARGS = 0, 4, 16


def machine() -> str:
    """This machine's architecture, as the filter names them."""
    m = platform.machine().lower()
    return {"amd64": "x86_64", "arm64": "aarch64"}.get(m, m)


def unavailable(arch: str | None = None) -> str | None:
    """Why the filter cannot be installed here (not Linux, an architecture it does not
    know, a big-endian machine), or None."""
    if not sys.platform.startswith("linux"):
        return f"no seccomp on {sys.platform}"
    arch = arch or machine()
    if arch not in AUDIT_ARCH:
        return f"the system call filter knows x86_64 and aarch64, not {arch}"
    if sys.byteorder != "little":
        return "the system call filter reads arguments as little-endian"
    return None


def program(arch: str, pid: int) -> list[tuple[int, int, int, int]]:
    """The filter of process ``pid`` on ``arch``: classic BPF instructions (code, jt, jf, k)
    over ``struct seccomp_data``."""
    col = 0 if arch == "x86_64" else 1
    code: list[tuple[int, Any, Any, int]] = []  # jumps by label, resolved below

    def op(c: int, k: int, jt: Any = 0, jf: Any = 0) -> None:
        code.append((c, jt, jf, k))

    op(_LD_W_ABS, OFF_ARCH)
    op(_JEQ_K, AUDIT_ARCH[arch], 0, "deny")
    op(_LD_W_ABS, OFF_NR)
    if arch == "x86_64":
        op(_JGE_K, X32_SYSCALL_BIT, "deny", 0)
    for name, rule in RULES.items():
        nr = NUMBERS[name][col]
        if nr is not None:
            op(_JEQ_K, nr, {"deny": "deny", "enosys": "enosys", "thread": "thread", "self": "self",
                            "self0": "self0", "who-self": "who-self"}[rule], 0)
    op(_RET_K, RET_ALLOW)
    labels = {"thread": len(code)}
    op(_LD_W_ABS, OFF_ARGS)
    op(_JSET_K, CLONE_THREAD, "allow", "deny")
    labels["self0"] = len(code)
    op(_LD_W_ABS, OFF_ARGS)
    op(_JEQ_K, 0, "allow", 0)
    labels["self"] = len(code)
    op(_LD_W_ABS, OFF_ARGS)
    op(_JEQ_K, pid, "allow", "deny")
    labels["who-self"] = len(code)
    op(_LD_W_ABS, OFF_ARGS)  # which: a process (setpriority's PRIO_PROCESS, ioprio's WHO_PROCESS)
    op(_JEQ_K, PRIO_PROCESS, "who", 0)
    op(_JEQ_K, IOPRIO_WHO_PROCESS, 0, "deny")  # (ioprio_set's PRIO_PROCESS 0 is not a class)
    labels["who"] = len(code)
    op(_LD_W_ABS, OFF_ARGS + 8)
    op(_JEQ_K, 0, "allow", 0)
    op(_JEQ_K, pid, "allow", "deny")
    labels["allow"] = len(code)
    op(_RET_K, RET_ALLOW)
    labels["deny"] = len(code)
    op(_RET_K, RET_ERRNO | errno.EPERM)
    labels["enosys"] = len(code)
    op(_RET_K, RET_ERRNO | errno.ENOSYS)
    out = []
    for i, (c, jt, jf, k) in enumerate(code):
        rel = [labels[j] - i - 1 if isinstance(j, str) else j for j in (jt, jf)]
        if not all(0 <= r < 256 for r in rel):
            raise ValueError("system call filter: a jump out of range")
        out.append((c, rel[0], rel[1], k))
    return out


def run_program(prog: list[tuple[int, int, int, int]], nr: int, arch: int, args: tuple[int, ...] = ()) -> int:
    """What ``prog`` answers for one system call (a BPF interpreter of the instructions
    :func:`program` uses): the seccomp return value."""
    data = struct.pack("<II Q 6Q", nr, arch, 0, *(list(args) + [0] * (6 - len(args))))
    acc, pc = 0, 0
    while True:
        c, jt, jf, k = prog[pc]
        pc += 1
        if c == _LD_W_ABS:
            acc = struct.unpack_from("<I", data, k)[0]
        elif c == _RET_K:
            return k
        elif c in (_JEQ_K, _JGE_K, _JSET_K):
            hit = acc == k if c == _JEQ_K else acc >= k if c == _JGE_K else bool(acc & k)
            pc += jt if hit else jf
        else:
            raise ValueError(f"system call filter: instruction {c:#x}")


class _SockFilter(ctypes.Structure):
    _fields_ = [("code", ctypes.c_ushort), ("jt", ctypes.c_ubyte), ("jf", ctypes.c_ubyte),
                ("k", ctypes.c_uint)]


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.POINTER(_SockFilter))]


def install() -> str | None:
    """Install the filter in this process (every thread: ``SECCOMP_FILTER_FLAG_TSYNC``),
    after ``PR_SET_NO_NEW_PRIVS``: None when it is in force, else why not (one line)."""
    why = unavailable()
    if why is not None:
        return why
    arch = machine()
    prog = program(arch, os.getpid())
    arr = (_SockFilter * len(prog))(*[_SockFilter(*ins) for ins in prog])
    fprog = _SockFprog(len(prog), arr)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError as exc:
        return f"no C library to install the system call filter: {exc}"
    if libc.prctl(38, 1, 0, 0, 0) != 0:  # PR_SET_NO_NEW_PRIVS
        return f"PR_SET_NO_NEW_PRIVS failed: {os.strerror(ctypes.get_errno())}"
    nr = NUMBERS["seccomp"][0 if arch == "x86_64" else 1] or 0
    # seccomp(SECCOMP_SET_MODE_FILTER, SECCOMP_FILTER_FLAG_TSYNC, prog)
    rc = libc.syscall(ctypes.c_long(nr), ctypes.c_uint(1), ctypes.c_uint(1), ctypes.byref(fprog))
    if rc != 0:
        e = ctypes.get_errno()
        if libc.prctl(22, 2, ctypes.byref(fprog), 0, 0) != 0:  # PR_SET_SECCOMP, SECCOMP_MODE_FILTER
            return f"the kernel refused the system call filter: {os.strerror(e)}"
    return None





def refuse_in_python(why: str) -> None:
    """Make the standard library's ways of starting a process raise ``PermissionError``
    with ``why`` (the kernel refuses them anyway: this only names the refusal, where a
    silent -1 of ``os.system`` or a bare ``EPERM`` would not say what was not allowed)."""
    def refuse(*_args: Any, **_kwargs: Any) -> Any:
        raise PermissionError(errno.EPERM, why)

    for name in ("fork", "forkpty", "system", "popen", "posix_spawn", "posix_spawnp", "execv", "execve",
                 "execl", "execle", "execlp", "execlpe", "execvp", "execvpe", "spawnv", "spawnve", "spawnl",
                 "spawnle", "spawnlp", "spawnlpe", "spawnvp", "spawnvpe"):
        if hasattr(os, name):
            setattr(os, name, refuse)
    try:
        import _posixsubprocess

        _posixsubprocess.fork_exec = refuse
    except ImportError:
        pass


__all__ = ["AUDIT_ARCH", "NUMBERS", "RULES", "install", "machine", "program", "refuse_in_python",
           "run_program", "unavailable"]
