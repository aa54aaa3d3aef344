"""eval's CSV tables are numbers a spreadsheet or pandas reads as they are: the recovery
columns agree with eval.json's figures, and a field has one name in every file."""

from __future__ import annotations

import csv
import json
import math

import numpy as np

from beacon_sim.cli.main import main
from beacon_sim.evaluation.mc_tables import RUN_COLUMNS
from beacon_sim.evaluation.report import COLUMNS, RECOVERY_COLUMNS


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_recovery_columns_are_numbers_that_agree_with_the_json(tmp_path):
    out = tmp_path / "ev"
    assert main(["eval", "sparse_kidnap", "--filter", "ekf", "--filter", "dead_reckoning",
                 "--runs", "4", "--seed", "11", "--jobs", "1", "--duration", "40", "--out", str(out)]) == 0
    doc = json.loads((out / "eval.json").read_text())
    table = _rows(out / "eval.csv")
    runs = _rows(out / "eval_runs.csv")
    recovery = _rows(out / "eval_recovery.csv")
    assert tuple(table[0]) == COLUMNS and tuple(recovery[0]) == RECOVERY_COLUMNS
    for row in table:
        r = doc["filters"][row["filter"]]
        kidnaps = len(r["recovery"])
        assert kidnaps >= 1
        assert int(row["kidnap_runs"]) == kidnaps * 4
        assert int(row["recovered_runs"]) == sum(k["recovered"] for k in r["recovery"])
        assert int(row["diverged_runs"]) == r["divergences"]
        # The pooled median is the median of the per-run columns, never-recovered as inf.
        mine = [rr for rr in runs if rr["filter"] == row["filter"]]
        times = [float(rr[f"recovery_{k + 1}_s"]) for rr in mine for k in range(kidnaps)]
        assert float(row["recovery_median_s"]) == float(np.median(times))
        for k, kid in enumerate(rr for rr in recovery if rr["filter"] == row["filter"]):
            assert int(kid["kidnap"]) == k + 1
            assert int(kid["recovered_runs"]) == r["recovery"][k]["recovered"]
            per_kidnap = [float(rr[f"recovery_{k + 1}_s"]) for rr in mine]
            assert sum(math.isfinite(t) for t in per_kidnap) == int(kid["recovered_runs"])
            want = r["recovery"][k]["median_s"]
            assert float(kid["recovery_median_s"]) == (math.inf if want is None else want)
    # Every cell parses as a number except the named text columns.
    text = {"scenario", "filter", "anees_verdict", "verdict", "anis_verdict", "first_failure", "failed"}
    for path in ("eval.csv", "eval_runs.csv", "eval_recovery.csv"):
        for row in _rows(out / path):
            for key, cell in row.items():
                if key not in text and cell != "":
                    float(cell)


def test_one_name_per_field_and_units_in_the_names():
    shared = {"pos_rmse_m", "heading_rmse_rad", "anees", "us_per_step", "scenario", "filter"}
    assert shared <= set(COLUMNS) and shared <= set(RUN_COLUMNS)
    for name in ("mse_x_m2", "mse_y_m2", "mse_theta_rad2"):
        assert name in COLUMNS and name in RUN_COLUMNS
    for old in ("mse_x", "recovery", "divergences", "nees_steps_in_band"):
        assert old not in COLUMNS
    # A column whose quantity has a unit says it.
    for name in (*COLUMNS, *RECOVERY_COLUMNS):
        if "rmse" in name and "over" not in name:
            assert name.endswith(("_m", "_rad")), name
        if "median" in name or "max_s" in name:
            assert name.endswith(("_s", "_s_lo", "_s_hi")), name
