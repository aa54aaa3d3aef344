"""``grade.html`` and each student's page: self-contained HTML (inline CSS and a small
script to sort the table), pseudonyms where asked.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

from beacon_sim.core.files import (
    write_text_atomic,
)
from beacon_sim.evaluation.grading.config import GradeError
from beacon_sim.evaluation.grading.csv_table import failure_text
from beacon_sim.evaluation.grading.scoring import SCAN_REFERENCE_SPEC, SLAM_REFERENCE_SPEC, status
from beacon_sim.evaluation.grading.students import LOG_BYTES
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M

_CSS = """body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse}
th,td{border:1px solid #ccc;padding:4px 8px;vertical-align:top}th{background:#eef;cursor:pointer}
tr.failed td{background:#fdecea}tr.suspicious td{background:#fff3cd}
.flag{font-size:85%;color:#8a5a00;max-width:28em}td.num{text-align:right;font-variant-numeric:tabular-nums}
.why{font-size:85%;color:#a00;max-width:28em}.note{color:#555;font-size:90%}"""

_JS = """
function sortBy(col, dir) {
  var body = document.getElementById('board').tBodies[0];
  var rows = Array.prototype.slice.call(body.rows);
  rows.sort(function (a, b) {
    var fa = +a.dataset.failed, fb = +b.dataset.failed;
    if (fa !== fb) return fa - fb;            /* a failed filter never above a working one */
    var x = a.dataset[col], y = b.dataset[col];
    var nx = parseFloat(x), ny = parseFloat(y);
    var c = (isNaN(nx) || isNaN(ny)) ? String(x).localeCompare(String(y)) : nx - ny;
    if (isNaN(nx) !== isNaN(ny)) c = isNaN(nx) ? 1 : -1;
    return dir * c;
  });
  rows.forEach(function (r) { body.appendChild(r); });
  document.getElementById('board').dataset.sorted = col + (dir > 0 ? '' : '-desc');
}
document.querySelectorAll('#board th[data-col]').forEach(function (th) {
  th.addEventListener('click', function () {
    var d = th.dataset.dir === '1' ? -1 : 1; th.dataset.dir = String(d); sortBy(th.dataset.col, d);
  });
});
var m = /sort=([a-z_]+)(-desc)?/.exec(location.hash);
if (m) sortBy(m[1], m[2] ? -1 : 1);
"""


def _reference_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on team scenarios: how a filter is graded there, and the
    built-in independent EKF's figures on the same seeds."""
    ref = board.get("reference") or {}
    if not ref:
        return ""
    parts = [f"{html.escape(n)}: {r['pos_rmse_m']:.4f} m, ANEES {r['anees']:.2f}"
             if r["pos_rmse_m"] is not None else f"{html.escape(n)}: failed" for n, r in ref.items()]
    return (" On a team scenario each student's filter is every robot's own filter (beacon readings "
            "only); its figures are the team's (RMSE over all robots, mean ANEES; RMSE/PCRB against "
            "each robot's bound alone). The built-in independent EKF on the same seeds: "
            + "; ".join(parts) + ".")


def _slam_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on SLAM scenarios: what the map columns mean, and the
    built-in EKF-SLAM's figures on the same seeds."""
    ref = board.get("slam_reference") or {}
    if not ref:
        return ""

    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    parts = [f"{html.escape(n)}: ATE {num(r['ate_m'], '.4f')} m, map GOSPA {num(r['map_gospa_m'], '.4f')} m, "
             f"joint NEES {num(r['joint_nees'], '.2f')}" for n, r in ref.items()]
    return (f" On a SLAM scenario (the filters are not given the beacon map) ATE is the path's RMS "
            f"position error over every seed (the pos RMSE on that scenario), map GOSPA the error "
            f"of the final map against the beacons it had to map "
            f"(cut-off {GOSPA_CUTOFF_M:g} m: a missed or a false landmark costs as much as one "
            f"{GOSPA_CUTOFF_M / math.sqrt(2):.2f} m off), joint NEES the final pose-and-map NEES "
            f"(for a filter with joint(); chi-square with 3 + 2M degrees of freedom), the last "
            f"two seed means. "
            f"The built-in {SLAM_REFERENCE_SPEC} on the same seeds: " + "; ".join(parts) + ".")


def _scan_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on scan scenarios: the built-in mcl's figures there."""
    ref = board.get("scan_reference") or {}
    if not ref:
        return ""
    parts = [f"{html.escape(n)}: {r['pos_rmse_m']:.4f} m" if r.get("pos_rmse_m") is not None
             else f"{html.escape(n)}: failed" for n, r in ref.items()]
    return (f" On a map world with a range finder each filter gets the occupancy grid (ctx.world.grid) "
            f"and the scans, never the pose; the built-in {SCAN_REFERENCE_SPEC} on the same seeds, "
            "position RMSE: " + "; ".join(parts) + ".")


def _notes(board: dict[str, Any]) -> str:
    """The page note's sentences on the team, SLAM and scan scenarios and their references."""
    return _reference_note(board) + _slam_note(board) + _scan_note(board)


def _isolation_banner(board: dict[str, Any]) -> str:
    """The page's warning when the students were not isolated from each other."""
    text = board.get("not_isolated")
    return f'<p class="why"><strong>{html.escape(text)}</strong></p>' if text else ""


def _sandbox_text(board: dict[str, Any]) -> str:
    level = board.get("sandbox", "process")
    text = ("bubblewrap sandbox: no network, read-only system, its own file alone" if level == "bwrap"
            else "process level: its own folder and limits, no OS sandbox: not isolated from the others")
    if board.get("team_in_process"):
        text += "; team scenarios in process, not isolated"
    return text


def pseudonym(student: str, board: dict[str, Any]) -> str:
    """A student's stable pseudonym on the class page: the same for the same class and
    configuration, not guessable from the name without the configuration's seeds."""
    import hashlib

    cfg = board["config"]
    key = f"{student}|{cfg['seeds']}|{cfg['scenarios']}".encode()
    return "student-" + hashlib.sha256(key).hexdigest()[:6]


def shown_names(board: dict[str, Any]) -> dict[str, str]:
    """Student -> the name the class page shows (the pseudonym with ``pseudonyms``)."""
    anon = bool(board["config"].get("pseudonyms"))
    return {r["student"]: pseudonym(r["student"], board) if anon else r["student"] for r in board["rows"]}


def write_html(board: dict[str, Any], path: Path) -> Path:
    """A self-contained leaderboard page (inline CSS, JS and SVG plots): click a column
    to sort (``#sort=COLUMN`` or ``#sort=COLUMN-desc`` in the address sorts on load)."""
    cfg = board["config"]
    cols = [("rank", "rank"), ("student", "student"), ("pos_rmse_m", "pos RMSE [m]"),
            ("heading_rmse_rad", "heading RMSE [rad]"), ("anees", "ANEES"),
            ("verdict", "consistency"), ("rmse_over_pcrb", "RMSE/PCRB"),
            ("us_per_step", "cost [us/step]"), ("failed_runs", "failed runs")]
    if board.get("slam_reference"):  # a SLAM assignment: the map columns
        cols[3:3] = [("ate_m", "ATE [m]"), ("map_gospa_m", "map GOSPA [m]"), ("joint_nees", "joint NEES")]
    if cfg.get("rubric"):  # the course's points, as results.json gives them
        total = sum(float(item["points"]) for item in cfg["rubric"])
        cols.insert(2, ("rubric_score", f"points (of {total:g})"))

    def cell(r: dict[str, Any], key: str) -> str:
        v = r.get(key, r["anees_verdict"]) if key == "verdict" else r.get(key)
        if v is None:
            return '<td class="num">&ndash;</td>'
        if isinstance(v, float):
            two = ("anees", "rmse_over_pcrb", "joint_nees")
            fmt = ".1f" if key == "us_per_step" else (".2f" if key in two else ".4f")
            if key == "rubric_score":
                fmt = "g"
            return f'<td class="num">{v:{fmt}}</td>'
        if isinstance(v, int):
            return f'<td class="num">{v}</td>'
        return f"<td>{html.escape(str(v))}</td>"

    body = []
    shown = shown_names(board)
    for r0 in board["rows"]:
        r = {**r0, "student": shown[r0["student"]]}
        data = " ".join(f'data-{k}="{html.escape("" if r.get(k) is None else str(r[k]))}"' for k, _ in cols)
        why = "<br>".join(html.escape(failure_text(f)) for f in r["failures"][:4])
        more = len(r["failures"]) - 4
        if more > 0:
            why += f"<br>... and {more} more"
        flags = "<br>".join(html.escape(f) for f in r.get("flags", []))
        st = status(r)
        kind = {"FAILED": "failed", "SUSPICIOUS": "suspicious"}.get(st, "ok")
        log = f' <a href="students/{html.escape(r["student"])}.html">page</a>'
        if r.get("log"):
            log += f' <a href="logs/{html.escape(r["student"])}.log">log</a>'

        order = {"ok": 0, "suspicious": 1, "failed": 2}[kind]  # the page's sort keeps this order
        body.append(f'<tr class="{kind}" data-failed="{order}" {data}>' + "".join(cell(r, k) for k, _ in cols)
                    + f'<td>{st}{log}<div class="why">{why}</div><div class="flag">{flags}</div></td>'
                    + f"<td>{r['plot']}</td></tr>")
    head = "".join(f'<th data-col="{k}">{html.escape(t)}</th>' for k, t in cols)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>beacon-sim grade</title>
<style>{_CSS}</style></head><body>
<h1>Leaderboard</h1>
{_isolation_banner(board)}
<p class="note">{board['students']} students, {board['runs_per_student']} runs each: scenarios
{html.escape(', '.join(cfg['scenarios']))}; seeds {html.escape(', '.join(map(str, cfg['seeds'])))};
{'each scenario' + chr(39) + 's duration' if cfg['duration'] is None else f"{cfg['duration']:g} s"} per run;
time limit {cfg['time_limit']:g} s per run. A filter that failed in any run has no score and
ranks below every working filter, whatever the column sorted; a suspicious result (far below
the Cramer-Rao bound) is kept out of the ranking, below the working filters, with its reason.
Each student's filter ran in a process of its own ({html.escape(_sandbox_text(board))}).
Click a column to sort.
Plot: position error [m] against time [s] of the first seed.{_notes(board)}</p>
<table id="board"><thead><tr>{head}<th>status and failures</th><th>error, first seed</th></tr></thead>
<tbody>
{chr(10).join(body)}
</tbody></table>
<script>{_JS}</script>
</body></html>
"""
    write_text_atomic(path, page, what="grade page", error=GradeError)
    return path


def write_student_page(board: dict[str, Any], row: dict[str, Any], path: Path, shown: str,
                       log: str) -> Path:
    """One student's page: the figures, each run, failures, warnings, the plot and the log."""
    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    runs = "".join(
        f"<tr><td>{html.escape(str(d['scenario']))}</td><td class=num>{d['seed']}</td>"
        f"<td class=num>{num(d['pos_rmse_m'], '.4f')}</td><td class=num>{d['steps']}</td>"
        f"<td class=num>{num(d['us_per_step'], '.1f')}</td>"
        f"<td class=why>{html.escape(d['failed'] or '')}</td></tr>" for d in row.get("run_detail", []))
    flags = "".join(f"<li>{html.escape(f)}</li>" for f in row.get("flags", []))
    fails = "".join(f"<li>{html.escape(failure_text(f))}</li>" for f in row["failures"])
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(shown)}: beacon-sim grade</title>
<style>{_CSS}</style></head><body>
<h1>{html.escape(shown)}</h1>
<p class="note"><a href="../grade.html">the class page</a>. Rank {row['rank']} of {board['students']};
status {status(row)}; position RMSE {num(row['pos_rmse_m'], '.4f')} m; heading RMSE
{num(row['heading_rmse_rad'], '.4f')} rad; ANEES {num(row['anees'], '.2f')}
({html.escape(str(row['anees_verdict']))});
RMSE/PCRB {num(row['rmse_over_pcrb'], '.2f')}; {num(row['us_per_step'], '.1f')} us per step.</p>
{_slam_table(row)}
{_rubric_table(row)}
<h2>Runs</h2>
<table><thead><tr><th>scenario</th><th>seed</th><th>pos RMSE [m]</th><th>steps</th><th>cost [us/step]</th>
<th>failure</th></tr></thead><tbody>{runs}</tbody></table>
{'<h2>Failures</h2><ul class="why">' + fails + '</ul>' if fails else ''}
{'<h2>Warnings</h2><ul class="flag">' + flags + '</ul>' if flags else ''}
<h2>Position error [m] against time [s], first seed</h2>{row['plot']}
<h2>Log (stdout and stderr, cut at {LOG_BYTES // 1024} KB)</h2>
<pre>{html.escape(log) or '(nothing printed)'}</pre>
</body></html>
"""
    write_text_atomic(path, page, what="grade page", error=GradeError)
    return path


def _slam_table(row: dict[str, Any]) -> str:
    """A student page's map figures, per SLAM scenario, beside the reference's."""
    slam = row.get("slam") or {}
    if not slam:
        return ""

    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    keys = (("ate_m", ".4f"), ("reference_ate_m", ".4f"), ("map_gospa_m", ".4f"),
            ("reference_map_gospa_m", ".4f"), ("map_landmarks", ".1f"), ("map_missed", ".1f"),
            ("map_false", ".1f"), ("joint_nees", ".2f"), ("reference_joint_nees", ".2f"))
    lines = "".join(f"<tr><td>{html.escape(n)}</td>"
                    + "".join(f"<td class=num>{num(v[k], fmt)}</td>" for k, fmt in keys) + "</tr>"
                    for n, v in slam.items())
    return ("<h2>The map (SLAM scenarios; ATE over every seed, the rest seed means)</h2>"
            "<table><thead><tr><th>scenario</th><th>ATE [m]</th>"
            f"<th>{SLAM_REFERENCE_SPEC} ATE</th><th>map GOSPA [m]</th><th>{SLAM_REFERENCE_SPEC} GOSPA</th>"
            "<th>landmarks</th><th>missed</th><th>false</th><th>joint NEES</th>"
            f"<th>{SLAM_REFERENCE_SPEC} joint NEES</th></tr></thead><tbody>{lines}</tbody></table>")


def _rubric_table(row: dict[str, Any]) -> str:
    """A student page's rubric: each test's points and what was measured (results.json's)."""
    tests = row.get("rubric")
    if not tests:
        return ""
    lines = "".join(f"<tr><td>{html.escape(t['name'])}</td><td class=num>{t['score']:g}</td>"
                    f"<td class=num>{t['max_score']:g}</td>"
                    f"<td>{html.escape(t['output'] or '')}</td></tr>"
                    for t in tests)
    return (f"<h2>Points: {row['rubric_score']:g} of {row['rubric_max']:g}</h2>"
            "<table><thead><tr><th>test</th>"
            f"<th>points</th><th>of</th><th>measured</th></tr></thead><tbody>{lines}</tbody></table>")
