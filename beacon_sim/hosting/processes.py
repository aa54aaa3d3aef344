"""What a student's process starts, found and stopped at the process level (the hosted
child, :mod:`beacon_sim.hosting.child`): the child becomes the subreaper of everything it
starts, so that a process below it (a double fork too) is found in /proc and killed, and one
that ran and was reaped shows in its children's usage. A process a filter starts is not
allowed: its CPU time and memory could not be counted with the student's (threads are
counted: every thread's CPU time is charged to the runs).
"""

from __future__ import annotations

import ctypes
import os
import resource
import signal
import time

#: The words of a run failed because the student's code started a process.
PROCESS_NOT_ALLOWED = ("started a process: not allowed (its CPU time and memory cannot be counted with "
                       "the filter's; use threads, which are counted)")


def descendants() -> list[int]:
    """The processes below this one (its children, and theirs: orphans come back to this
    process, their subreaper), from /proc (Linux; elsewhere none are found)."""
    out: list[int] = []
    todo = [os.getpid()]
    while todo:
        pid = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tasks:
            try:
                with open(f"/proc/{pid}/task/{tid}/children", "rb") as fh:  # bytes: no codec to
                    kids = [int(x) for x in fh.read().split()]                # import as nobody
            except (OSError, ValueError):
                continue
            out += kids
            todo += kids
    return out


def children_usage() -> tuple[float, float, int]:
    """What the reaped children of this process used (CPU seconds, user and system; minor
    page faults): any change means a process ran."""
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (u.ru_utime, u.ru_stime, u.ru_minflt)


def become_subreaper() -> bool:
    """Make this process the subreaper of everything it starts (Linux ``prctl``): an
    orphaned grandchild comes back to it instead of init, so it can be found and killed."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(36, 1, 0, 0, 0) == 0  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):
        return False


def _reap() -> None:
    """Collect every ended child (this process is their subreaper: orphans come back here)."""
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return


def stop_descendants(rounds: int = 200) -> bool:
    """Kill every process below this one, again until none is left (a process being forked
    as the last was killed comes back here as an orphan), reaping them; whether any was
    found. At most ``rounds`` rounds, 5 ms apart."""
    found = False
    for _ in range(rounds):
        _reap()
        kids = descendants()
        if not kids:
            return found
        found = True
        for pid in kids:
            try:
                os.kill(pid, signal.SIGKILL)  # signal, time: imported before the child drops its rights
            except OSError:
                pass
        time.sleep(0.005)
    return found


def has_children() -> bool:
    """Whether this process has a child, running or ended (one system call: the cheap test
    made every tick; a process anywhere below this one, its subreaper, implies a child)."""
    try:
        os.waitpid(-1, os.WNOHANG)
    except ChildProcessError:
        return False
    return True
