"""Feeding a batch of runs to a hosted filter: the one client of the child's batch protocol
(:mod:`beacon_sim.hosting.child`), shared by ``grade``, ``eval``'s hosted runs and
``check``, so that a filter sees the same calls, in the same order, with the
same limits, whichever of them feeds it, and is judged by the same rules.

A batch is a list of :class:`Slot` (one filter each: its context, initial belief, the
"step" requests of its ticks). :func:`feed_batch` builds every filter in one exchange,
asks each for its estimate after reset, feeds every tick of every slot in one exchange (a
slot leaves when its ticks end or, for a probe, when the run it probes fails: decided here,
never told to the child), asks the SLAM runs for their final ``joint()``, every filter that
is still going for its ``belief()``, and ends the batch (did it draw from the global
generators?).

The probes (:func:`probe_slots`) are what ``grade`` and ``check`` ask of a filter besides
its scored runs, each drawn like a scored run (a probe is one more seed, not a
recognisable special case): the first run fed again ("again": is the filter
deterministic?), and one more seed, drawn from the run's key, fed with its readings
("extra") and with its readings drawn again from another stream ("extra_redrawn"): does
the filter use its readings? (No probe shares a scored run's truth with other readings: a
file that fused the readings of two copies would learn more of that truth than the run
gives.) Every slot of a batch is built and fed in an order drawn from the run's key, so
neither the order nor anything the child holds says which slot is scored: the run and
its copy fed again are the same to the file, which would have to treat one of two
identical runs differently to tell them apart, and that is what the determinism probe
flags.

:class:`LocalChild` serves the same protocol in this process (a built-in filter, or
``check --sandbox none``), with the child's own code (:class:`~beacon_sim.hosting.batch.Batch`).
"""

from __future__ import annotations

import hashlib
import pickle
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.hosting.containment import Limits
from beacon_sim.hosting.isolated import MIN_REPLY_TIMEOUT_S, ChildFailure, FilterChild
from beacon_sim.hosting.wire import (
    ESTIMATE,
    MAPPED,
    OK,
    WireError,
    encode_request,
    map_problem,
    parse_estimate,
    parse_json,
    split_mapped,
)

#: How many ticks the probes run (the first run's first ticks).
PROBE_TICKS = 200
#: The probes, in the order :func:`probe_slots` gives them.
PROBES = ("again", "extra", "extra_redrawn")
#: A default grade (``GradeConfig()``): its seeds, run length [s], time limit per run [s] and
#: memory limit [GB]. ``check`` hosts a file as such a grade does, so a file cannot tell one
#: from the other by its limits.
GRADE_SEEDS = 5
GRADE_RUN_S = 60.0
GRADE_TIME_LIMIT_S = 60.0
GRADE_MEMORY_GB = 4.0
GRADE_DISK_MB = 64.0
#: The most of a student's log a grade keeps [bytes] (and ``check``'s child writes).
LOG_BYTES = 256 << 10
#: Why a probe stopped when the run it probes failed (its failure is that run's).
LEAD_FAILED = "the run it probes failed"


def child_limits(time_limit_s: float, runs: int, memory_gb: float = GRADE_MEMORY_GB,
                 disk_mb: float = GRADE_DISK_MB) -> Limits:
    """A student's child's limits for ``runs`` runs of ``time_limit_s`` [s] each: its
    address space, a CPU-time backstop for the whole child (1.5 times the runs' budgets
    and a minute for imports), what it may write [MB], the grade's log size. ``grade`` and
    ``check`` both."""
    return Limits(memory_gb=memory_gb, cpu_s=time_limit_s * runs * 1.5 + 60.0, log_bytes=LOG_BYTES,
                  disk_bytes=int(disk_mb * 2**20))


def reply_timeout(time_limit_s: float) -> float:
    """The longest wall time [s] the grader waits for one answer of a child whose runs have
    ``time_limit_s`` [s] of CPU time each: a filter that sleeps is stopped then."""
    return max(MIN_REPLY_TIMEOUT_S, 5.0 * time_limit_s)


def grade_limits() -> Limits:
    """The child limits of a default grade (one scenario, :data:`GRADE_SEEDS` seeds and the
    probes): what ``check`` gives its child too."""
    return child_limits(GRADE_TIME_LIMIT_S, GRADE_SEEDS + len(PROBES), GRADE_MEMORY_GB)


def _digest_int(key: bytes, what: bytes, nbytes: int = 32) -> int:
    return int.from_bytes(hashlib.sha256(b"beacon-sim " + what + b"\0" + key).digest()[:nbytes], "little")


def other_readings_seed(key: bytes) -> int:
    """The seed (63 bits) of the readings drawn again of the run whose key is ``key``
    (:func:`~beacon_sim.core.streams.run_key`; the "extra_redrawn" probe): as unknown to a
    filter as the key."""
    return _digest_int(key, b"other readings", 8) >> 1


def probe_seed(key: bytes) -> int:
    """The seed (63 bits) of the probes' extra run of the run whose key is ``key`` (its
    scenario's first run): drawn from the key like a grade's secret seeds, never one of the
    scored seeds but by chance."""
    return _digest_int(key, b"probe seed", 8) >> 1


def slot_order(key: bytes, n: int) -> list[int]:
    """The order in which a batch of ``n`` slots is built and fed (position j holds slot
    ``order[j]``), drawn from the run's key: nothing in the child's view says which slot is
    a probe."""
    rng = np.random.Generator(np.random.PCG64(_digest_int(key, b"slot order")))
    return [int(k) for k in rng.permutation(n)]


@dataclass
class Slot:
    """One filter of a batch.

    Attributes
    ----------
    ctx : FilterContext
        What the filter may know (its random generator included).
    initial : GaussianBelief or None
        Its initial belief (None: a global start).
    frames : sequence of bytes
        The "step" request of each tick (:func:`~beacon_sim.hosting.wire.encode_request`).
    ticks : int
        How many of them it is fed.
    spec : str
        The name sent with its build (the filter's name in the run).
    lead : int or None
        A probe: the slot (an index into the batch) whose failure ends it. Never sent.
    """

    ctx: FilterContext
    initial: GaussianBelief | None
    frames: Sequence[bytes]
    ticks: int
    spec: str
    lead: int | None = None


@dataclass
class Fed:
    """What :func:`feed_batch` got back, per slot in the caller's order.

    ``store`` (T, S, 24): per tick and slot the estimate after predict (mean 3, cov 9; NaN
    without one) and after update (mean 3, cov 9), as the child sent them (values not
    judged); ``has_prior``, ``answered`` (T, S) bool; ``walls`` (T, S) the child's wall
    time of each step [ns]; ``failed`` why each slot stopped early (None: it ran its ticks),
    ``failed_at`` the tick it stopped at (its first unanswered one); ``built`` whether it
    was built; ``first`` its estimate after reset (a pair of arrays) or why there was none;
    ``maps`` a SLAM filter's last map, ``joints`` its final ``joint()``; ``beliefs`` None
    when its ``belief()`` was fine, else why not (a slot that failed is not asked:
    ``"not asked"``); ``report`` what the child said at the end (``np_global``,
    ``py_global``; ``failed_child``: do not reuse it)."""

    store: np.ndarray
    has_prior: np.ndarray
    answered: np.ndarray
    walls: np.ndarray
    failed: list[str | None]
    failed_at: list[int | None]
    built: list[bool]
    first: list[Any]
    maps: list[Any]
    joints: list[Any]
    beliefs: list[str | None]
    report: dict[str, Any] = field(default_factory=dict)

    def means(self, k: int) -> np.ndarray:
        """Slot k's estimates' means (T, 3) [m, m, rad] (NaN where it gave none)."""
        return np.ascontiguousarray(self.store[:, k, 12:15])

    def covs(self, k: int) -> np.ndarray:
        """Slot k's estimates' covariances (T, 3, 3)."""
        return np.ascontiguousarray(self.store[:, k, 15:24]).reshape(-1, 3, 3)

    def prior_means(self, k: int) -> np.ndarray:
        """Slot k's estimates after predict: means (T, 3) (NaN on a tick without one)."""
        return np.ascontiguousarray(self.store[:, k, 0:3])

    def prior_covs(self, k: int) -> np.ndarray:
        """Slot k's estimates after predict: covariances (T, 3, 3)."""
        return np.ascontiguousarray(self.store[:, k, 3:12]).reshape(-1, 3, 3)

    def done(self, k: int) -> int:
        """How many ticks slot k answered."""
        return int(self.answered[:, k].sum())


def feed_batch(child: Any, slots: Sequence[Slot], run_limit_s: float | None, global_seed: int,
               order: Sequence[int] | None = None, joints: bool = True,
               restart: Callable[[], Any] | None = None) -> Fed:
    """Build the filters of ``slots`` in ``child`` (a :class:`FilterChild` or
    :class:`LocalChild`) and feed them (see the module's docstring): each with its own
    CPU-time budget ``run_limit_s`` [s], the global generators seeded once with
    ``global_seed`` (derived from the run's key, never its seed), in ``order`` (position j
    holds slot ``order[j]``; default as given). A slot that fails fails alone; a child that
    dies fails every slot still going with its reason. ``joints``: ask the runs that have a
    map (and are not probes) for their final ``joint()``.

    ``restart`` (a function that stops the current child and returns a fresh one, or why
    there is none): the memory limit is each slot's own. The slots of a batch share one
    address space, so when a slot of a batch of several fails in a way the memory limit
    can cause (:func:`memory_suspect`), the whole batch is fed again one slot per fresh
    child (:func:`feed_alone`), as each would be graded alone; ``report["alone"]`` says so."""
    fed = _feed_together(child, slots, run_limit_s, global_seed, order, joints)
    if restart is None or len(slots) < 2 or not any(memory_suspect(w) for w in fed.failed):
        return fed
    return feed_alone(restart, slots, run_limit_s, global_seed, order, joints)


def memory_suspect(why: str | None) -> bool:
    """Whether a slot's failure ``why`` may come from the memory limit of the process it
    shared with other slots: a ``MemoryError``, a thread that could not start, or the
    process killed by a signal an allocation that failed in compiled code sends."""
    if not why:
        return False
    return any(w in why for w in ("MemoryError", "can't start new thread", "memory limit", "SIGSEGV",
                                  "SIGABRT", "SIGBUS", "was killed by SIGKILL"))


def feed_alone(restart: Callable[[], Any], slots: Sequence[Slot], run_limit_s: float | None,
               global_seed: int, order: Sequence[int] | None = None, joints: bool = True) -> Fed:
    """:func:`feed_batch` with each slot alone in a fresh child (``restart()``: stops the
    current child and returns a fresh one, or a string saying why there is none), in
    ``order``: each its own address space, memory limit and CPU-time backstop, as if it
    were the only run graded. A probe is fed all its ticks and cut afterwards where the run
    it probes failed, exactly where :func:`feed_batch` would have stopped it (so the order
    need not put the runs before their probes, and says nothing of which slot is one)."""
    S = len(slots)
    order = list(range(S)) if order is None else [int(k) for k in order]
    T = max((s.ticks for s in slots), default=0)
    fed = Fed(np.full((T, S, 24), np.nan), np.zeros((T, S), dtype=bool), np.zeros((T, S), dtype=bool),
              np.zeros((T, S), dtype=np.int64), [None] * S, [None] * S, [False] * S, [None] * S,
              [None] * S, [None] * S, ["not asked"] * S, {"alone": True})
    for k in order:
        s = slots[k]
        child = restart()
        if isinstance(child, str) or child is None:
            fed.failed[k], fed.failed_at[k] = child or "the filter's process could not be started", 0
            continue
        one = _feed_together(child, [Slot(s.ctx, s.initial, s.frames, s.ticks, s.spec)], run_limit_s,
                             global_seed, None, joints and s.lead is None)
        n = one.store.shape[0]
        fed.store[:n, k], fed.has_prior[:n, k] = one.store[:, 0], one.has_prior[:, 0]
        fed.answered[:n, k], fed.walls[:n, k] = one.answered[:, 0], one.walls[:, 0]
        fed.failed[k], fed.failed_at[k], fed.built[k] = one.failed[0], one.failed_at[0], one.built[0]
        fed.first[k], fed.maps[k], fed.joints[k], fed.beliefs[k] = (one.first[0], one.maps[0], one.joints[0],
                                                                    one.beliefs[0])
        for key in ("np_global", "py_global", "failed_child", "died"):
            fed.report[key] = bool(fed.report.get(key) or one.report.get(key))
        if one.report.get("traceback") and not fed.report.get("traceback"):
            fed.report["traceback"] = one.report["traceback"]
    for k, s in enumerate(slots):  # each probe stopped where the run it probes failed
        if s.lead is None:
            continue
        lead = s.lead
        cut = (0 if not fed.built[lead] else
               None if fed.failed[lead] is None else int(fed.failed_at[lead] or 0) + 1)
        own = fed.failed_at[k] if fed.failed[k] is not None else None
        if cut is None or cut >= s.ticks or not fed.built[k] or (own is not None and own < cut):
            continue
        fed.store[cut:, k] = np.nan
        fed.has_prior[cut:, k] = fed.answered[cut:, k] = False
        fed.walls[cut:, k] = 0
        fed.failed[k], fed.failed_at[k], fed.beliefs[k] = LEAD_FAILED, cut, "not asked"
    return fed


def _feed_together(child: Any, slots: Sequence[Slot], run_limit_s: float | None, global_seed: int,
                   order: Sequence[int] | None, joints: bool) -> Fed:
    """Every slot in ``child`` at once, one exchange per tick (:func:`feed_batch`)."""
    S = len(slots)
    order = list(range(S)) if order is None else [int(k) for k in order]
    if sorted(order) != list(range(S)):
        raise ValueError("feed_batch: order must be a permutation of the slots")
    pos = {k: j for j, k in enumerate(order)}  # slot -> its position in the child
    T = max((s.ticks for s in slots), default=0)
    store = np.full((T, S, 24), np.nan)
    walls = np.zeros((T, S), dtype=np.int64)
    has_prior = np.zeros((T, S), dtype=bool)
    answered = np.zeros((T, S), dtype=bool)
    fed = Fed(store, has_prior, answered, walls, [None] * S, [None] * S, [False] * S, [None] * S,
              [None] * S, [None] * S, ["not asked"] * S)
    failed, failed_at = fed.failed, fed.failed_at

    def fail(k: int, why: str, at: int) -> None:
        failed[k], failed_at[k] = why, at

    try:
        why = child.batch_build([(slots[k].ctx, slots[k].initial, slots[k].spec) for k in order],
                                global_seed, run_limit_s)
        for j, w in enumerate(why):
            if w is None:
                fed.built[order[j]] = True
            else:
                fail(order[j], w, 0)
        live = [j for j in range(S) if failed[order[j]] is None]
        if live:
            for j, (tag, payload) in zip(live, child.batch_first(live), strict=True):
                fed.first[order[j]] = (parse_estimate(payload)[2] if tag == ESTIMATE
                                       else child.failure_text(payload))
        for i in range(T):
            going = []
            for j in live:
                k = order[j]
                lead = slots[k].lead
                if i >= slots[k].ticks:
                    continue
                if lead is not None and failed[lead] is not None:
                    fail(k, LEAD_FAILED, i)
                    continue
                going.append(j)
            live = going
            if not live:
                break
            got = child.batch_step(live, [slots[order[j]].frames[i][4:] for j in live])
            ks = np.asarray([order[j] for j in live], dtype=int)
            if isinstance(got, np.ndarray):  # every slot answered with an estimate
                store[i, ks] = got["v"]
                walls[i, ks] = got["wall"]
                has_prior[i, ks] = got["prior"] != 0
                answered[i, ks] = True
                continue
            going = []
            for j, (tag, payload) in zip(live, got, strict=True):
                k = order[j]
                if tag == MAPPED:
                    payload, block = split_mapped(payload)
                    fed.maps[k], problem = map_problem(block)
                    if problem is not None:  # a bad map switches the filter off, as a bad estimate
                        fail(k, problem, i)
                        continue
                elif tag != ESTIMATE:
                    fail(k, child.failure_text(payload), i)
                    continue
                wall, prior, (mean, cov) = parse_estimate(payload)
                store[i, k, 12:15], store[i, k, 15:24] = mean, cov.ravel()
                if prior is not None:
                    store[i, k, 0:3], store[i, k, 3:12] = prior[0], prior[1].ravel()
                    has_prior[i, k] = True
                walls[i, k], answered[i, k] = wall, True
                going.append(j)
            live = going
        if joints:
            for k in range(S):
                if failed[k] is None and fed.maps[k] is not None and slots[k].lead is None:
                    fed.joints[k] = child.final_joint(pos[k])
        alive = [j for j in range(S) if fed.built[order[j]] and failed[order[j]] is None]
        if alive:
            for j, (tag, payload) in zip(alive, child.batch_belief(alive), strict=True):
                fed.beliefs[order[j]] = None if tag == OK else child.failure_text(payload)
        fed.report = child.batch_end()
        over = child.disk_problem()
        if over is not None:  # what it wrote is the batch's: every run of it fails
            for k in range(S):
                if fed.built[k] and (failed[k] is None or failed[k] == LEAD_FAILED):
                    fail(k, over, int(answered[:, k].sum()))
            fed.report["failed_child"] = True
    except ChildFailure as exc:  # the whole child: every slot still going fails with its reason
        for k in range(S):
            n = int(answered[:, k].sum())
            if failed[k] is None and n < slots[k].ticks:
                fail(k, str(exc) or "the filter failed", n)
        fed.report = {"failed_child": True, "died": exc.died, "traceback": exc.tb}
    except WireError as exc:  # a malformed answer: the child is not to be trusted further
        child.kill()
        for k in range(S):
            n = int(answered[:, k].sum())
            if failed[k] is None and n < slots[k].ticks:
                fail(k, f"the filter's process {exc} and was stopped", n)
        fed.report = {"failed_child": True, "died": True, "traceback": ""}
    return fed


def probe_slots(lead: int, slot: Slot, extra: tuple[Slot, Sequence[bytes]] | None,
                probe_ticks: int = PROBE_TICKS) -> list[tuple[str, Slot]]:
    """The probes of the run ``slot`` (slot ``lead`` of its batch), each on its first
    ``probe_ticks`` ticks: "again" (the same filter built the same way, the same context and
    random generator, fed the same frames); and, with ``extra`` (the slot of one more seed's
    run and that run's frames with the readings drawn again), "extra" and "extra_redrawn"
    (the same context, so the readings alone differ). Each ends when the run it probes
    fails (decided by the grader)."""
    n = min(probe_ticks, slot.ticks)
    out = [("again", Slot(slot.ctx, slot.initial, slot.frames, n, slot.spec, lead))]
    if extra is not None:
        e, redrawn = extra
        m = min(probe_ticks, e.ticks, len(redrawn))
        out += [("extra", Slot(e.ctx, e.initial, e.frames, m, e.spec, lead)),
                ("extra_redrawn", Slot(e.ctx, e.initial, redrawn, m, e.spec, lead))]
    return out


@dataclass
class ProbeFindings:
    """What the probes say of a filter: ``deterministic`` (None: not judged), whether the
    run fed again gave the same estimates bit for bit; ``differs_at`` the first tick (from
    1) where it did not; ``readings_used``
    (None: not judged); ``failures``: the probes that failed on their own (not because the
    run they probe did), by name, with why and the tick."""

    deterministic: bool | None = None
    differs_at: int | None = None
    readings_used: bool | None = None
    failures: dict[str, tuple[str, int]] = field(default_factory=dict)


def metered_stop(why: str | None) -> bool:
    """Whether a slot stopped on a budget the machine meters (``why``: CPU time, memory, or
    the run it probes stopping): the tick it stops at is the meter's, which another load or
    processor moves by a tick or two, never a property of the filter's arithmetic."""
    if not why:
        return False
    return why == LEAD_FAILED or "time limit" in why or memory_suspect(why)


def _differs_at(fed: Fed, k: int, ref: int, horizon: int) -> int | None:
    """The first tick (from 1) within ``horizon`` ticks at which slots k and ``ref`` of
    ``fed`` differ: one answered and the other did not, their estimates (means and
    covariances) are not the same bits, or they stopped at the same tick for different
    reasons; None when they are the same throughout. When either stopped on a metered
    budget (:func:`metered_stop`), only the ticks both answered are compared."""
    if metered_stop(fed.failed[k]) or metered_stop(fed.failed[ref]):
        horizon = min(horizon, int((fed.answered[:, k] & fed.answered[:, ref]).sum()))
        a, b = fed.store[:horizon, k, 12:24], fed.store[:horizon, ref, 12:24]
        same = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        return None if same.all() else int(np.argmin(same)) + 1
    a_ok, b_ok = fed.answered[:horizon, k], fed.answered[:horizon, ref]
    a, b = fed.store[:horizon, k, 12:24], fed.store[:horizon, ref, 12:24]
    same = (a_ok == b_ok) & np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
    if not same.all():
        return int(np.argmin(same)) + 1
    n = int(a_ok.sum())
    if n < horizon and fed.failed[k] != fed.failed[ref]:
        return n + 1
    return None


def judge_probes(fed: Fed, lead: int, probes: dict[str, int], readings_within: bool) -> ProbeFindings:
    """The findings of the probes (name -> slot) of the run ``lead`` in ``fed``. The copy
    fed the run's ticks again must answer them as the run did, bit for bit, and stop (or
    not) at the same tick for the same reason: else the filter is not deterministic. The
    extra run fed its readings and fed them drawn again differ by the readings alone:
    equal estimates say the filter uses none (judged only when ``readings_within``: the
    ticks probed hold readings). A probe that failed on its own (not because the run it
    probes did, nor as the copy it pairs with did) is in ``failures``."""
    out = ProbeFindings()
    if not fed.built[lead]:
        return out  # the run was not even built: nothing to compare
    k = probes.get("again")
    if k is not None and fed.built[k]:
        diff = _differs_at(fed, k, lead, _horizon(fed, k))
        out.deterministic, out.differs_at = diff is None, diff
    for name, k in probes.items():
        why, at = fed.failed[k], int(fed.failed_at[k] or 0)
        if why is None or why == LEAD_FAILED:
            continue
        if fed.failed[lead] is not None and int(fed.failed_at[lead] or 0) <= at:
            continue  # the run failed by then: that failure is the one that counts
        twin = probes.get("extra") if name == "extra_redrawn" else None
        if twin is not None and fed.failed[twin] is not None:
            continue  # the extra run failed already: one failure of that run
        out.failures[name] = (why, at)
    a, b = probes.get("extra"), probes.get("extra_redrawn")
    if a is not None and b is not None and readings_within and fed.failed[a] is None \
            and fed.failed[b] is None:
        n = min(fed.done(a), fed.done(b))
        x, y = fed.store[:n, a, 12:24], fed.store[:n, b, 12:24]
        out.readings_used = not bool(np.all((x == y) | (np.isnan(x) & np.isnan(y))))
    return out


def _horizon(fed: Fed, k: int) -> int:
    """How many ticks probe k was to run: the ticks it answered, and the one it stopped at."""
    n = fed.done(k)
    return n + 1 if fed.failed[k] is not None else n


class LocalChild(FilterChild):
    """The child's batch protocol served in this process (a built-in filter, or
    ``check --sandbox none``): the same :class:`~beacon_sim.hosting.batch.Batch` code
    builds and steps the filters, so their calls and verdicts are those of a hosted one.
    The global generators are seeded for a batch and restored after it."""

    def __init__(self, cls: type):
        from beacon_sim.hosting.child import Server

        self.limits, self.sandbox = Limits(), "none"
        self.source_name = getattr(cls, "__name__", "filter")
        self.reply_timeout_s = self._waited_s = MIN_REPLY_TIMEOUT_S
        self.dead = None
        self.reported_cpu_s = 0.0
        self._proc = None
        self._replies: list[bytes] = []
        self.server = Server(None, sink=self._replies.append)
        self.server.cls = cls
        self.class_name = str(getattr(cls, "__qualname__", "filter"))
        self.form = "class"
        self.info = {"name": self.class_name, "form": "class",
                     "missing": [m for m in ("reset", "predict", "update", "estimate", "belief")
                                 if not callable(getattr(cls, m, None))],
                     "module": str(getattr(cls, "__module__", "?")),
                     "sensor_kinds": getattr(cls, "sensor_kinds", None),
                     "landmarks": callable(getattr(cls, "landmarks", None)),
                     "joint": callable(getattr(cls, "joint", None))}
        self._saved: tuple[Any, Any] | None = None

    def request(self, frame: bytes, expect: int | None = None, runs: int = 1) -> tuple[bytes, bytes]:
        from beacon_sim.hosting.child import serve_one
        from beacon_sim.hosting.wire import FAIL

        req = pickle.loads(frame[4:])
        if req[0] in ("bbuild", "build"):
            self._saved = (np.random.get_state(legacy=False), random.getstate())  # noqa: NPY002
        try:
            self._replies.clear()
            serve_one(self.server, req, {})
        finally:
            if req[0] in ("bend", "end") and self._saved is not None:
                np.random.set_state(self._saved[0])  # noqa: NPY002 - the caller's, as it was
                random.setstate(self._saved[1])
                self._saved = None
        raw = b"".join(self._replies)
        tag, body = raw[:1], raw[5:]
        if tag == FAIL:
            doc = parse_json(body)
            raise ChildFailure(str(doc.get("why", "the filter failed"))[:400], str(doc.get("tb", "")))
        return tag, body

    def _death(self, exc: BaseException) -> str:
        self.dead = str(exc)
        return self.dead

    def kill(self) -> None:
        pass

    def disk_problem(self) -> str | None:
        return None

    def close(self) -> None:
        if self._saved is not None:
            np.random.set_state(self._saved[0])  # noqa: NPY002
            random.setstate(self._saved[1])
            self._saved = None


def step_request(control: Control, dt: float, measurements: Sequence[Measurement], want_prior: bool) -> bytes:
    """One tick's "step" request, pickled once and sent to every child fed that run: the
    command, dt [s] and the readings (what a filter may see), and whether the estimate
    after predict is wanted too (a tick with readings: for the NIS)."""
    return encode_request("step", control, dt, tuple(measurements), bool(want_prior))


def step_frames(steps: Sequence[Any]) -> list[bytes]:
    """The "step" requests of simulated ``steps`` (:class:`~beacon_sim.core.types.Step`), as
    every front end sends them: the control, dt, the readings, and whether the estimate
    after predict is wanted (on a tick with readings, for the NIS)."""
    return [step_request(st.control, st.dt, st.measurements, bool(st.measurements)) for st in steps]


__all__ = ["GRADE_MEMORY_GB", "GRADE_RUN_S", "GRADE_SEEDS", "GRADE_TIME_LIMIT_S", "LEAD_FAILED",
           "LOG_BYTES", "PROBES", "PROBE_TICKS", "Fed", "LocalChild", "ProbeFindings", "Slot",
           "child_limits", "feed_alone", "feed_batch", "grade_limits", "judge_probes", "memory_suspect",
           "metered_stop", "other_readings_seed",
           "probe_seed", "probe_slots", "reply_timeout", "slot_order", "step_frames", "step_request"]
