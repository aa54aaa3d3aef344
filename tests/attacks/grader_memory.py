"""Attack: read the memory of the process that started it (the grader, or its worker, which
holds every run's truth) through ``/proc/<parent>/mem``, or attach to it with ``ptrace``, as
a process of the grader's own user could. A real attacker would search the memory for the
truth; this file only says, in the failure of its runs, that it could read it: graded
honestly (an EKF) it is when every way in is refused."""

import ctypes
import os

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


def grader_bytes() -> int:
    """How many bytes of the parent's memory this process could read (0: refused)."""
    ppid = os.getppid()
    got = 0
    try:
        with open(f"/proc/{ppid}/comm", "rb") as fh:
            if b"python" not in fh.read():
                return 0  # not the grader (bubblewrap's own process, in a PID namespace)
    except OSError:
        return 0
    try:
        with open(f"/proc/{ppid}/maps", "rb") as fh:
            regions = [line.split()[0].split(b"-") for line in fh.read().splitlines()]
        with open(f"/proc/{ppid}/mem", "rb", buffering=0) as mem:
            for lo, _hi in regions[:20]:
                try:
                    mem.seek(int(lo, 16))
                    got += len(mem.read(4096))
                except OSError:
                    continue
    except OSError:
        pass
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.ptrace(16, ppid, 0, 0) == 0:  # PTRACE_ATTACH
        libc.ptrace(17, ppid, 0, 0)  # PTRACE_DETACH
        got += 1
    return got


class Spy(ExtendedKalmanFilter):
    def __init__(self, ctx):
        super().__init__(ctx)
        n = grader_bytes()
        if n:
            raise RuntimeError(f"read the grader's memory: {n} bytes")
