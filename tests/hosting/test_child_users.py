"""A root grader at the process level gives each child a user of its own (a reserved
range): a classmate's child cannot read its submission or write in its folder, and what a
child leaves in /tmp and /dev/shm is removed when it ends. Root only (skipped otherwise)."""

from __future__ import annotations

import os
import re
import time

import pytest

from beacon_sim.hosting.child_users import FIRST_UID, UIDS, lease_uid, processes_of
from beacon_sim.hosting.containment import Limits
from beacon_sim.hosting.isolated import ChildFailure, FilterChild

pytestmark = pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                                reason="a user per child needs a root grader")

VICTIM = """
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Victim(ExtendedKalmanFilter):
    pass
"""
SPY = """
import os

seen = read = wrote = 0
owners = set()
for d in [{victim!r}]:  # the classmate's folder (a spy would search /tmp: the test names it)
    seen += os.path.isdir(d)
    owners.add(os.stat(d + "/work").st_uid)
    try:
        open(d + "/src/victim.py").read()
        read += 1
    except OSError:
        pass
    try:
        open(os.path.join(d, "work", "planted.py"), "w").write("x = 1")
        wrote += 1
    except OSError:
        pass
raise RuntimeError(f"SPY uid={{os.getuid()}} seen={{seen}} read={{read}} wrote={{wrote}} "
                   f"owners={{sorted(owners)}}")
"""


def test_a_classmates_child_cannot_read_its_submission_or_write_in_its_folder(tmp_path):
    (tmp_path / "victim.py").write_text(VICTIM)
    with FilterChild(tmp_path / "victim.py", None, tmp_path / "v.log", "process", Limits()) as victim:
        assert victim._proc is not None
        (tmp_path / "spy.py").write_text(SPY.format(victim=str(victim._proc.tmp)))
        with pytest.raises(ChildFailure) as info:
            FilterChild(tmp_path / "spy.py", None, tmp_path / "s.log", "process", Limits())
    m = re.search(r"SPY uid=(\d+) seen=(\d+) read=(\d+) wrote=(\d+) owners=\[([\d, ]*)\]", str(info.value))
    assert m, str(info.value)
    uid, seen, read, wrote = (int(m.group(k)) for k in range(1, 5))
    owners = {int(x) for x in m.group(5).split(",") if x.strip()}
    assert seen >= 1, "the spy did not find the victim's folder: the test tried nothing"
    assert FIRST_UID <= uid < FIRST_UID + UIDS and uid not in owners
    assert all(FIRST_UID <= o < FIRST_UID + UIDS for o in owners)
    assert read == 0 and wrote == 0


LEAVES = """
import os
for top in ("/tmp", "/dev/shm"):
    try:
        with open(os.path.join(top, {name!r}), "w") as fh:
            fh.write("for the next student")
    except OSError:
        pass
os.makedirs("/tmp/{name}-dir/inner", exist_ok=True)
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Leaves(ExtendedKalmanFilter):
    pass
"""


def test_what_a_child_leaves_in_the_shared_temporary_folders_is_removed_with_it(tmp_path):
    name = f"beacon-sim-left-{os.getpid()}-{time.monotonic_ns()}"
    (tmp_path / "leaves.py").write_text(LEAVES.format(name=name))
    left = [f"/tmp/{name}", f"/dev/shm/{name}", f"/tmp/{name}-dir"]
    with FilterChild(tmp_path / "leaves.py", None, tmp_path / "l.log", "process", Limits()):
        assert any(os.path.exists(p) for p in left), "the file left nothing: the test tried nothing"
    assert not [p for p in left if os.path.exists(p)]


def test_each_lease_is_a_user_of_its_own_given_back_with_nothing_left_under_it():
    a, b = lease_uid(), lease_uid()
    try:
        assert a.uid != b.uid and all(FIRST_UID <= x.uid < FIRST_UID + UIDS for x in (a, b))
    finally:
        a.release()
        b.release()
    c = lease_uid()  # given back: free again (the search starts at the same place)
    try:
        assert c.uid == a.uid and not processes_of(c.uid)
    finally:
        c.release()


def test_a_user_left_in_use_by_a_dead_grader_is_swept_before_it_is_leased_again():
    a = lease_uid()
    uid = a.uid
    stale = f"/dev/shm/beacon-sim-stale-{os.getpid()}-{time.monotonic_ns()}"
    with open(stale, "w") as fh:
        fh.write("for the next holder of this user")
    os.chown(stale, uid, uid)
    os.close(a.lock)  # its grader died: the user was never given back
    a.lock = -1
    b = lease_uid()
    try:
        assert b.uid == uid and not os.path.exists(stale)
    finally:
        b.release()
        if os.path.exists(stale):
            os.unlink(stale)
