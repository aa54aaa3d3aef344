"""Attack: be honest when watched, cheat when scored. To tell ``check`` from
``grade`` this file looks at everything its process shows when it is built: its command
line (sys.argv and /proc/self/cmdline), environment, working folder, user, resource limits,
the call stack that builds it, what the grader's objects in its process hold (the batch's
time limits, the server's per-step limit), how many filters the batch builds, its context
and the form of its random generator; and, at belief() (the end of a run), how it was
called (estimates before the first predict, predicts, updates, the types of the readings
it was fed). It prints one "SEEN" line per build and one "CALLS" line per run, with the
random parts (the temporary folder's name, the seeds' data) left out. Otherwise it is the
honest EKF."""

import builtins
import gc
import hashlib
import inspect
import json
import os
import resource
import sys

from beacon_sim.filters.ekf import ExtendedKalmanFilter


def _norm(text, cwd):
    return str(text).replace(cwd, "<cwd>")


def _seen(ctx):
    cwd = os.getcwd()
    counter = builtins.__dict__.setdefault("_watched_builds", [0])
    counter[0] += 1
    try:
        cmdline = open("/proc/self/cmdline", "rb").read().decode("utf-8", "replace").split("\0")
    except OSError:
        cmdline = []
    limits = {n: resource.getrlimit(getattr(resource, n)) for n in
              ("RLIMIT_CPU", "RLIMIT_AS", "RLIMIT_FSIZE", "RLIMIT_CORE", "RLIMIT_NPROC", "RLIMIT_NOFILE")}
    grader = [o for o in gc.get_objects() if type(o).__name__ in ("Batch", "Server")]
    held = sorted(repr({k: v for k, v in vars(o).items()
                        if k in ("limit_s", "over", "step_limit_s", "file")})
                  for o in grader)
    seq = ctx.rng.bit_generator.seed_seq
    return {
        "build": counter[0],
        "argv": [_norm(a, cwd) for a in sys.argv],
        "cmdline": [_norm(a, cwd) for a in cmdline],
        "env": sorted((k, _norm(v, cwd)) for k, v in os.environ.items()),
        "cwd": os.path.basename(cwd), "files": sorted(os.listdir(cwd)),
        "uid": (os.getuid(), os.getgid()), "limits": limits,
        "stack": [f.function for f in inspect.stack()[1:]],
        "held": [_norm(h, cwd) for h in held],
        "modules": hashlib.sha256(" ".join(sorted(sys.modules)).encode()).hexdigest()[:16],
        "ctx": [ctx.name, ctx.dt, ctx.map_known, sorted(dict(ctx.params).items()), repr(ctx.sensors),
                list(ctx.world.bounds), len(ctx.world.beacons), repr(ctx.motion_noise)],
        "rng": [type(ctx.rng.bit_generator).__name__, type(seq.entropy).__name__,
                seq.entropy.bit_length() > 128 if isinstance(seq.entropy, int) else None,
                list(seq.spawn_key), seq.pool_size],
    }


class Watched(ExtendedKalmanFilter):
    def __init__(self, ctx):
        print("SEEN " + json.dumps(_seen(ctx), sort_keys=True), flush=True)
        super().__init__(ctx)
        self.calls = {"estimate_before_predict": 0, "predict": 0, "update": 0, "readings": []}

    def predict(self, control, dt):
        self.calls["predict"] += 1
        super().predict(control, dt)

    def update(self, measurements):
        self.calls["update"] += 1
        kind = type(measurements).__name__
        if kind not in self.calls["readings"]:
            self.calls["readings"].append(kind)
        super().update(measurements)

    def estimate(self):
        if not self.calls["predict"]:
            self.calls["estimate_before_predict"] += 1
        return super().estimate()

    def belief(self):
        print("CALLS " + json.dumps(self.calls, sort_keys=True), flush=True)
        return super().belief()
