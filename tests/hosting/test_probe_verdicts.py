"""The "fed again" probe judges a filter's arithmetic, not the meter: a copy that stops a
tick earlier or later than its run on a CPU-time or memory budget (load moves that tick)
is deterministic when the ticks both answered are the same bits; a copy that stops at
another tick for a reason of its own, or gives other bits, is not."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.hosting.feed import LEAD_FAILED, Fed, judge_probes

T = 40
OVER = "time limit: over 1 s of filter time in the run"


def _fed(stops: list[tuple[str | None, int | None]], flip_at: int | None = None) -> Fed:
    """Two slots (0 the run, 1 its copy fed again), the same estimates on every tick each
    answered; slot k stops at its tick (its first unanswered one, from 0) for its reason.
    ``flip_at``: the copy's estimate differs in the last bit at that tick."""
    rng = np.random.default_rng(7)
    one = rng.normal(size=(T, 24))
    store = np.repeat(one[:, None, :], 2, axis=1)
    answered = np.ones((T, 2), bool)
    for k, (_, at) in enumerate(stops):
        if at is not None:
            answered[at:, k] = False
            store[at:, k, :] = np.nan
    if flip_at is not None:
        store[flip_at, 1, 12] = np.nextafter(store[flip_at, 1, 12], np.inf)
    return Fed(store=store, has_prior=answered.copy(), answered=answered, walls=np.zeros((T, 2)),
               failed=[w for w, _ in stops], failed_at=[a for _, a in stops], built=[True, True],
               first=[None, None], maps=[None, None], joints=[None, None], beliefs=[None, None])


@pytest.mark.parametrize("run_stop, copy_stop", [
    ((OVER, 17), (OVER, 16)),           # the copy's meter ran out a tick early (a loaded machine)
    ((OVER, 16), (OVER, 17)),           # ... or a tick late
    ((OVER, 17), (LEAD_FAILED, 17)),    # the copy cut where its run stopped
    ((None, None), ("MemoryError raised by the filter", 30)),
])
def test_a_copy_stopped_by_a_meter_is_judged_on_the_ticks_both_answered(run_stop, copy_stop):
    found = judge_probes(_fed([run_stop, copy_stop]), 0, {"again": 1}, readings_within=False)
    assert found.deterministic is True and found.differs_at is None


def test_other_bits_before_the_meter_stops_it_are_not_deterministic():
    found = judge_probes(_fed([(OVER, 17), (OVER, 16)], flip_at=5), 0, {"again": 1}, readings_within=False)
    assert found.deterministic is False and found.differs_at == 6


def test_a_copy_that_raises_where_its_run_did_not_is_not_deterministic():
    raised = "ValueError raised by the filter"
    found = judge_probes(_fed([(raised, 17), (raised, 12)]), 0, {"again": 1}, readings_within=False)
    assert found.deterministic is False and found.differs_at == 13
    same = judge_probes(_fed([(raised, 17), (raised, 17)]), 0, {"again": 1}, readings_within=False)
    assert same.deterministic is True
