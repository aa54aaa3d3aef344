"""What every figure of docs/results.md shares: the paths, the seeds (``DOCS_SEED``,
``CHECK_SEED``), a figure's ``Context`` and ``Figure``, the evaluation table and its
checked quantities, and the intervals (bootstrap over runs, Wilson for rates)."""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from beacon_sim.evaluation import plots
from beacon_sim.evaluation.intervals import text as interval_text
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.summary import Thresholds, evaluate

ROOT = Path(__file__).resolve().parents[2]


DOCS = ROOT / "docs"


FIG = DOCS / "results"


def fmt(x, spec=".3f"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def with_iv(value, iv, spec) -> str:
    """``value [lo, hi]`` (the 95 % bootstrap interval over runs), ``-`` for no value."""
    if value is None:
        return "-"
    return f"{format(value, spec)} {interval_text(iv, spec)}".rstrip()


def recovery_cell(recovery: list[dict]) -> str:
    """Per kidnap: median recovery time [interval] and recovered count [interval]."""
    if not recovery:
        return "-"
    parts = []
    for r in recovery:
        med = "never" if r["median_s"] is None else f"{r['median_s']:.1f} s"
        parts.append(f"{med} {interval_text(r.get('median_s_interval'), '.1f')}, "
                     f"{r['recovered']}/{r['runs']} {interval_text(r.get('recovered_interval'), '.0f')}")
    return "; ".join(parts)


def md_table(meta) -> list[str]:
    lo, hi = next(iter(meta["filters"].values()))["anees_band"]
    out = [f"{meta['runs']} runs x {meta['steps']} steps (dt {meta['dt']:g} s), seeds "
           f"{meta['seed']}..{meta['seed'] + meta['runs'] - 1}. PCRB: position "
           f"{meta['pcrb']['pos_rmse_m']:.4f} m, heading {meta['pcrb']['heading_rmse_rad']:.4f} rad. "
           f"ANEES 95 % band [{lo:.2f}, {hi:.2f}]. Brackets: 95 % bootstrap intervals over the "
           "runs.", "",
           "| filter | pos RMSE [m] | heading RMSE [rad] | MSE x [m²] | MSE y [m²] | MSE θ [rad²] "
           "| ANEES | verdict | ANIS/dof | diverged | RMSE/PCRB | µs/step | recovery after kidnap |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for name, r in meta["filters"].items():
        iv = r.get("intervals") or {}
        anees = with_iv(r["anees"], iv.get("anees"), ".2f")
        ratio = with_iv(r["rmse_over_pcrb"], iv.get("rmse_over_pcrb"), ".2f")
        verdict = r.get("verdict", r["anees_verdict"])
        rmse = with_iv(r["pos_rmse_m"], r.get("pos_rmse_interval"), ".4f")
        out.append(f"| {name} | {rmse} | {fmt(r['heading_rmse_rad'], '.4f')} "
                   f"| {fmt(r['mse_x'], '.2e')} | {fmt(r['mse_y'], '.2e')} | {fmt(r['mse_theta'], '.2e')} "
                   f"| {anees} | {verdict} | {fmt(r['anis'], '.2f')} | {r['divergences']}/{meta['runs']} "
                   f"| {ratio} | {fmt(r['us_per_step'], '.1f')} | {recovery_cell(r['recovery'])} |")
        if r.get("below_bound_reason"):
            notes.append(f"- {name}: {r['below_bound_reason']}.")
    return out + (["", *notes] if notes else [])


def figures(sc, curves, meta, stem) -> list[str]:
    if not plots.available():
        return [f"({plots.INSTALL_HINT})"]
    paths = plots.plot_all(dataclasses.replace(sc, name=stem), curves, FIG, meta["runs"])
    return ["", *[f"![{p.stem}](results/{p.name})" for p in paths[1:]] +
            [f"![{paths[0].stem}](results/{paths[0].name})"], ""]


def run(sc, filters, runs, jobs, duration=None, thresholds=None, params=None, *, seed: int):
    t = time.perf_counter()
    # batch=False: the cost columns are each filter's own per-step cost, as `beacon-sim run`
    # reports it (the batched Monte Carlo path gives the same figures, but cheaper costs).
    rs = run_monte_carlo(sc, filters, runs, seed=seed, duration=duration, jobs=jobs, params=params,
                         progress=True, batch=False)  # a bar, or lines in a log
    meta, curves = evaluate(sc, rs, thresholds or Thresholds())
    print(f"{sc.name}: {runs} runs (seeds {seed}..{seed + runs - 1}) of {', '.join(filters)} "
          f"in {time.perf_counter() - t:.1f} s", file=sys.stderr)
    return rs, meta, curves


def wilson_interval(k: int, n: int, z: float = 1.96) -> list[float]:
    """The 95 % Wilson score interval [lo, hi] of a rate of ``k`` successes in ``n`` trials."""
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return [max(0.0, c - h), min(1.0, c + h)]


def wilson(k: int, n: int) -> str:
    """``k/n = rate [lo, hi]`` with the 95 % Wilson interval."""
    lo, hi = wilson_interval(k, n)
    return f"{k}/{n} = {k / n:.2f} [{lo:.2f}, {hi:.2f}]"


def splice_section(text: str, header: str, section: list[str]) -> str:
    """``text`` (results.md) with the section that starts at ``header`` replaced by
    ``section`` (up to the next ``## `` heading or the closing ``_Generated`` line)."""
    lines = text.split("\n")
    if header not in lines:
        raise SystemExit(f"docs/results.md has no line {header!r}: run the whole script")
    a = lines.index(header)
    b = next((i for i in range(a + 1, len(lines))
              if lines[i].startswith("## ") or lines[i].startswith("_Generated")), len(lines))
    return "\n".join(lines[:a] + section + lines[b:])


#: The seeds of the docs' figures: every seeded figure's runs start here (seeds 20000,
#: 20001, ...), and ``--check-seeds`` re-runs each figure from ``CHECK_SEED``. The tests use
#: seeds below 10000 (and a few huge ones that test parsing); nothing was tuned on either
#: range, so a figure made here is one nobody looked at before it was printed.
DOCS_SEED = 20000


CHECK_SEED = 30000


#: Where the docs run leaves each figure's checked quantities (value and interval), so that
#: ``--check-seeds`` compares against them without re-running the docs range.
CHECKS_FILE = FIG / "figures.json"


@dataclasses.dataclass
class Context:
    """What a figure function is given: its first seed, the run-count scale, the worker
    processes, the filters installed, the MRCLAM folder, and whether to draw PNGs."""

    seed: int
    scale: float
    jobs: int
    have: set[str]
    mrclam: Path | None = None
    draw: bool = True

    def n(self, k: int) -> int:
        """The number of runs of a figure sized for ``k`` runs."""
        return max(2, round(k * self.scale))

    def seeds(self, k: int) -> str:
        """The seeds of ``n(k)`` runs, as the docs print them."""
        return f"{self.seed}..{self.seed + self.n(k) - 1}"


#: A checked quantity: its value and its 95 % interval ([lo, hi], ends may be None).
Check = tuple[float | None, list | None]


@dataclasses.dataclass
class Figure:
    """A section of results.md (without its heading) and the quantities ``--check-seeds``
    compares between seed ranges (name -> value and interval)."""

    md: list[str]
    checks: dict[str, Check] = dataclasses.field(default_factory=dict)


def pos_rmse_interval(rs, name: str) -> list | None:
    """95 % bootstrap interval over the runs of filter ``name``'s position RMSE."""
    from beacon_sim.evaluation.intervals import ratio_of_sums

    err = np.stack([r.filters[name].err for r in rs])
    pos2 = err[..., 0] ** 2 + err[..., 1] ** 2
    ok = np.isfinite(pos2)
    return ratio_of_sums(np.where(ok, pos2, 0.0).sum(axis=1), ok.sum(axis=1).astype(float), sqrt=True)


def table_checks(meta, rs) -> dict[str, Check]:
    """The checked quantities of an evaluation table: per filter the position RMSE, the
    ANEES, RMSE/PCRB and, per kidnap, the runs recovered."""
    out: dict[str, Check] = {}
    for name, r in meta["filters"].items():
        iv = r.get("intervals") or {}
        out[f"{name} pos RMSE [m]"] = (r["pos_rmse_m"], r.get("pos_rmse_interval"))
        out[f"{name} ANEES"] = (r["anees"], iv.get("anees"))
        if r["rmse_over_pcrb"] is not None:
            out[f"{name} RMSE/PCRB"] = (r["rmse_over_pcrb"], iv.get("rmse_over_pcrb"))
        for k, rec in enumerate(r["recovery"]):
            out[f"{name} recovered after kidnap {k + 1} (of {rec['runs']})"] = (
                rec["recovered"], rec.get("recovered_interval"))
    return out


def evaluated(ctx: Context, sc, filters, k: int, duration=None, jobs=None):
    """``run`` from the context's first seed, with each filter's position-RMSE interval."""
    rs, meta, curves = run(sc, filters, ctx.n(k), ctx.jobs if jobs is None else jobs,
                           duration=duration, seed=ctx.seed)
    for name, r in meta["filters"].items():
        r["pos_rmse_interval"] = pos_rmse_interval(rs, name)
    return rs, meta, curves


def drawn(ctx: Context, sc, curves, meta, stem) -> list[str]:
    """The figure's PNGs (docs run only: the check run draws nothing)."""
    return figures(sc, curves, meta, stem) if ctx.draw else []


def helper_module(folder: str, name: str):
    """A module of ``scripts/`` or ``benchmarks/`` (``symmetric_room_modes``, ``bench_mcl``),
    imported by name so that worker processes find it too: the figures reuse their runs."""
    import importlib

    where = str(ROOT / folder)
    if where not in sys.path:
        sys.path.insert(0, where)
    return importlib.import_module(name)


def mean_interval(values) -> list | None:
    """95 % bootstrap interval over runs of the mean of per-run ``values``."""
    from beacon_sim.evaluation.intervals import ratio_of_sums

    a = np.asarray(values, dtype=float)
    return ratio_of_sums(a, np.ones(len(a)))


def rms_interval(values) -> list | None:
    """95 % bootstrap interval over runs of the RMS of per-run RMS ``values`` (runs of equal length)."""
    from beacon_sim.evaluation.intervals import ratio_of_sums

    a = np.asarray(values, dtype=float)
    return ratio_of_sums(a * a, np.ones(len(a)), sqrt=True)
