"""A batch fed one slot per fresh child (each run its own memory) gives what the batch fed
together gives, slot for slot and bit for bit: the estimates, the failures and the ticks
they came at, and the probes stopped where the run they probe failed, although a probe may
be fed before its run. In this process (LocalChild), so fast."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.montecarlo import simulate_run
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.hosting.client import hosted_slot
from beacon_sim.hosting.feed import (
    LEAD_FAILED,
    LocalChild,
    feed_alone,
    feed_batch,
    memory_suspect,
    probe_slots,
    slot_order,
)


class Doomed(ExtendedKalmanFilter):
    """Fails at its 10th update in the runs whose own generator's first draw is under 0.5."""

    def __init__(self, ctx):
        super().__init__(ctx)
        self.doomed = ctx.rng.random() < 0.5
        self.n = 0

    def update(self, measurements):
        super().update(measurements)
        self.n += 1
        if self.doomed and self.n == 10:
            raise RuntimeError("doomed in this seed")


def _slots(sr):
    lead = hosted_slot(sr.scenario, sr.stream_key, "doomed", None, sr.frames)
    ex = sr.extra
    extra = (hosted_slot(ex.scenario, ex.stream_key, "doomed", None, ex.frames), ex.frames_other)
    return [lead] + [s for _, s in probe_slots(0, lead, extra, 60)]


def _same(a, b) -> None:
    assert np.array_equal(a.store, b.store, equal_nan=True)
    for attr in ("has_prior", "answered", "walls"):
        assert np.array_equal(getattr(a, attr), getattr(b, attr)) or attr == "walls", attr
    assert (a.failed, a.failed_at, a.built, a.beliefs) == (b.failed, b.failed_at, b.built, b.beliefs)


@pytest.fixture(scope="module")
def runs():
    scenario = load_scenario("default")
    return [simulate_run(scenario, seed, 8.0, index=0, probe=True, redraw=True) for seed in range(8)]


def test_fed_alone_is_fed_together_and_the_probes_are_cut_where_their_run_failed(runs):
    cut = 0
    for sr in runs:
        slots = _slots(sr)
        order = slot_order(sr.stream_key, len(slots))
        together = feed_batch(LocalChild(Doomed), slots, None, 7, order)
        alone = feed_alone(lambda: LocalChild(Doomed), slots, None, 7, order)
        _same(together, alone)
        assert alone.report.get("alone") is True
        cut += sum(w == LEAD_FAILED for w in alone.failed)
    assert cut >= 2, "no run failed before a probe of it that would not: the cut was not tried"


def test_a_batch_that_ran_out_of_shared_memory_is_fed_again_alone(runs):
    """The restart is used only when a slot failed as the memory limit makes slots fail."""
    sr = runs[0]
    slots = _slots(sr)
    started = []

    def restart():
        started.append(1)
        return LocalChild(Doomed)

    feed_batch(LocalChild(Doomed), slots, None, 7, restart=restart)
    assert not started  # "doomed in this seed" is not the memory's doing
    assert memory_suspect("construction failed: MemoryError: Unable to allocate 150. MiB")
    assert memory_suspect("the filter's process was killed by SIGKILL (killed: its memory limit is 4 GB, "
                          "or it was stopped)")
    assert not memory_suspect("RuntimeError: doomed in this seed") and not memory_suspect(None)
