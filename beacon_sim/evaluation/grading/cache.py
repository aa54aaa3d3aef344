"""A student whose file and settings are unchanged since the last grade is not run again:
results kept by :func:`cache_key` (only where no child could have written the cache).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from beacon_sim.evaluation.grading.students import PROBE_TICKS, StudentJob, StudentResult, run_students


def students_cannot_write_here(sandbox: str) -> bool:
    """Whether the students' children cannot write the grader's files (the cache of pickles
    is read back): inside bubblewrap, or as ``nobody`` under a root grader."""
    import os

    return sandbox == "bwrap" or (hasattr(os, "geteuid") and os.geteuid() == 0)


def cache_key(job: StudentJob) -> str:
    """A student's results are reused when this is unchanged: the file's bytes and name, the
    class, the limits, the sandbox level, beacon-sim's version and every simulated run
    (scenario, seed, length, the truth's checksum)."""
    import hashlib

    from beacon_sim.version import __version__

    h = hashlib.sha256(job.source)
    meta = [job.filename, job.class_name, job.time_limit, job.memory_limit_gb, job.sandbox, __version__,
            job.total_time_s, job.disk_limit_mb,
            PROBE_TICKS, [(sr.label, sr.seed, len(sr.frames), sr.truth_checksum, repr(sr.scenario),
                           hashlib.sha256(sr.stream_key).hexdigest())  # the secret's mark, not it
                          for sr in job.sims],
            [(ts.label, ts.seed, len(ts.robots[0].frames), ts.truth_checksum,
              [repr(r.scenario) for r in ts.robots], hashlib.sha256(ts.robots[0].stream_key).hexdigest())
             for ts in job.team_sims]]
    h.update(json.dumps(meta, default=str).encode())
    return h.hexdigest()


def run_cached(student_jobs: list[StudentJob], jobs: int | None, scheduler: Any,
                progress: Callable[[int, int], None] | None, cache: Path | None
                ) -> tuple[list[StudentResult], list[str]]:
    """:func:`run_students` for the students whose results are not in ``cache`` (a folder of
    pickles the grader wrote itself: numbers and texts, nothing of a student's code); the
    others' results from it. Returns the results in order and the students taken from it."""
    import pickle

    if cache is None:
        return (run_students(student_jobs, jobs, scheduler, progress) if student_jobs else []), []
    cache.mkdir(parents=True, exist_ok=True)
    found: dict[int, StudentResult] = {}
    for i, job in enumerate(student_jobs):
        f = cache / f"{cache_key(job)}.pickle"
        if f.is_file():
            try:
                found[i] = pickle.loads(f.read_bytes())
            except Exception:  # a damaged entry: run the student again
                pass
    todo = [j for i, j in enumerate(student_jobs) if i not in found]
    fresh = iter(run_students(todo, jobs, scheduler, progress) if todo else [])
    out = []
    for i, job in enumerate(student_jobs):
        if i in found:
            out.append(found[i])
            continue
        res = next(fresh)
        out.append(res)
        if any(r.problem and r.problem.startswith("worker lost") for r in res.results):
            continue  # the machine's failure, not the student's: run it again next time
        tmp = cache / f".{cache_key(job)}.tmp"
        tmp.write_bytes(pickle.dumps(res, protocol=pickle.HIGHEST_PROTOCOL))
        tmp.replace(cache / f"{cache_key(job)}.pickle")
    return out, [student_jobs[i].student for i in sorted(found)]
