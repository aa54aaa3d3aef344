"""One BLAS thread by default (beacon_sim/core/threads.py): the setting, its override, and
that the command line and the Monte Carlo workers apply it."""

import subprocess
import sys

import pytest

from beacon_sim.core import threads


def test_the_wanted_count_comes_from_the_environment():
    assert threads.wanted_blas_threads({}) == threads.DEFAULT == 1
    assert threads.wanted_blas_threads({threads.ENV: "3"}) == 3
    assert threads.wanted_blas_threads({threads.ENV: " Auto "}) is None
    for bad in ("0", "-2", "two", "1.5"):
        with pytest.raises(ValueError, match=threads.ENV):
            threads.wanted_blas_threads({threads.ENV: bad})


def _in_child(code: str, env_value: str | None = None) -> str:
    import os
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env.pop(threads.ENV, None)
    if env_value is not None:
        env[threads.ENV] = env_value
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


def test_the_limit_reaches_a_loaded_blas_and_the_eval_workers():
    code = """
import numpy as np
from concurrent.futures import ProcessPoolExecutor
from beacon_sim.core.threads import blas_threads, limit_blas_threads
from beacon_sim.evaluation import montecarlo
applied = limit_blas_threads()
here = [n for _, n in blas_threads()]
with ProcessPoolExecutor(max_workers=1, initializer=limit_blas_threads) as pool:
    there = pool.submit(blas_threads).result()
print(applied, here, [n for _, n in there])
"""
    assert _in_child(code) == "1 [1] [1]"
    assert _in_child("from beacon_sim.core.threads import limit_blas_threads as f; print(f())",
                     "auto") == "None"


def test_a_bad_setting_is_a_usage_error():
    code = ("import sys; from beacon_sim.cli.main import main; "
            "sys.exit(main(['run', 'default', '--duration', '0.1']))")
    import os
    env = {**os.environ, threads.ENV: "many"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 2
    assert threads.ENV in r.stderr
