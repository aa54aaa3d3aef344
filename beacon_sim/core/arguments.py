"""The numbers a run is given (seed, duration, tick), checked in one place for the command
line (``--seed 3``), the Python API (``seed=3``) and ``Scenario.with_changes``.

``label`` names the argument in the message: an option (``"--seed"``, the message reads
``--seed -1: ...``) or a keyword ending in ``=`` (``"seed="``, read ``seed=-1: ...``); the
text after the colon is the same for both.
"""

from __future__ import annotations

import math
import numbers

from beacon_sim.errors import BeaconSimError, UsageError

#: Largest seed: numpy's generators take 0 .. 2^63 - 1 here.
MAX_SEED = 2**63 - 1


def _named(label: str, value: object, spec: str = "") -> str:
    """``seed=-1`` for a keyword, ``--seed -1`` for an option (``spec``: its number format)."""
    return f"{label}{value!r}" if label.endswith("=") else f"{label} {value:{spec}}"


def check_seed(seed: object, label: str = "seed=", error: type[BeaconSimError] = UsageError) -> int | None:
    """``seed``: None or a whole number from 0 to 2^63 - 1 (not a string, not a bool);
    returns it as an ``int``."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= int(seed) <= MAX_SEED:
        raise error(f"{_named(label, seed)}: expected a seed from 0 to 2^63 - 1")
    return int(seed)


def check_duration(duration: object, dt: float | None = None, max_ticks: int | None = None,
                   label: str = "duration=", error: type[BeaconSimError] = UsageError) -> float | None:
    """``duration`` [s]: None or a positive, finite number; with the tick ``dt`` [s], at
    least one tick and at most ``max_ticks`` ticks. Returns it as a ``float``."""
    if duration is None:
        return None
    if isinstance(duration, bool) or not isinstance(duration, numbers.Real) \
            or not (float(duration) > 0 and math.isfinite(duration)):
        raise error(f"{_named(label, duration)}: expected a positive number of seconds")
    duration = float(duration)
    if dt is not None:
        ratio = duration / dt  # a float: 1e308 / 0.1 is inf, which round() cannot take
        if max_ticks is not None and ratio > max_ticks + 0.5:
            raise error(f"{_named(label, duration, 'g')}: over {max_ticks:,} ticks of "
                        f"{dt:g} s (at most {max_ticks * dt:g} s)")
        if not math.isfinite(ratio):
            raise error(f"{_named(label, duration, 'g')}: too long for a tick of {dt:g} s")
        ticks = round(ratio)
        if ticks < 1:
            raise error(f"{_named(label, duration, 'g')}: shorter than one tick of {dt:g} s")
        if max_ticks is not None and ticks > max_ticks:
            raise error(f"{_named(label, duration, 'g')}: over {max_ticks:,} ticks of "
                        f"{dt:g} s (at most {max_ticks * dt:g} s)")
    return duration


def check_tick(dt: object, lo: float, hi: float, label: str = "dt=",
               error: type[BeaconSimError] = UsageError) -> float:
    """``dt`` [s]: a number from ``lo`` to ``hi``."""
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not lo <= float(dt) <= hi:
        raise error(f"{_named(label, dt)}: expected a tick from {lo:g} to {hi:g} s")
    return float(dt)


#: The most simulated time one command may ask for in all [s]: runs x seconds per run (x
#: scenarios), about 11.6 days; a soak of one long run stays within it. Raise it with
#: ``BEACON_SIM_MAX_SIMULATED_S``.
MAX_SIMULATED_S = 1_000_000.0


def check_simulated_total(runs: int, seconds: float, label: str,
                          error: type[BeaconSimError] = UsageError) -> None:
    """Refuse ``runs`` runs of ``seconds`` simulated seconds each when together they exceed
    :data:`MAX_SIMULATED_S` (or ``BEACON_SIM_MAX_SIMULATED_S``); ``label`` names what asked
    (``"--runs 10000 x --duration 86400"``). The message has both numbers and the cap."""
    import os

    cap = MAX_SIMULATED_S
    raw = os.environ.get("BEACON_SIM_MAX_SIMULATED_S")
    if raw is not None:
        try:
            cap = float(raw)
        except ValueError:
            cap = math.nan
        if not (cap > 0 and math.isfinite(cap)):
            raise error(f"BEACON_SIM_MAX_SIMULATED_S={raw[:40]!r}: expected a positive number of seconds")
    total = runs * seconds
    if total > cap:
        raise error(f"{label}: {runs:,} runs x {seconds:,.6g} s = {total:,.0f} simulated seconds: at most "
                    f"{cap:,.0f} in one command (set BEACON_SIM_MAX_SIMULATED_S to raise it)")
