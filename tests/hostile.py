"""A seeded generator of hostile input: malformed scenarios mutated from the
shipped ones, hand-made scenarios, bad recordings, bad MRCLAM folders, bad command lines and
faulty filters. Every case is a command line for ``beacon-sim`` plus the files it needs;
tests/cli/test_hostile_corpus.py runs them and checks exit status 0 or 2, at most two lines on
stderr for exit 2, no traceback, and a time bound.
"""

from __future__ import annotations

import dataclasses
import json
import math
import random
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from beacon_sim.core.resources import scenario_dir

#: Values a mutation puts in place of a number, a list or a string.
EXTREMES: list[Any] = [0, -1, 0.0, -0.0, 1e-9, 1e-300, 1e9, 1e300, 1e308, -1e308, math.inf, -math.inf,
                       math.nan, 2**63, -(2**63), 10**30, 1.5, True, "x", "", [], [1e308, 0, 0],
                       [math.nan, 1, 2], {}, [[0, 0]], [[math.nan, 0]]]


@dataclass
class Case:
    """One hostile input: ``argv`` for ``beacon-sim`` and files to write first
    (name -> text), relative to the case's folder."""

    name: str
    argv: list[str]
    files: dict[str, str] = field(default_factory=dict)


# --------------------------------------------------------------------------- TOML writing
def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def dump_toml(data: dict[str, Any]) -> str:
    """A TOML document for ``data`` (tables as inline tables: enough for the corpus)."""
    return "".join(f"{json.dumps(k)} = {_value(v)}\n" for k, v in data.items())


# --------------------------------------------------------------------------- scenarios
def _leaves(obj: Any, path: tuple = ()) -> list[tuple]:
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.append((*path, k))
            out.extend(_leaves(v, (*path, k)))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out.append((*path, i))
            out.extend(_leaves(v, (*path, i)))
    return out


def _set(obj: Any, path: tuple, value: Any) -> None:
    for p in path[:-1]:
        obj = obj[p]
    obj[path[-1]] = value


def _delete(obj: Any, path: tuple) -> None:
    for p in path[:-1]:
        obj = obj[p]
    del obj[path[-1]]


def shipped() -> dict[str, dict[str, Any]]:
    return {p.stem: tomllib.loads(p.read_text(encoding="utf-8"))
            for p in sorted(scenario_dir().glob("*.toml"))}


def mutate(rng: random.Random, document: dict[str, Any]) -> dict[str, Any]:
    """A copy of a scenario document with one to three leaves replaced by an extreme value
    (or, one time in seven, deleted)."""
    data = json.loads(json.dumps(document))
    for _ in range(rng.randint(1, 3)):
        leaves = _leaves(data)
        if not leaves:
            break
        path = rng.choice(leaves)
        if rng.random() < 0.15:
            _delete(data, path)
        else:
            _set(data, path, rng.choice(EXTREMES))
    return data


def mutated_scenarios(rng: random.Random, n: int) -> list[Case]:
    """``n`` scenarios, each a shipped one with one to three leaves replaced by an extreme
    value or deleted, run headless for a second with the EKF and dead reckoning."""
    base = shipped()
    names = sorted(base)
    cases = []
    for i in range(n):
        data = mutate(rng, base[rng.choice(names)])
        data["default_filters"] = ["ekf", "dead_reckoning"]
        argv = ["run", "s.toml", "--duration", "1"]
        if rng.random() < 0.2:
            argv = ["run", "s.toml", "--duration", "1", "--filter", rng.choice(["pf", "histogram"]),
                    "--set", "pf.n_particles=200" if "pf" in argv else "histogram.cell=0.5"]
            argv[-1] = "pf.n_particles=200" if argv[-3] == "pf" else "histogram.cell=0.5"
        cases.append(Case(f"mutated-{i}", argv, {"s.toml": dump_toml(data)}))
    return cases


def mutated_team_scenarios(rng: random.Random, n: int) -> list[Case]:
    """``n`` team scenarios, each a shipped one (``scenarios/team/``) with one to three leaves
    replaced by an extreme value or deleted, run headless for a second, or played for a
    few frames in the window (one in five)."""
    base = {p.stem: tomllib.loads(p.read_text(encoding="utf-8"))
            for p in sorted((scenario_dir() / "team").glob("*.toml"))}
    names = sorted(base)
    cases = []
    for i in range(n):
        data = mutate(rng, base[rng.choice(names)])
        argv = ["run", "t.toml", "--duration", "1"]
        if i % 5 == 4:
            argv = ["play", "t.toml", "--frames", "3", "--screenshot", "shot.png"]
        cases.append(Case(f"team-mutated-{i}", argv, {"t.toml": dump_toml(data)}))
    return cases


_ROOM = ('dt = 0.1\nduration = 5\n[world]\nbounds = [0, 0, 10, 8]\nbeacons = [{ id = 1, x = 2, y = 2 }, '
         '{ id = 2, x = 8, y = 6 }]\n[robot]\ninitial_pose = [5, 4, 0]\n')
_SENSOR = '[[sensors]]\nkind = "range_bearing"\nname = "b"\n'


def hand_made_scenarios() -> list[Case]:
    """Scenarios written for one extreme each (the numbers the issue names, and more)."""
    texts = {
        "period-zero": _ROOM + _SENSOR + "period = 0\n",
        "period-inf": _ROOM + _SENSOR + "period = inf\n",
        "period-huge": _ROOM + _SENSOR + "period = 1e308\n",
        "event-time-inf": _ROOM + '[[events]]\nkind = "kidnap"\ntime = inf\nrandom = true\n',
        "event-time-huge": _ROOM + '[[events]]\nkind = "kidnap"\ntime = 1e308\nrandom = true\n',
        "blackout-1e9": _ROOM + _SENSOR + '[[events]]\nkind = "blackout"\ntime = 1\nduration = 1e9\n',
        "burst-inf": _ROOM + '[[events]]\nkind = "noise_burst"\ntime = 1\nduration = inf\nv_std = 1\n',
        "burst-v-inf": _ROOM + '[[events]]\nkind = "noise_burst"\ntime = 1\nduration = 1\nv_std = inf\n',
        "margin-huge": _ROOM + '[driver]\nkind = "random_goal"\nmargin = 1e308\n',
        "margin-wide": _ROOM + '[driver]\nkind = "random_goal"\nmargin = 4\n',
        "speed-inf": _ROOM + '[driver]\nkind = "random_goal"\nspeed = inf\n',
        "circle-speed-huge": _ROOM + '[driver]\nkind = "circle"\nspeed = 1e308\n',
        "omega-inf": _ROOM + '[driver]\nkind = "constant"\nv = 0.1\nomega = inf\n',
        "v-nan": _ROOM + '[driver]\nkind = "constant"\nv = nan\n',
        "waypoints-nan": _ROOM + '[driver]\nkind = "waypoints"\npoints = [[nan, 1], [2, 2]]\n',
        "waypoints-inf": _ROOM + '[driver]\nkind = "waypoints"\npoints = [[inf, 1]]\n',
        "v-std-inf": _ROOM + '[robot.motion_noise]\nv_std = inf\n',
        "v-std-huge": _ROOM + '[robot.motion_noise]\nv_std = 1e300\n',
        "omega-frac-inf": _ROOM + '[robot.motion_noise]\nomega_frac = inf\n',
        "pose-std-huge": _ROOM + '[robot.motion_noise]\npose_std = [1e308, 0, 0]\n',
        "duration-inf": _ROOM.replace("duration = 5", "duration = inf"),
        "duration-1e300": _ROOM.replace("duration = 5", "duration = 1e300"),
        "duration-tiny": _ROOM.replace("duration = 5", "duration = 1e-9"),
        "dt-tiny": _ROOM.replace("dt = 0.1", "dt = 1e-9"),
        "dt-zero": _ROOM.replace("dt = 0.1", "dt = 0"),
        "dt-nan": _ROOM.replace("dt = 0.1", "dt = nan"),
        "seed-negative": _ROOM + "seed = -1\n",
        "seed-huge": "seed = 100000000000000000000000\n" + _ROOM,
        "bounds-huge": _ROOM.replace("[0, 0, 10, 8]", "[-1e308, -1e308, 1e308, 1e308]"),
        "bounds-inf": _ROOM.replace("[0, 0, 10, 8]", "[0, 0, inf, 8]"),
        "beacon-x-inf": _ROOM.replace("x = 2,", "x = inf,"),
        "beacon-id-huge": _ROOM.replace("id = 1,", "id = 100000000000000000000,"),
        "beacon-dup": _ROOM.replace("id = 2,", "id = 1,"),
        "many-beacons": (_ROOM.split("beacons")[0] + "beacons = ["
                         + ", ".join(f"{{ id = {i}, x = {i % 10}, y = {i % 8} }}" for i in range(20000))
                         + "]\n[robot]\ninitial_pose = [5, 4, 0]\n"),
        "many-events": _ROOM + "".join(f'[[events]]\nkind = "kidnap"\ntime = {i}\nrandom = true\n'
                                       for i in range(20000)),
        "initial-nan": _ROOM.replace("[5, 4, 0]", "[5, nan, 0]"),
        "initial-theta-huge": _ROOM.replace("[5, 4, 0]", "[5, 4, 1e308]"),
        "belief-std-inf": _ROOM + '[initial_belief]\nstd = [inf, 1, 1]\n',
        "belief-std-huge": _ROOM + '[initial_belief]\nstd = [1e300, 1, 1]\n',
        "belief-mean-huge": _ROOM + '[initial_belief]\nmean = [1e300, 1, 1]\n',
        "max-range-nan": _ROOM + _SENSOR + "max_range = nan\n",
        "max-range-inf": _ROOM + _SENSOR + "max_range = inf\n",
        "bearing-std-inf": _ROOM + _SENSOR + "bearing_std = inf\n",
        "range-std-huge": _ROOM + _SENSOR + "range_std = 1e308\n",
        "min-beacons-huge": _ROOM + _SENSOR + "min_beacons = 1000000000000\n",
        "model-inf": _ROOM + _SENSOR + '[model.sensors.b]\nbearing_std = inf\n',
        "model-noise-nan": _ROOM + '[model.motion_noise]\nv_std = nan\n',
        "keyboard-inf": _ROOM + '[keyboard]\nv_max = inf\n',
        "filters-file": _ROOM + 'default_filters = ["evil.py:Evil", "ekf"]\n',
        "filters-abs-file": _ROOM + 'default_filters = ["/tmp/evil.py:Evil"]\n',
        "filters-module": _ROOM + 'default_filters = ["os:system"]\n',
        "filters-label-file": _ROOM + 'default_filters = ["a=evil.py:Evil"]\n',
        "filter-params-nan": _ROOM + '[filters.ekf]\ngate_chi2 = nan\n',
        "filter-params-pf-huge": _ROOM + 'default_filters = ["pf"]\n[filters.pf]\nn_particles = 1000000000\n',
        "filter-params-grid-tiny": (_ROOM + 'default_filters = ["histogram"]\n'
                                    '[filters.histogram]\ncell = 1e-5\n'),
        "filter-params-unknown": _ROOM + '[filters.ekf]\nbogus = 1\n',
        "not-toml": "this is [ not toml\n",
        "binary": "\x00\x01\x02",
        "empty": "",
        "top-array": "x = [1, 2\n",
        "world-string": 'world = "big"\n[robot]\ninitial_pose = [0, 0, 0]\n',
        "sensors-table": _ROOM + "sensors = 3\n",
        "events-number": _ROOM + "events = 5\n",
        "event-kind-bad": _ROOM + '[[events]]\nkind = "explode"\ntime = 1\n',
        "kidnap-offset-nan": _ROOM + '[[events]]\nkind = "kidnap"\ntime = 1\noffset = [nan, 0, 0]\n',
        "kidnap-pose-huge": _ROOM + '[[events]]\nkind = "kidnap"\ntime = 1\npose = [1e300, 0, 0]\n',
        "fov-zero": _ROOM + _SENSOR + "fov = 0\n",
        "detection-2": _ROOM + _SENSOR + "detection_prob = 2\n",
        "outlier-nan": _ROOM + _SENSOR + "outlier_rate = nan\n",
        "beacon-height-inf": _ROOM + _SENSOR.replace("range_bearing", "position") + "beacon_height = inf\n",
        "radius-inf": _ROOM.replace("initial_pose = [5, 4, 0]", "initial_pose = [5, 4, 0]\nradius = inf"),
        "name-long": f'name = "{"n" * 10000}"\n' + _ROOM,
        "circle-radius-tiny": _ROOM + '[driver]\nkind = "circle"\nradius = 1e-300\n',
        "gain-huge": _ROOM + '[driver]\nkind = "random_goal"\ngain = 1e308\n',
        "tolerance-inf": _ROOM + '[driver]\nkind = "waypoints"\npoints = [[1, 1]]\ntolerance = inf\n',
        "ok-room": _ROOM + _SENSOR,
    }
    cases = []
    for name, text in texts.items():
        for cmd in (["run", "s.toml"], ["eval", "s.toml", "--runs", "1", "--jobs", "1"]):
            argv = [*cmd, "--duration", "2"] if "duration" not in name else cmd
            cases.append(Case(f"hand-{name}-{cmd[0]}", argv, {"s.toml": text, "evil.py": EVIL}))
    return cases


EVIL = "raise SystemExit('a scenario made me run code')\n"


# --------------------------------------------------------------------------- recordings
def recording_text(tmp: Path) -> str:
    """A short real recording of ``default`` (written by the Recorder)."""
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.runs.live import Session
    from beacon_sim.runs.recorder import Recorder

    sc = load_scenario("sparse_kidnap")
    path = tmp / "base.jsonl"
    params = {"pf": {"n_particles": 300}}
    session = Session(sc, ["ekf", "pf"], 3, params, Recorder(path, sc, 3, ["ekf", "pf"], params))
    session.toggle_autopilot()  # the scenario's driver, as a recorder without a window records
    for k in range(1, 31):
        if k == 10:
            session.command({"kind": "reset"})
        session.tick()
    session.close()
    return path.read_text(encoding="utf-8")


def team_recording_text(tmp: Path) -> str:
    """A short real team recording of ``team_sparse`` (written by the Recorder): the
    keys drive the scout, Tab, a kidnap and a reset."""
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.runs.live import Session
    from beacon_sim.runs.recorder import Recorder

    team = load_team_scenario("team_sparse")
    path = tmp / "team_base.jsonl"
    s = Session(team, ["independent", "centralised"], 2, {},
                Recorder(path, team, 2, ["independent", "centralised"]))
    for k in range(1, 41):
        if k == 3:
            s.drive("w")
        if k == 12:
            s.next_robot()
        if k == 20:
            s.command({"kind": "kidnap"})
        if k == 30:
            s.command({"kind": "reset"})
        s.tick()
    s.close()
    return path.read_text(encoding="utf-8")


def bad_recordings(rng: random.Random, base: str, n: int) -> list[Case]:
    """Hand-made corruptions of a recording, then ``n`` random ones."""
    lines = base.splitlines()
    header = json.loads(lines[0])

    def with_header(**changes) -> str:
        h = dict(header)
        for k, v in changes.items():
            if v is None:
                h.pop(k, None)
            else:
                h[k] = v
        return "\n".join([json.dumps(h), *lines[1:]]) + "\n"

    toml = header["scenario_toml"]
    made = {
        "empty": "",
        "header-only": lines[0] + "\n",
        "not-json": "hello\n",
        "binary": "\x00\xff" * 10,
        "truncated": base[: len(base) // 2],
        "version-99": with_header(version=99),
        "version-1": with_header(version=1, scenario_sha256=None),
        "version-string": with_header(version="2"),
        "no-toml": with_header(scenario_toml=None),
        "bad-toml": with_header(scenario_toml="[[[", scenario_sha256=None, version=1),
        "seed-negative": with_header(seed=-5),
        "seed-huge": with_header(seed=10**40),
        "dt-string": with_header(dt="x"),
        "filters-file": with_header(filters=["evil.py:Evil", "ekf"]),
        "filters-not-strings": with_header(filters=[1, 2]),
        "params-particles-huge": with_header(params={"pf": {"n_particles": 10**9}}),
        "params-particles-float": with_header(params={"pf": {"n_particles": 1e9}}),
        "params-grid-tiny": with_header(filters=["histogram"], params={"histogram": {"cell": 1e-5}}),
        "params-nan": with_header(params={"ekf": {"gate_chi2": float("nan")}}),
        "params-not-dict": with_header(params={"ekf": 3}),
        "toml-edited": with_header(scenario_toml=toml.replace("dt = 0.1", "dt = 0.2")),
        "toml-inf": with_header(scenario_toml=toml + "\nduration = inf\n", version=1,
                                scenario_sha256=None),
        "ticks-stripped": "\n".join(ln for ln in lines if '"tick"' not in ln) + "\n",
        "tick-gap": "\n".join(ln for ln in lines if '"k":5,' not in ln) + "\n",
        "control-nan": base.replace('"u":[', '"u":[NaN,', 1).replace("NaN,", "NaN", 1),
        "control-huge": base.replace('"u":[', '"u":[1e308,0],"x":[', 1),
        "command-bad": base.replace('"c":[{"kind":"reset"}]', '"c":[{"kind":"explode"}]'),
        "command-pose-short": base.replace('"c":[{"kind":"reset"}]', '"c":[{"kind":"kidnap","pose":[1]}]'),
        "command-pose-nan": base.replace('"c":[{"kind":"reset"}]',
                                         '"c":[{"kind":"kidnap","pose":[NaN,1,1]}]'),
        "command-pose-huge": base.replace('"c":[{"kind":"reset"}]',
                                          '"c":[{"kind":"kidnap","pose":[1e308,1,1]}]'),
        "end-not-dict": base.rstrip("\n").rsplit("\n", 1)[0] + '\n{"type":"end","checksum":5}\n',
        "list-line": lines[0] + "\n[1,2,3]\n",
    }
    cases = [Case(f"rec-{k}", ["replay", "r.jsonl", "--headless"], {"r.jsonl": v})
             for k, v in made.items()]
    for i in range(n):
        ls = list(lines)
        for _ in range(rng.randint(1, 3)):
            j = rng.randrange(len(ls))
            ln = ls[j]
            op = rng.random()
            if op < 0.3 and len(ln) > 2:
                a = rng.randrange(len(ln))
                ls[j] = ln[:a] + rng.choice(["", "x", "9", "-", "}", '"', "1e308", "NaN"]) + ln[a + 1:]
            elif op < 0.5:
                del ls[j]
            elif op < 0.7:
                ls.insert(j, ls[rng.randrange(len(ls))])
            else:
                try:
                    obj = json.loads(ln)
                except json.JSONDecodeError:
                    continue
                if isinstance(obj, dict) and obj:
                    key = rng.choice(sorted(obj))
                    obj[key] = rng.choice(EXTREMES)
                    ls[j] = json.dumps(obj)
        cases.append(Case(f"rec-random-{i}", ["replay", "r.jsonl", "--headless"],
                          {"r.jsonl": "\n".join(ls) + "\n"}))
    return cases


# --------------------------------------------------------------------------- MRCLAM
_COMMENT = "# {what}\r\n# {cols}\r\n"


def mrclam_folder(rng: random.Random, corrupt: str) -> dict[str, str]:
    """A tiny MRCLAM folder (robot 1, 20 s) with one kind of corruption."""
    t0 = 1248272272.841
    lm = {6: (1.0, 1.0), 7: (4.0, 1.0), 8: (4.0, 4.0), 9: (1.0, 4.0)}
    barcodes = {1: 5, 2: 14, 6: 27, 7: 54, 8: 70, 9: 36}
    od, gt, me = [], [], []
    for k in range(2000):
        t = t0 + 0.01 * k
        od.append(f"{t:.3f} \t 0.1 \t 0.05")
        gt.append(f"{t:.3f} \t {2 + 0.001 * k:.6f} \t 2.0 \t 0.0")
        if k % 25 == 0:
            me.append(f"{t:.3f} \t {barcodes[6 + (k // 25) % 4]} \t 2.0 \t 0.1")
    files = {
        "Barcodes.dat": "".join(f"{s} \t {b}\r\n" for s, b in barcodes.items()),
        "Landmark_Groundtruth.dat": "".join(f"{s} \t {x} \t {y} \t 0 \t 0\r\n" for s, (x, y) in lm.items()),
        "Robot1_Odometry.dat": "\r\n".join(od) + "\r\n",
        "Robot1_Groundtruth.dat": "\r\n".join(gt) + "\r\n",
        "Robot1_Measurement.dat": "\r\n".join(me) + "\r\n",
    }
    name = rng.choice(sorted(f for f in files if f.startswith("Robot")))
    rows = files[name].split("\r\n")
    j = rng.randrange(len(rows) - 1)
    if corrupt == "stamp-huge":
        rows[j] = "1e15" + rows[j][rows[j].index(" "):]
    elif corrupt == "stamp-nan":
        rows[j] = "nan" + rows[j][rows[j].index(" "):]
    elif corrupt == "stamp-inf":
        rows[j] = "inf" + rows[j][rows[j].index(" "):]
    elif corrupt == "stamp-negative":
        rows[j] = "-1e9" + rows[j][rows[j].index(" "):]
    elif corrupt == "value-inf":
        rows[j] = rows[j].rsplit("\t", 1)[0] + "\t inf"
    elif corrupt == "value-huge":
        rows[j] = rows[j].rsplit("\t", 1)[0] + "\t 1e308"
    elif corrupt == "text":
        rows[j] = "abc def"
    elif corrupt == "binary":
        rows[j] = "\x00\x01"
    elif corrupt == "missing":
        files.pop(name)
        return files
    elif corrupt == "empty":
        rows = [""]
    elif corrupt == "backwards":
        rows = rows[::-1]
    elif corrupt == "landmarks-nan":
        files["Landmark_Groundtruth.dat"] = "6 \t nan \t 1 \t 0 \t 0\r\n"
        return files
    elif corrupt == "barcodes-dup":
        files["Barcodes.dat"] += "6 \t 27\r\n7 \t 27\r\n"
        return files
    files[name] = "\r\n".join(rows)
    return files


MRCLAM_CORRUPTIONS = ["none", "stamp-huge", "stamp-nan", "stamp-inf", "stamp-negative", "value-inf",
                      "value-huge", "text", "binary", "missing", "empty", "backwards", "landmarks-nan",
                      "barcodes-dup"]


def bad_mrclam(rng: random.Random, n: int) -> list[Case]:
    cases = []
    for i in range(n):
        corrupt = MRCLAM_CORRUPTIONS[i % len(MRCLAM_CORRUPTIONS)]
        files = {f"m/{k}": v for k, v in mrclam_folder(rng, corrupt).items()}
        argv = ["mrclam", "m", "--robot", "1", "--headless", "--filter", "ekf", "--filter", "dead_reckoning"]
        if i % 3 == 1:
            argv = ["mrclam", "m", "--robot", "1", "--calibrate"]
        if i % 3 == 2:
            argv = ["mrclam", "m", "--team", "--duration", "5"]
        cases.append(Case(f"mrclam-{corrupt}-{i}", argv, files))
    return cases


# --------------------------------------------------------------------------- command lines
def bad_command_lines(rng: random.Random, n: int) -> list[Case]:
    fixed = [
        ["run", "default", "--seed", "-1"], ["run", "default", "--seed", "99999999999999999999999"],
        ["run", "default", "--duration", "0.01"], ["run", "default", "--duration", "inf"],
        ["run", "default", "--duration", "nan"], ["run", "default", "--duration", "1e300"],
        ["run", "default", "--duration", "-1"], ["run", "default", "--duration", "x"],
        ["run", "default", "--set", "pf.n_particles=1.5", "--filter", "pf"],
        ["run", "default", "--set", "ekf.gate_chi2=nan", "--filter", "ekf"],
        ["run", "default", "--set", "pf.alpha_slow=-3", "--filter", "pf"],
        ["run", "default", "--set", "nosuchfilter.x=1"], ["run", "default", "--set", "garbage"],
        ["run", "default", "--set", "pf.n_particles=1000000000", "--filter", "pf"],
        ["run", "default", "--set", "histogram.cell=0.00001", "--filter", "histogram"],
        ["run", "default", "--filter", "nosuch"], ["run", "default", "--filter", "nosuch.py:X"],
        ["run", "default", "--filter", "os:nosuch"], ["run", "default", "--filter", ":"],
        ["run", "nosuch"], ["run", "/"], ["run", "/dev/null"], ["run", "."],
        ["eval", "default", "--runs", "0"], ["eval", "default", "--runs", "-5"],
        ["eval", "default", "--jobs", "0"], ["eval", "default", "--seed", "-3"],
        ["eval", "default", "--time-limit", "nan"], ["eval", "default", "--duration", "0.001"],
        ["eval", "default", "--out", "/proc/nope", "--runs", "1"],
        ["export", "default", "--out", "/nonexistent/x.npz"], ["export", "default", "--out", "x.txt"],
        ["export", "default", "--out", "/proc/x.npz"], ["export", "default", "--out", "."],
        ["play", "default", "--frames", "0"], ["play", "default", "--frames", "-1"],
        ["play", "default", "--size", "1x1"], ["play", "default", "--speed", "nan"],
        ["play", "default", "--speed", "100"], ["play", "default", "--screenshot", "/proc/x.png"],
        ["play", "default", "--gif", "x.png"], ["replay", "nosuch.jsonl"], ["replay", "/"],
        ["replay", "/dev/null", "--headless"], ["mrclam", "/nonexistent", "--robot", "1"],
        ["mrclam", ".", "--robot", "0"], ["mrclam", ".", "--robot", "99"], ["check", "nosuch"],
        ["grade", "/nonexistent"], ["new-filter", "/proc/x.py"], ["new-filter", "/"],
        ["nosuchcommand"], ["--nosuch"], ["run"], ["run", "default", "--json", "--json", "extra"],
    ]
    cases = [Case(f"cli-{i}", argv) for i, argv in enumerate(fixed)]
    words = ["run", "eval", "export", "replay", "mrclam", "check", "default", "--seed", "--duration",
             "--set", "--filter", "--runs", "--out", "-1", "0", "nan", "inf", "1e308", "x", "=", ".",
             "pf.n_particles=0", "ekf", "/", "--jobs", "--time-limit"]
    for i in range(n):
        argv = [rng.choice(["run", "eval", "export", "check"])] + [rng.choice(words)
                                                                   for _ in range(rng.randint(0, 5))]
        cases.append(Case(f"cli-random-{i}", argv))
    return cases


# --------------------------------------------------------------------------- filters
FAULTY_FILTERS = '''
import sys
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter as E

class ExitUpdate(E):
    def update(self, m): sys.exit(0)
class ExitPredict(E):
    def predict(self, c, dt): sys.exit(3)
class ExitInit(E):
    def __init__(self, ctx): sys.exit(3)
class KbInit(E):
    def __init__(self, ctx): raise KeyboardInterrupt
class RaiseInit(E):
    def __init__(self, ctx): raise RuntimeError("boom in __init__")
class RaiseReset(E):
    def reset(self, init): raise RuntimeError("boom in reset")
class RaiseEstimate(E):
    def estimate(self): raise RuntimeError("boom in estimate")
class RaiseBelief(E):
    def belief(self): raise RuntimeError("boom in belief")
class ExitBelief(E):
    def belief(self): sys.exit(0)
class StrMean(E):
    def estimate(self): return "abc", np.eye(3)
class HugeCov(E):
    def estimate(self): return np.zeros(3), np.eye(3) * 1e308
class NanMean(E):
    def estimate(self): return np.full(3, np.nan), np.eye(3)
class KbPredict(E):
    def predict(self, c, dt): raise KeyboardInterrupt
class WriteZ(E):
    def update(self, ms):
        for m in ms:
            m.z[...] = 0
        super().update(ms)
class WriteWorld(E):
    def predict(self, c, dt):
        self.ctx.world.beacon_xy[...] = 0
class Unwrite(E):
    def update(self, ms):
        for m in ms:
            m.z.flags.writeable = True
class LoopPredict(E):
    def predict(self, c, dt):
        while True:
            pass
class NotAFilter:
    def __init__(self, ctx): pass
'''

FILTER_CLASSES = ["ExitUpdate", "ExitPredict", "ExitInit", "KbInit", "RaiseInit", "RaiseReset",
                  "RaiseEstimate", "RaiseBelief", "ExitBelief", "StrMean", "HugeCov", "NanMean",
                  "KbPredict", "WriteZ", "WriteWorld", "Unwrite", "LoopPredict", "NotAFilter"]
IMPORT_FAULTS = {"exit_import.py": "import sys\nsys.exit(3)\n",
                 "kb_import.py": "raise KeyboardInterrupt\n",
                 "syntax.py": "def (:\n"}


def faulty_filter_cases(recording: str) -> list[Case]:
    """Each faulty filter beside the EKF in ``run``, ``replay --headless`` and ``mrclam``."""
    cases = []
    files = {"faulty.py": FAULTY_FILTERS, "r.jsonl": recording, **IMPORT_FAULTS}
    specs = [f"faulty.py:{c}" for c in FILTER_CLASSES] + [f"{f}:X" for f in IMPORT_FAULTS]
    for spec in specs:
        if "LoopPredict" in spec:  # the headless limit is 10 s a step: the window's test covers it
            continue
        for cmd in (["run", "default", "--duration", "1"], ["replay", "r.jsonl", "--headless"]):
            cases.append(Case(f"filter-{spec}-{cmd[0]}", [*cmd, "--filter", spec, "--filter", "ekf"],
                              files))
    return cases


# --------------------------------------------------------------------------- bounded work
def _shipped_text(name: str) -> str:
    return (Path(__file__).resolve().parents[1] / "scenarios" / f"{name}.toml").read_text(encoding="utf-8")


def bounded_work_cases() -> list[Case]:
    """Work with no bound, each refused at load with the number in the message (exit 2), or
    a filter that cannot run switched off in one line (exit 0), through every front end that
    reads it: clutter, beacons on an unknown map, runs x duration, a grade config's seeds x
    duration, MRCLAM time stamps a day apart, a localization filter on an unknown map."""
    lookalike = _shipped_text("lookalike_beacons").replace("clutter_rate = 0.1", "clutter_rate = 100")
    slam = _shipped_text("slam_loop")
    head, rest = slam.split("beacons = [", 1)
    many = "beacons = [\n" + "".join(f"  {{ id = {1000 + i}, x = {1 + (i % 40) * 0.3:.1f}, "
                                      f"y = {1 + (i // 40) * 0.3:.1f} }},\n" for i in range(600))
    slam_many = head + many + rest
    cases = []
    for label, text in (("clutter-100", lookalike), ("slam-600-beacons", slam_many)):
        for argv in SCENARIO_FRONT_ENDS:
            cases.append(Case(f"work-{label}-{argv[0]}", list(argv), {"s.toml": text}))
    cases.append(Case("work-eval-runs-x-duration",
                      ["eval", "default", "--runs", "100000", "--duration", "100"]))
    cases.append(Case("work-grade-seeds-x-duration", ["grade", "class", "--config", "g.toml"],
                      {"g.toml": f"seeds = {list(range(10_000))}\nduration = 86400\n",
                       "class/alice.py": "x = 1\n"}))
    cases.append(Case("work-unknown-map-ekf", ["run", "slam_loop", "--filter", "ekf", "--duration", "2"]))
    files = {f"m/{k}": v for k, v in mrclam_folder(random.Random(41), "none").items()}
    rows = files["m/Robot1_Odometry.dat"].split("\r\n")
    rows[len(rows) // 2] = "1e12" + rows[len(rows) // 2][rows[len(rows) // 2].index(" "):]
    files["m/Robot1_Odometry.dat"] = "\r\n".join(rows)
    for argv in (["mrclam", "m", "--robot", "1", "--headless", "--slam", "--filter", "ekf_slam"],
                 *MRCLAM_FRONT_ENDS):
        cases.append(Case(f"work-mrclam-stamp-1e12-{len(cases)}", list(argv), files))
    return cases


def corpus(tmp: Path, seed: int = 15, mutated: int = 200, recordings: int = 40, mrclam: int = 28,
           command_lines: int = 30, team: int = 60) -> list[Case]:
    """The whole corpus, deterministic for a seed."""
    rng = random.Random(seed)
    rec = recording_text(tmp)
    return (mutated_scenarios(rng, mutated) + hand_made_scenarios() + bad_recordings(rng, rec, recordings)
            + bad_mrclam(rng, mrclam) + bad_command_lines(rng, command_lines) + faulty_filter_cases(rec)
            + mutated_team_scenarios(random.Random(seed + 18), team)
            + [dataclasses.replace(c, name="team-" + c.name)
               for c in bad_recordings(random.Random(seed + 19), team_recording_text(tmp), 20)]
            + bounded_work_cases())


# --------------------------------------------------------------------------- files
#: The front ends that read a scenario file, as command lines (``s.toml`` in the case folder).
SCENARIO_FRONT_ENDS: list[list[str]] = [
    ["run", "s.toml", "--duration", "2"],
    ["play", "s.toml", "--frames", "3", "--no-record", "--autopilot"],
    ["eval", "s.toml", "--runs", "1", "--jobs", "1", "--duration", "2"],
    ["check", "ekf", "--scenario", "s.toml"],
]
#: The front ends that read a recording (``r.jsonl``): replay headless and in the window,
#: and export.
RECORDING_FRONT_ENDS: list[list[str]] = [
    ["replay", "r.jsonl", "--headless"],
    ["replay", "r.jsonl", "--frames", "3"],
    ["export", "r.jsonl", "--out", "r.npz"],
]
#: The front ends that read an MRCLAM folder (``m``).
MRCLAM_FRONT_ENDS: list[list[str]] = [
    ["mrclam", "m", "--robot", "1", "--headless", "--filter", "ekf", "--filter", "ukf"],
    ["mrclam", "m", "--robot", "1", "--frames", "3", "--filter", "ekf"],
    ["mrclam", "m", "--robot", "1", "--calibrate"],
]


def _deep(n: int, open_: str = "[", close: str = "]") -> str:
    return open_ * n + close * n


def issue24_scenarios() -> dict[str, str]:
    """Scenario texts that once ended in a traceback (each named by what is wrong), and new kinds."""
    room = _ROOM + _SENSOR
    big_beacons = ", ".join(f"{{id={i},x=1,y=1}}" for i in range(1_000_000))
    return {
        # the issue's
        "range-std-zero": room + "range_std = 0\n",
        "blackout-sensors-nested": room + '[[events]]\nkind = "blackout"\ntime = 1\nduration = 1\n'
                                          "sensors = [[1]]\n",
        "bounds-millimetres": _ROOM.replace("[0, 0, 10, 8]", "[0, 0, 0.003, 0.003]")
                              .replace("[5, 4, 0]", "[0.001, 0.001, 0]")
                              .replace("x = 2, y = 2", "x = 0.002, y = 0.002")
                              .replace("x = 8, y = 6", "x = 0.001, y = 0.002"),
        "nested-array-deep": "x = " + _deep(5000) + "\n" + _ROOM,
        "beacons-million": _ROOM.split("beacons")[0] + f"beacons = [{big_beacons}]\n"
                           "[robot]\ninitial_pose = [5, 4, 0]\n",
        "description-over-cap": f'description = "{"d" * 5_000_000}"\n' + _ROOM,
        # new kinds
        "bearing-std-zero": room + "bearing_std = 0\n",
        "model-range-std-zero": room + "[model.sensors.b]\nrange_std = 0\n",
        "position-std-zero": _ROOM + _SENSOR.replace("range_bearing", "position") + "position_std = 0\n",
        "heading-std-zero": _ROOM + '[[sensors]]\nkind = "pose"\nname = "c"\nheading_std = 0\n',
        "blackout-sensors-table": room + '[[events]]\nkind = "blackout"\ntime = 1\nduration = 1\n'
                                         "sensors = [{ a = 1 }]\n",
        "blackout-sensors-int": room + '[[events]]\nkind = "blackout"\ntime = 1\nduration = 1\n'
                                       "sensors = 3\n",
        "nested-table-deep": "x = " + _deep(3000, "{ a = ", " }").replace("{ a =  }", "{ a = 1 }")
                             + "\n" + _ROOM,
        "nested-array-500": "x = " + _deep(500) + "\n" + _ROOM,
        "integer-5000-digits": room + "min_beacons = " + "9" * 5000 + "\n",
        "seed-5000-digits": "seed = " + "1" * 5000 + "\n" + _ROOM,
        "bounds-reversed": _ROOM.replace("[0, 0, 10, 8]", "[10, 8, 0, 0]"),
        "bounds-sliver": _ROOM.replace("[0, 0, 10, 8]", "[0, 0, 10, 1e-6]")
                              .replace("[5, 4, 0]", "[5, 0, 0]"),
        "beacons-over-cap": (_ROOM.split("beacons")[0] + "beacons = ["
                             + ", ".join(f"{{id={i},x=1,y=1}}" for i in range(10_001))
                             + "]\n[robot]\ninitial_pose = [5, 4, 0]\n"),
        "events-over-cap": _ROOM + "".join(f'[[events]]\nkind = "kidnap"\ntime = {i}\nrandom = true\n'
                                           for i in range(10_001)),
        "long-line-key": room + "k" * 2_000_000 + " = 1\n",
        "control-characters-name": 'name = "a\\u0000b\\u001b[2J"\n' + room,
        "range-std-negative-zero": room + "range_std = -0.0\n",
        "range-std-subnormal": room + "range_std = 5e-324\n",
        "sensor-name-table": _ROOM + '[[sensors]]\nkind = "range_bearing"\nname = { a = 1 }\n',
    }


def issue24_recordings(base: str) -> dict[str, str]:
    """Corruptions of a real single-robot recording (kinds that once ended in a traceback, and new)."""
    lines = base.splitlines()
    reset = '"c":[{"kind":"reset"}]'
    assert reset in base, "the base recording holds a reset"

    def cmd(text: str) -> str:
        return base.replace(reset, '"c":[' + text + "]")

    def tick_u(u: str, at: int = 5) -> str:
        out = []
        for ln in lines:
            if ln.startswith(f'{{"type":"tick","k":{at},'):
                obj = json.loads(ln)
                ln = ln.replace(json.dumps(obj["u"], separators=(",", ":")), u, 1)
            out.append(ln)
        return "\n".join(out) + "\n"

    deep = _deep(100_000)
    return {
        # the issue's
        "kidnap-pose-dict": cmd('{"kind":"kidnap","pose":{"x":1,"y":2,"theta":0}}'),
        "kidnap-pose-int": cmd('{"kind":"kidnap","pose":3}'),
        "kidnap-pose-strings": cmd('{"kind":"kidnap","pose":["1","2","3"]}'),
        "toggle-list": cmd('{"kind":"toggle","filter":["ekf"]}'),
        "toggle-dict": cmd('{"kind":"toggle","filter":{"a":1}}'),
        "kidnap-pose-nan": cmd('{"kind":"kidnap","pose":[NaN,1,1]}'),
        "integer-5000-digits": tick_u("[" + "9" * 5000 + ",0]"),
        "nested-line": "\n".join([*lines[:5], '{"type":"tick","x":' + deep + "}", *lines[5:]]) + "\n",
        "nested-last-line": base + '{"type":"tick","x":' + deep + "}\n",
        "control-nan": tick_u("[NaN,0]"),
        "control-inf": tick_u("[Infinity,0]"),
        "control-huge": tick_u("[1e308,0]"),
        # new kinds
        "control-omega-nan": tick_u("[0.1,NaN]"),
        "control-neg-inf": tick_u("[-Infinity,0]"),
        "control-over-speed": tick_u("[1000.0,0]"),
        "control-strings": tick_u('["0.1","0"]'),
        "control-bool": tick_u("[true,false]"),
        "kidnap-pose-inf": cmd('{"kind":"kidnap","pose":[1,Infinity,0]}'),
        "kidnap-pose-bools": cmd('{"kind":"kidnap","pose":[true,false,true]}'),
        "kidnap-pose-outside": cmd('{"kind":"kidnap","pose":[1e6,1e6,0]}'),
        "kidnap-theta-huge": cmd('{"kind":"kidnap","pose":[1,1,1e300]}'),
        "kidnap-pose-null": cmd('{"kind":"kidnap","pose":null}'),
        "toggle-number": cmd('{"kind":"toggle","filter":5}'),
        "toggle-unknown": cmd('{"kind":"toggle","filter":"nosuch"}'),
        "commands-many": cmd(",".join(['{"kind":"reset"}'] * 5000)),
        "tick-k-float": base.replace('"k":5,', '"k":5.0,', 1),
        "tick-k-huge": base.replace('"k":5,', '"k":' + "9" * 400 + ",", 1),
        "seed-5000-digits": "\n".join([lines[0].replace('"seed":3', '"seed":' + "1" * 5000),
                                       *lines[1:]]) + "\n",
        "header-nested-params": "\n".join(
            [lines[0].replace('"params":{', '"params":{"deep":' + deep + ",", 1), *lines[1:]]) + "\n",
        "line-too-long": "\n".join([*lines[:3], '{"type":"tick","pad":"' + "x" * 20_000_000 + '"}',
                                    *lines[3:]]) + "\n",
        "bom-header": "\ufeff" + base,
        "crlf-lines": base.replace("\n", "\r\n"),
        "dt-nan": "\n".join([lines[0].replace('"dt":0.1', '"dt":NaN'), *lines[1:]]) + "\n",
        "checkpoint-k-negative": base.replace('{"type":"checkpoint","k":10',
                                              '{"type":"checkpoint","k":-10', 1),
        "checksum-number": base.replace('"h":"', '"h":1,"hh":"', 1),
        "filters-many": "\n".join([lines[0].replace('"filters":["ekf","pf"]',
                                                    '"filters":[' + ",".join(['"ekf"'] * 100_000) + "]"),
                                   *lines[1:]]) + "\n",
        "duplicate-keys": base.replace('{"type":"tick","k":5,', '{"type":"tick","k":5,"k":6,', 1),
    }


def issue24_team_recordings(base: str) -> dict[str, str]:
    """The same kinds on a real team recording (its kidnap of robot 1 replaced)."""
    kidnap = '"c":[{"kind":"kidnap","robot":1}]'
    assert kidnap in base, "the base team recording holds a kidnap"

    def cmd(text: str) -> str:
        return base.replace(kidnap, '"c":[' + text + "]")

    line5 = '{"type":"tick","k":5,"d":0,"u":[0.1,0.0]'
    assert line5 in base, "the base team recording drives robot 0 at 0.1 m/s on tick 5"

    def tick(new: str) -> str:
        return base.replace(line5, '{"type":"tick","k":5,' + new, 1)

    return {
        "team-kidnap-pose-dict": cmd('{"kind":"kidnap","robot":1,"pose":{"x":1}}'),
        "team-kidnap-pose-nan": cmd('{"kind":"kidnap","robot":1,"pose":[NaN,1,1]}'),
        "team-kidnap-pose-strings": cmd('{"kind":"kidnap","robot":1,"pose":["1","2","3"]}'),
        "team-kidnap-robot-float": cmd('{"kind":"kidnap","robot":1.0}'),
        "team-kidnap-robot-huge": cmd('{"kind":"kidnap","robot":' + "9" * 30 + "}"),
        "team-toggle-list": cmd('{"kind":"toggle","filter":["ci"]}'),
        "team-control-nan": tick('"d":0,"u":[NaN,0.0]'),
        "team-control-huge": tick('"d":0,"u":[1e308,0.0]'),
        "team-driven-huge": tick('"d":' + "9" * 5000 + ',"u":[0.1,0.0]'),
        "team-nested-last-line": base + '{"type":"tick","x":' + _deep(100_000) + "}\n",
    }


def issue24_mrclam(rng: random.Random) -> dict[str, dict[str, str]]:
    """MRCLAM folders with the issue's bad data (a landmark or a range of 1e308) and new kinds."""
    def folder(edit) -> dict[str, str]:
        files = mrclam_folder(random.Random(0), "none")
        edit(files)
        return files

    def set_row(name: str, j: int, row: str):
        def edit(files: dict[str, str]) -> None:
            rows = files[name].split("\r\n")
            rows[j] = row
            files[name] = "\r\n".join(rows)
        return edit

    def first_measurement(row_of):
        def edit(files: dict[str, str]) -> None:
            rows = files["Robot1_Measurement.dat"].split("\r\n")
            t = rows[3].split()[0]
            rows[3] = row_of(t)
            files["Robot1_Measurement.dat"] = "\r\n".join(rows)
        return edit

    return {
        "landmark-x-huge": folder(set_row("Landmark_Groundtruth.dat", 0, "6 \t 1e308 \t 1 \t 0 \t 0")),
        "landmark-y-negative-huge": folder(set_row("Landmark_Groundtruth.dat", 1,
                                                   "7 \t 4 \t -1e308 \t 0 \t 0")),
        "landmark-x-far": folder(set_row("Landmark_Groundtruth.dat", 2, "8 \t 1e7 \t 4 \t 0 \t 0")),
        "range-huge": folder(first_measurement(lambda t: f"{t} \t 27 \t 1e308 \t 0.1")),
        "range-negative": folder(first_measurement(lambda t: f"{t} \t 27 \t -2 \t 0.1")),
        "bearing-huge": folder(first_measurement(lambda t: f"{t} \t 27 \t 2 \t 1e308")),
        "barcode-5000-digits": folder(first_measurement(lambda t: f"{t} \t {'9' * 5000} \t 2 \t 0.1")),
        "odometry-v-huge": folder(set_row("Robot1_Odometry.dat", 5, "1248272272.891 \t 1e308 \t 0")),
        "odometry-omega-huge": folder(set_row("Robot1_Odometry.dat", 5, "1248272272.891 \t 0.1 \t 1e300")),
        "truth-x-huge": folder(set_row("Robot1_Groundtruth.dat", 5, "1248272272.891 \t 1e308 \t 2 \t 0")),
        "long-line": folder(set_row("Robot1_Odometry.dat", 5, "1" * 5_000_000)),
        "landmark-id-huge": folder(set_row("Landmark_Groundtruth.dat", 3, "9" * 30 + " \t 1 \t 4 \t 0 \t 0")),
    }


def issue24_cases(tmp: Path) -> list[Case]:
    """Inputs that once ended in a traceback, and new kinds, each through every front
    end that reads it (scenarios: run, play, eval, check; recordings: replay headless, in
    the window, export; MRCLAM: mrclam headless, window, calibrate); ``--duration`` in run,
    eval and mrclam. (A ``recordings`` that is not a folder: tests/runs/test_replay_verification.py.)"""
    cases = []
    for name, text in issue24_scenarios().items():
        for argv in SCENARIO_FRONT_ENDS:
            cases.append(Case(f"i24-scenario-{name}-{argv[0]}", list(argv), {"s.toml": text}))
    for name, text in {**issue24_recordings(recording_text(tmp)),
                       **issue24_team_recordings(team_recording_text(tmp))}.items():
        for argv in RECORDING_FRONT_ENDS:
            where = "headless" if "--headless" in argv else "export" if argv[0] == "export" \
                else "window"
            cases.append(Case(f"i24-recording-{name}-{where}", list(argv), {"r.jsonl": text}))
    for name, files in issue24_mrclam(random.Random(24)).items():
        for argv in MRCLAM_FRONT_ENDS:
            cases.append(Case(f"i24-mrclam-{name}-{argv[4].lstrip('-')}", list(argv),
                              {f"m/{k}": v for k, v in files.items()}))
    for cmd in (["run", "default"], ["eval", "default", "--runs", "1"],
                ["mrclam", "m", "--robot", "1", "--headless"]):
        for d in ("1e308", "1e300", "9" * 400, "1e19"):
            cases.append(Case(f"i24-duration-{d[:6]}-{cmd[0]}", [*cmd, "--duration", d],
                              {f"m/{k}": v for k, v in mrclam_folder(random.Random(0), "none").items()}
                              if cmd[0] == "mrclam" else {}))
    return cases


#: The kinds (old and new) that must be refused: exit 2 and this in the one
#: line on stderr (the file, the key or line, what was expected). Keyed by the case's kind.
ISSUE24_REFUSED: dict[str, str] = {
    "scenario-range-std-zero": "s.toml: sensors[0].range_std = 0: expected a number in [1e-06",
    "scenario-bearing-std-zero": "sensors[0].bearing_std = 0: expected",
    "scenario-model-range-std-zero": "model.sensors.b.range_std = 0: expected",
    "scenario-position-std-zero": "sensors[0].position_std = 0: expected",
    "scenario-heading-std-zero": "sensors[0].heading_std = 0: expected",
    "scenario-range-std-negative-zero": "range_std = -0.0: expected",
    "scenario-range-std-subnormal": "range_std = 5e-324: expected",
    "scenario-blackout-sensors-nested": "events[0].sensors = [[1]]: expected a list of sensor names",
    "scenario-blackout-sensors-table": "events[0].sensors",
    "scenario-bounds-millimetres": "world.bounds",
    "scenario-bounds-sliver": "world.bounds",
    "scenario-nested-array-deep": "nested too deep",
    "scenario-nested-table-deep": "nested too deep",
    "scenario-nested-array-500": "nested too deep",
    "scenario-beacons-million": "bytes: a scenario file holds at most",
    "scenario-description-over-cap": "bytes: a scenario file holds at most",
    "scenario-beacons-over-cap": "world.beacons",
    "scenario-events-over-cap": "at most 10,000 events",
    "scenario-integer-5000-digits": "s.toml: not valid TOML",
    "scenario-seed-5000-digits": "s.toml: not valid TOML",
    "recording-kidnap-pose-dict": "r.jsonl:12: kidnap pose",
    "recording-kidnap-pose-int": "r.jsonl:12: kidnap pose 3",
    "recording-kidnap-pose-strings": "r.jsonl:12: kidnap pose",
    "recording-kidnap-pose-nan": "r.jsonl:12: kidnap pose [nan",
    "recording-kidnap-pose-inf": "r.jsonl:12: kidnap pose",
    "recording-kidnap-theta-huge": "r.jsonl:12: kidnap pose",
    "recording-toggle-list": "r.jsonl:12: toggle of ['ekf']",
    "recording-toggle-dict": "r.jsonl:12: toggle of",
    "recording-integer-5000-digits": "r.jsonl:7: not a usable number",
    "recording-nested-line": "r.jsonl:6: nested too deep",
    "recording-nested-last-line": "nested too deep",
    "recording-control-nan": "r.jsonl:7: control u = [nan, 0]",
    "recording-control-inf": "r.jsonl:7: control u = [inf, 0]",
    "recording-control-huge": "r.jsonl:7: control u = [1e+308, 0]",
    "recording-control-omega-nan": "r.jsonl:7: control u",
    "recording-control-over-speed": "r.jsonl:7: control u",
    "recording-commands-many": "user commands on one tick",
    "recording-line-too-long": "r.jsonl:4: a line longer than",
    "recording-header-nested-params": "r.jsonl:1: nested too deep",
    "recording-filters-many": "r.jsonl:1: corrupted header",
    "recording-checkpoint-k-negative": "checkpoint of tick -10",
    "recording-team-kidnap-pose-dict": "kidnap pose",
    "recording-team-kidnap-pose-nan": "kidnap pose [nan",
    "recording-team-kidnap-robot-float": "kidnap of robot 1.0",
    "recording-team-toggle-list": "toggle of ['ci']",
    "recording-team-control-nan": "control u = [nan",
    "recording-team-control-huge": "control u = [1e+308",
    "recording-team-driven-huge": "not a usable number",
    "mrclam-landmark-x-huge": "Landmark_Groundtruth.dat:1: bad data: x = 1e+308",
    "mrclam-landmark-y-negative-huge": "bad data: y = -1e+308",
    "mrclam-range-huge": "Robot1_Measurement.dat:4: bad data: range = 1e+308",
    "mrclam-range-negative": "bad data: range = -2",
    "mrclam-odometry-v-huge": "bad data: v = 1e+308",
    "mrclam-truth-x-huge": "Robot1_Groundtruth.dat:6: bad data: x",
    "duration-1e308-run": "--duration 1e+308: over 1,000,000 ticks",
    "duration-1e308-eval": "--duration 1e+308: over 1,000,000 ticks",
}


def case_kind(case: Case) -> str:
    """The kind of an issue-24 case (its name without ``i24-`` and the front end)."""
    name = case.name.removeprefix("i24-")
    if name.startswith("duration-"):
        return name
    return name.rsplit("-", 1)[0]
