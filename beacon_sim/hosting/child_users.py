"""A user of its own for each student's child when the grader is root at the process level
(no bubblewrap): a user ID from a reserved range (:data:`FIRST_UID` on), leased for the
child's life through a lock file (so that graders and workers on one machine never share
one), owner of the child's folder and of its copy of the submission (readable by it
alone). Classmates then cannot read each other's files, write in each other's folders, or
signal, trace or renice each other (the kernel checks the user); when the child ends,
every process left under its user is killed and what it left in the shared temporary
folders (``/tmp``, ``/var/tmp``, ``/dev/shm``) is removed, so nothing it wrote survives it.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import signal
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path

#: The first user ID of the reserved range, and how many there are.
FIRST_UID = 61000
UIDS = 1000
#: The shared folders where a child may leave files, cleaned of its user's after it.
SHARED_TMP = ("/tmp", "/var/tmp", "/dev/shm")


@dataclass
class UidLease:
    """A user ID leased to one child: held while ``lock`` (a locked file) is open."""

    uid: int
    lock: int

    def release(self) -> None:
        """Kill what runs under the user, remove what it left in the shared folders, and
        give the user ID back, marked clean."""
        if self.lock < 0:
            return
        sweep(self.uid)
        with contextlib.suppress(OSError):
            os.ftruncate(self.lock, 0)  # clean: the next holder need not sweep
        with contextlib.suppress(OSError):
            os.close(self.lock)
        self.lock = -1


def _lock_dir() -> Path:
    d = Path(tempfile.gettempdir()) / "beacon-sim-uids"
    d.mkdir(mode=0o700, exist_ok=True)
    os.chmod(d, 0o700)
    return d


def lease_uid() -> UidLease:
    """A free user ID of the reserved range, swept of anything an earlier holder left when
    it was not given back clean (its grader died; raises OSError when all are in use)."""
    d = _lock_dir()
    start = os.getpid() % UIDS  # graders on one machine start their search apart
    for i in range(UIDS):
        uid = FIRST_UID + (start + i) % UIDS
        if _named(uid):
            continue  # a user of this machine's own: never ours
        fd = os.open(d / str(uid), os.O_CREAT | os.O_RDWR | os.O_CLOEXEC, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if os.fstat(fd).st_size:  # marked in use: its last holder did not give it back
            sweep(uid)
        os.pwrite(fd, b"in use\n", 0)
        return UidLease(uid, fd)
    raise OSError(f"every user ID from {FIRST_UID} to {FIRST_UID + UIDS - 1} is in use by a child")


def _named(uid: int) -> bool:
    import pwd

    try:
        pwd.getpwuid(uid)
    except KeyError:
        return False
    return True


def processes_of(uid: int) -> list[int]:
    """The processes whose real or effective user is ``uid`` (from /proc)."""
    out = []
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/status", "rb") as fh:
                for line in fh:
                    if line.startswith(b"Uid:"):
                        ids = [int(x) for x in line.split()[1:3]]
                        if uid in ids:
                            out.append(int(name))
                        break
        except (OSError, ValueError):
            continue
    return out


def sweep(uid: int, rounds: int = 50) -> None:
    """Kill every process of user ``uid`` (again, until none is left) and remove the files
    and folders it owns at the top of the shared temporary folders (and one level into a
    shared world-writable folder there)."""
    for _ in range(rounds):
        pids = processes_of(uid)
        if not pids:
            break
        for pid in pids:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
    for top in SHARED_TMP:
        _remove_owned(Path(top), uid, depth=1)


def _remove_owned(folder: Path, uid: int, depth: int) -> None:
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for e in entries:
        try:
            st = e.stat(follow_symlinks=False)
        except OSError:
            continue
        if st.st_uid == uid:
            if stat.S_ISDIR(st.st_mode):
                shutil.rmtree(e.path, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.unlink(e.path)
        elif depth > 0 and stat.S_ISDIR(st.st_mode) and st.st_mode & 0o002:
            _remove_owned(Path(e.path), uid, depth - 1)


def give_to(uid: int, tmp: Path, src: Path, work: Path) -> None:
    """Make the child's folder its user's alone: ``work`` its own (0700), ``src`` (the copy
    of the submission) readable by it alone, ``tmp`` passable but not listable by others."""
    for d, files in ((src, 0o400), (work, 0o600)):
        for root, dirs, names in os.walk(d):
            for n in names:
                p = os.path.join(root, n)
                os.chown(p, uid, uid, follow_symlinks=False)
                os.chmod(p, files)
            for n in dirs:
                p = os.path.join(root, n)
                os.chown(p, uid, uid, follow_symlinks=False)
                os.chmod(p, 0o500 if d == src else 0o700)
    os.chown(src, uid, uid)
    os.chmod(src, 0o500)
    os.chown(work, uid, uid)
    os.chmod(work, 0o700)
    os.chmod(tmp, 0o711)


__all__ = ["FIRST_UID", "UIDS", "UidLease", "give_to", "lease_uid", "processes_of", "sweep"]
