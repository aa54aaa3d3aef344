"""The terminal tables of ``run`` and ``replay`` (``eval`` prints its own:
beacon_sim/evaluation/report.py)."""

from __future__ import annotations

from typing import Any


def fmt(x: float, spec: str) -> str:
    """A figure for a table; huge ones (ANEES after a kidnap) in exponent form."""
    return format(x, spec) if abs(x) < 1e5 else format(x, ".2e")


def failed_text(r: dict[str, Any]) -> str:
    """``FAILED at 3.00 s: reason`` for a filter row of ``run``, ``replay`` or ``mrclam``."""
    at = r.get("failed_time_s")
    return f"FAILED{'' if at is None else f' at {at:.2f} s'}: {r['failed']}"


def print_run(d: dict[str, Any]) -> None:
    """The summary of one headless run (``RunResult.as_json()``)."""
    print(f"scenario {d['scenario']}  seed {d['seed']}  steps {d['steps']} "
          f"({d['sim_time_s']:g} s simulated)  distance {d['distance_m']:.2f} m")
    meas = ", ".join(f"{k}: {v}" for k, v in d["measurements"].items()) or "none"
    print(f"measurements  {meas}")
    ev = ", ".join(f"{e['kind']} at {e['time']:.2f} s" for e in d["events"]) or "none"
    print(f"events        {ev}")
    rate = d.get("steps_per_s")
    print(f"truth checksum {d['truth_checksum']}  ("
          + (f"{rate:.0f} simulation steps/s)" if rate is not None else "no steps)"))
    if d["filters"]:
        print(f"{'filter':<16}{'pos RMSE m':>11}{'head RMSE':>11}{'MSE x':>10}{'MSE y':>10}"
              f"{'MSE th':>10}{'ANEES':>9}{'us/step':>9}")
        for name, r in d["filters"].items():
            if "failed" in r:
                print(f"{name:<16}{failed_text(r)}")
                continue
            if r.get("pos_rmse_m") is None:
                print(f"{name:<16}no estimate (no steps)")
                continue
            print(f"{name:<16}{r['pos_rmse_m']:>11.4f}{r['heading_rmse_rad']:>11.4f}"
                  f"{r['mse_x']:>10.4f}{r['mse_y']:>10.4f}{r['mse_theta']:>10.4f}"
                  f"{fmt(r['anees'], '.2f'):>9}{r['us_per_step']:>9.1f}")
