"""Tidy tables: a run's truth, estimates (long form), readings, events and metrics
as DataFrames that pandas' plotting takes directly, one name per field in the API, the
``.npz`` and the ``.csv`` files, and exports written with the old names still loading."""

from __future__ import annotations

import csv
import warnings

import numpy as np
import pandas as pd
import pytest

import beacon_sim as bs
from beacon_sim.core.metrics import nees, pose_errors
from beacon_sim.io.export import csv_paths


@pytest.fixture(scope="module")
def run():
    # a kidnap (an event with poses) and two filters
    return bs.run("sparse_kidnap", ["ekf", "dead_reckoning"], seed=3, duration=25)


def test_estimates_are_long_form_with_covariance_errors_and_nees(run):
    df = run.to_frame("estimates")
    T = len(run.controls)
    assert len(df) == 2 * T and list(df["filter"].unique()) == ["ekf", "dead_reckoning"]
    for name in run.filter_names:
        rows = df[df["filter"] == name]
        np.testing.assert_array_equal(rows["tick"], np.arange(1, T + 1))
        np.testing.assert_array_equal(rows["time_s"], run.time[1:])
        np.testing.assert_array_equal(rows[["x_m", "y_m", "theta_rad"]].to_numpy(), run.estimates[name])
        cov = run.covariances[name]
        for col, (a, b) in {"cov_xx": (0, 0), "cov_xy": (0, 1), "cov_xt": (0, 2), "cov_yy": (1, 1),
                            "cov_yt": (1, 2), "cov_tt": (2, 2)}.items():
            np.testing.assert_array_equal(rows[col], cov[:, a, b])
        err = pose_errors(run.estimates[name], run.truth[1:])
        np.testing.assert_array_equal(rows[["err_x_m", "err_y_m", "err_theta_rad"]].to_numpy(), err)
        np.testing.assert_allclose(rows["err_pos_m"], np.hypot(err[:, 0], err[:, 1]), rtol=1e-12)
        np.testing.assert_allclose(rows["nees"], nees(err, cov), rtol=1e-9)
    # mean NEES of the table = the run's ANEES
    assert df[df["filter"] == "ekf"]["nees"].mean() == pytest.approx(run.metrics()["filters"]["ekf"]["anees"])


def test_readings_events_truth_and_metrics_are_one_row_per_thing(run):
    tabs = run.tables()
    assert set(tabs) == {"truth", "estimates", "readings", "events", "metrics"}
    steps = run.result.steps
    rd = tabs["readings"]
    assert len(rd) == sum(len(m) for s in steps for m in s.measurements)
    first = next(m for s in steps for m in s.measurements)
    assert rd["kind"].iloc[0] == first.kind == "range_bearing"
    assert rd["range_m"].iloc[0] == first.z[0, 0] and rd["bearing_rad"].iloc[0] == first.z[0, 1]
    assert rd.loc[rd["kind"] == "range_bearing", "x_m"].isna().all()
    ev = tabs["events"]
    kid = ev[ev["kind"] == "kidnap"]
    assert len(kid) == 1
    want = next(e for s in steps for e in s.events if e.kind == "kidnap")
    np.testing.assert_array_equal(kid[["x_after_m", "y_after_m", "theta_after_rad"]].to_numpy()[0],
                                  want.pose_after)
    tr = tabs["truth"]
    np.testing.assert_array_equal(tr[["x_m", "y_m", "theta_rad"]].to_numpy(), run.truth)
    np.testing.assert_array_equal(tr[["v_mps", "omega_radps"]].to_numpy()[1:], run.controls)
    me = tabs["metrics"].set_index("filter")
    assert me.loc["ekf", "pos_rmse_m"] == run.metrics()["filters"]["ekf"]["pos_rmse_m"]
    assert me.loc["ekf", "failed"] == ""
    # the same dicts are plain columns: pandas takes them without help
    assert pd.DataFrame(run.readings).shape == rd.shape
    assert pd.DataFrame(run.events).shape == ev.shape


def test_pandas_plotting_takes_the_frames_directly(run):
    matplotlib = pytest.importorskip("matplotlib")  # the plot extra (in the test extra)
    matplotlib.use("Agg", force=False)
    df = run.to_frame("estimates")
    wide = df.pivot(index="time_s", columns="filter", values="err_pos_m")
    ax = wide.plot()
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"ekf", "dead_reckoning"}
    assert len(ax.get_lines()) == 2 and len(ax.get_lines()[0].get_xdata()) == len(run.controls)
    ax2 = run.to_frame("readings").plot.scatter(x="time_s", y="range_m")
    assert ax2.collections
    import matplotlib.pyplot as plt

    plt.close("all")


def _rows(path):
    with path.open(newline="") as f:
        return list(csv.reader(f))


def test_one_name_per_field_in_the_api_the_npz_and_the_csv(run, tmp_path):
    run.export(tmp_path / "r.npz")
    run.export(tmp_path / "r.csv")
    with np.load(tmp_path / "r.npz") as z:
        keys = set(z.files)
    paths = csv_paths(tmp_path / "r.csv")
    for table in ("readings", "events"):
        header = _rows(paths[table])[0]
        assert header == list(run.columns(table))           # CSV = API
        assert {f"{table}_{c}" for c in header} <= keys      # npz = API, prefixed by the table
    assert _rows(paths["truth"])[0] == list(run.columns("truth"))
    assert _rows(paths["estimates"])[0] == list(run.columns("estimates"))
    for source in (tmp_path / "r.npz", tmp_path / "r.csv"):  # both load back to the same frames
        loaded = bs.load_tables(source)
        for name, df in loaded.items():
            pd.testing.assert_frame_equal(df, run.to_frame(name), check_dtype=False)


def _old_npz(arrays):
    """The arrays as ``beacon-sim export`` wrote them before 0.3.0."""
    old = {k: v for k, v in arrays.items() if not k.startswith(("readings_", "events_", "truth_time"))}
    old["truth_time"] = arrays["truth_time_s"]
    for new, was in (("tick", "tick"), ("time_s", "time"), ("sensor", "sensor"), ("kind", "kind"),
                     ("beacon_id", "beacon_id"), ("hdop", "hdop")):
        old[f"meas_{was}"] = arrays[f"readings_{new}"]
    z = np.full((len(arrays["readings_tick"]), 3), np.nan)
    rb = arrays["readings_kind"] == "range_bearing"
    z[rb, 0], z[rb, 1] = arrays["readings_range_m"][rb], arrays["readings_bearing_rad"][rb]
    old["meas_z"] = z
    for new, was in (("tick", "tick"), ("time_s", "time"), ("kind", "kind"), ("detail", "detail")):
        old[f"event_{was}"] = arrays[f"events_{new}"]
    for w in ("before", "after"):
        old[f"event_pose_{w}"] = np.column_stack([arrays[f"events_x_{w}_m"], arrays[f"events_y_{w}_m"],
                                                  arrays[f"events_theta_{w}_rad"]])
    return old


def test_an_npz_with_the_old_names_still_loads(run, tmp_path):
    arrays = run.arrays()
    assert set(run.readings["kind"]) == {"range_bearing"}  # what _old_npz writes back
    np.savez_compressed(tmp_path / "old.npz", **_old_npz(arrays))
    loaded = bs.load_tables(tmp_path / "old.npz")
    for name in ("truth", "estimates", "readings", "events"):
        pd.testing.assert_frame_equal(loaded[name], run.to_frame(name), check_dtype=False)


def test_csv_files_with_the_old_names_still_load(run, tmp_path):
    """Before 0.3.0: ``X.measurements.csv`` with ``z0..z2``, event poses without units."""
    new = tmp_path / "new.csv"
    run.export(new)
    old = tmp_path / "old.csv"
    p_new, p_old = csv_paths(new), csv_paths(old)
    for table in ("truth", "estimates"):
        p_old[table].write_text(p_new[table].read_text())
    cols = run.columns("readings")
    with (tmp_path / "old.measurements.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["tick", "time_s", "sensor", "kind", "beacon_id", "z0", "z1", "z2", "hdop"])
        for i in range(len(cols["tick"])):
            w.writerow([int(cols["tick"][i]), repr(float(cols["time_s"][i])), cols["sensor"][i],
                        cols["kind"][i], int(cols["beacon_id"][i]), repr(float(cols["range_m"][i])),
                        repr(float(cols["bearing_rad"][i])), "nan", repr(float(cols["hdop"][i]))])
    rows = _rows(p_new["events"])
    rows[0] = [{"x_before_m": "x_before", "y_before_m": "y_before", "theta_before_rad": "theta_before",
                "x_after_m": "x_after", "y_after_m": "y_after", "theta_after_rad": "theta_after"}.get(c, c)
               for c in rows[0]]
    with p_old["events"].open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    loaded = bs.load_tables(old)
    for name in ("truth", "estimates", "readings", "events"):
        pd.testing.assert_frame_equal(loaded[name], run.to_frame(name), check_dtype=False)


def test_the_apis_old_names_still_work_with_a_warning(run):
    with pytest.warns(DeprecationWarning, match="old name"):
        z = run.readings["z"]
    np.testing.assert_array_equal(z[:, 0], run.readings["range_m"])
    with pytest.warns(DeprecationWarning):
        np.testing.assert_array_equal(run.readings["time"], run.readings["time_s"])
    with pytest.warns(DeprecationWarning):
        after = run.events["pose_after"]
    assert after.shape == (len(run.events["kind"]), 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run.readings["time_s"]  # the new names: no warning
    with pytest.raises(KeyError):
        run.readings["no_such_column"]


def test_bad_table_names_and_files_are_one_line_errors(run, tmp_path):
    with pytest.raises(bs.UsageError, match="expected one of truth, estimates"):
        run.to_frame("estimate")
    (tmp_path / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(bs.BeaconSimError):
        bs.load_tables(tmp_path / "x.npz")
    np.savez(tmp_path / "y.npz", a=np.zeros(2))
    with pytest.raises(bs.RecordingError, match="not a beacon-sim export"):
        bs.load_tables(tmp_path / "y.npz")
