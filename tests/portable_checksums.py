"""Truth and readings checksums of every shipped scenario over a fixed number of ticks, and
digests of the portable kernels on fixed inputs: what must be the same bits on every machine
(tests/core/test_portable_math.py runs this under every numpy dispatch the machine can run, and
compares with the table in docs/portability.md).

``python tests/portable_checksums.py`` prints the JSON; ``--table`` prints the docs' table.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
from pathlib import Path

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario, load_team_scenario, shipped_team_scenarios
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team import TeamSimulation
from beacon_sim.runs.recorder import TeamReadingsHash

#: Ticks of each run in the table (docs/portability.md).
TICKS = 300


def scenario_checksums(ticks: int = TICKS) -> dict[str, tuple[str, str]]:
    """``{scenario: (truth checksum, readings checksum)}`` of every shipped scenario, run with
    its own seed and driver for ``ticks`` ticks."""
    out = {}
    for name in shipped_scenarios():
        sim = Simulation(load_scenario(name))
        for _ in range(ticks):
            sim.step()
        out[name] = (sim.truth_checksum, sim.readings_checksum)
    for name in shipped_team_scenarios():
        team = TeamSimulation(load_team_scenario(name))
        readings = TeamReadingsHash()
        for _ in range(ticks):
            readings.update(team.step())
        out[name] = (team.truth_checksum, readings.checksum)
    return out


def kernel_inputs(n: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """Fixed inputs in [-10, 10) from integer arithmetic (the same bits everywhere)."""
    k = np.arange(n, dtype=np.int64)
    x = ((k * 2654435761) % 1048576).astype(float) / 52428.8 - 10.0
    y = ((k * 40503 + 977) % 1048576).astype(float) / 52428.8 - 10.0
    return x, y


def kernel_digests() -> dict[str, str]:
    """12 hex digits of SHA-256 of each portable kernel's output on :func:`kernel_inputs`
    (arrays, and the float forms on the first 2000)."""
    x, y = kernel_inputs()
    outs = {
        "sincos": np.concatenate(pm.sincos(x)),
        "atan2": pm.atan2(y, x),
        "hypot": pm.hypot(x, y),
        "exp": pm.exp(x * 7.0),
        "log": pm.log(np.abs(x) * 100.0),
        "log1p": pm.log1p(np.abs(x)),
        "expm1": pm.expm1(x),
        "floats": np.array([v for a, b in zip(x[:2000].tolist(), y[:2000].tolist(), strict=True)
                            for v in (*pm.sincos1(a), pm.atan2_1(b, a), pm.hypot1(a, b))]),
    }
    return {k: hashlib.sha256(np.ascontiguousarray(v, dtype="<f8").tobytes()).hexdigest()[:12]
            for k, v in outs.items()}


def documented_checksums() -> dict[str, tuple[str, str]]:
    """The table of docs/portability.md as ``{scenario: (truth, readings)}``: the one home of
    the shipped scenarios' pinned checksums (over :data:`TICKS` ticks)."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "portability.md").read_text()
    rows = re.findall(r"^\| (\w+) \| `([0-9a-f]{16})` \| `([0-9a-f]{16})` \|$", doc, re.M)
    return {name: (truth, readings) for name, truth, readings in rows}


def table(checksums: dict[str, tuple[str, str]]) -> str:
    """The Markdown table docs/portability.md holds."""
    rows = ["| scenario | truth checksum | readings checksum |", "|---|---|---|"]
    rows += [f"| {name} | `{t}` | `{r}` |" for name, (t, r) in sorted(checksums.items())]
    return "\n".join(rows)


if __name__ == "__main__":
    sums = scenario_checksums()
    if "--table" in sys.argv:
        print(table(sums))
    else:
        print(json.dumps({"scenarios": sums, "kernels": kernel_digests()}, sort_keys=True))
