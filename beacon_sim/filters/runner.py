"""The old import path of the filter runner, which now lives in
:mod:`beacon_sim.hosting.runner` (the hosting layer: running someone's filter,
docs/architecture.md).

Files written against ``beacon_sim.filters.runner`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.hosting.runner import (
    CPU_BACKSTOP_FACTOR,
    CPU_BACKSTOP_S,
    HEADLESS_STEP_LIMIT_S,
    MAX_COV,
    MAX_MEAN,
    NOT_BUILT,
    SLOW_MIN_STEPS,
    SLOW_STEP_MS,
    SLOW_WINDOW,
    WINDOW_STEP_LIMIT_S,
    FilterExit,
    FilterRunner,
    FilterTimeout,
    FilterTrack,
    StepWatch,
    bounded_track,
    call_guarded,
    check_estimate,
    exit_text,
    failure_line,
    failure_of,
    failure_text,
    guarded_call,
    is_filter_failure,
    note_step_time,
    note_user_interrupt,
    one_line,
    run_filter_code,
    settle_slot,
    shape_text,
    status_line,
    step_slot,
    time_limit,
    user_interrupted,
    validate_belief,
    validate_estimate,
)

__all__ = [
    "CPU_BACKSTOP_FACTOR", "CPU_BACKSTOP_S", "HEADLESS_STEP_LIMIT_S", "MAX_COV", "MAX_MEAN",
    "NOT_BUILT", "SLOW_MIN_STEPS", "SLOW_STEP_MS", "SLOW_WINDOW", "WINDOW_STEP_LIMIT_S",
    "FilterExit", "FilterRunner", "FilterTimeout", "FilterTrack", "StepWatch", "bounded_track",
    "call_guarded", "check_estimate", "exit_text", "failure_line", "failure_of", "failure_text",
    "guarded_call", "is_filter_failure", "note_step_time", "note_user_interrupt", "one_line",
    "run_filter_code", "settle_slot", "shape_text", "status_line", "step_slot", "time_limit",
    "user_interrupted", "validate_belief", "validate_estimate",
]
