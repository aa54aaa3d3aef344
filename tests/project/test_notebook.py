"""examples/python_api.ipynb runs top to bottom in a fresh kernel (nbclient, the test extra),
and shows what it says: the three filters' arrays, the metrics, the events, the plots and the
Monte Carlo error bands drawn by seaborn from ``evaluate``'s per-tick frame as it is."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "python_api.ipynb"
KERNEL = "beacon-sim-test"


def test_the_python_api_notebook_runs_top_to_bottom(tmp_path, monkeypatch):
    # A kernel spec of our own: this interpreter (with this checkout's beacon_sim), whatever
    # "python3" kernels the machine has.
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": KERNEL, "language": "python"}))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("PYTHONPATH", str(NOTEBOOK.parent.parent))
    nb = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(nb, timeout=120, kernel_name=KERNEL,
                   resources={"metadata": {"path": str(tmp_path)}}).execute()  # raises on an error
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    for name in ("ekf", "pf", "RangeOnlyEKF"):
        assert f"{name:12s} estimates (600, 3)" in text
        assert f"{name:12s} position RMSE" in text
    assert "['blackout_start', 'blackout_end']" in text
    assert "'err_pos_m', 'nees']" in text                               # the tidy tables
    assert sum("image/png" in o.get("data", {}) for o in outputs) == 4  # four figures drawn
    # the Monte Carlo bands: seaborn straight from evaluate()'s per-tick frame
    assert "6400 rows: 8 runs x 2 filters x 400 ticks" in text
    band = next(c for c in nb.cells if c.cell_type == "code" and "sns.lineplot(ticks" in c.source)
    assert "pivot" not in band.source and "melt" not in band.source
    assert any("image/png" in o.get("data", {}) for o in band.outputs)
