"""The simulation's maths is the same bits on every machine.

- The portable kernels (core/portable_math.py) are accurate: within 3 ulp of the C library
  (Python's ``math``) on seeded random inputs, with the C library's signs of zero and pi.
- Their float and array forms give the same bits (small arrays go through the floats, large
  ones through numpy: both are checked).
- The truth and readings of every shipped scenario, and the kernels' outputs, are the same
  bits under every numpy dispatch this machine can run (a subprocess per setting of
  ``NPY_DISABLE_CPU_FEATURES``), and equal the table in docs/portability.md: on a machine
  with AVX-512 this runs numpy's SVML kernels and its baseline ones, which differ
  (``maths_fingerprint``), while the simulation does not.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from portable_checksums import kernel_digests, scenario_checksums, table

from beacon_sim.core import portable_math as pm
from beacon_sim.core.maths_fingerprint import maths_fingerprint
from beacon_sim.core.motion import move, move_portable

ROOT = Path(__file__).resolve().parents[2]
RNG = np.random.default_rng(20261207)


def ulps(got, want) -> float:
    """Largest error in units of the last place of ``want``."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    same = (got == want) | (np.isnan(got) & np.isnan(want))
    err = np.abs(got - want) / np.spacing(np.maximum(np.abs(want), np.finfo(float).tiny))
    return float(np.max(np.where(same, 0.0, err)))


def mathf(f, *args):
    return np.array([f(*a) for a in zip(*(np.asarray(x).tolist() for x in args), strict=True)])


ANGLES = np.concatenate([RNG.uniform(-10.0, 10.0, 50_000), RNG.uniform(-1e-6, 1e-6, 500),
                         RNG.uniform(-1000.0, 1000.0, 2000),
                         [0.0, -0.0, math.pi, -math.pi, math.pi / 2, math.pi / 4, 1e-300]])


@pytest.mark.parametrize(("kernel", "reference"), [(pm.sin, math.sin), (pm.cos, math.cos)])
def test_sin_and_cos_are_within_3_ulp(kernel, reference):
    assert ulps(kernel(ANGLES), mathf(reference, ANGLES)) <= 3.0


def test_atan2_is_within_3_ulp_with_the_c_librarys_signs():
    y = np.concatenate([RNG.uniform(-10, 10, 50_000), RNG.uniform(-1e-3, 1e-3, 500),
                        [0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 5.0, -5.0, 1e-300]])
    x = np.concatenate([RNG.uniform(-10, 10, 50_000), RNG.uniform(-1e3, 1e3, 500),
                        [0.0, 0.0, -0.0, -0.0, 0.0, -0.0, 5.0, -5.0, -1.0]])
    got, want = pm.atan2(y, x), mathf(math.atan2, y, x)
    assert ulps(got, want) <= 3.0
    assert np.array_equal(np.signbit(got), np.signbit(want))
    assert got[-9:-5].tolist() == [0.0, -0.0, math.pi, -math.pi]


def test_exp_log_log1p_expm1_are_within_3_ulp():
    e = np.concatenate([RNG.uniform(-700, 700, 20_000), RNG.uniform(-2, 2, 20_000), [0.0, -0.0]])
    assert ulps(pm.exp(e), mathf(math.exp, e)) <= 3.0
    pos = np.concatenate([np.exp(RNG.uniform(-700, 700, 20_000)), RNG.uniform(0.5, 2.0, 20_000)])
    assert ulps(pm.log(pos), mathf(math.log, pos)) <= 3.0
    small = np.concatenate([RNG.uniform(-0.99, 5.0, 20_000), RNG.uniform(-1e-9, 1e-9, 2000)])
    assert ulps(pm.log1p(small), mathf(math.log1p, small)) <= 3.0
    assert ulps(pm.expm1(small), mathf(math.expm1, small)) <= 3.0


def test_special_values():
    assert pm.exp(np.array([1000.0, -1000.0])).tolist() == [math.inf, 0.0]
    assert np.isnan(pm.exp(np.array([math.nan]))[0])
    got = pm.log(np.array([0.0, -1.0, math.inf]))
    assert got[0] == -math.inf and np.isnan(got[1]) and got[2] == math.inf
    assert all(math.isnan(v) for v in pm.sincos1(math.nan) + pm.sincos1(math.inf))
    assert pm.hypot1(3.0, 4.0) == 5.0 and pm.hypot(np.array([-3.0]), np.array([4.0]))[0] == 5.0


@pytest.mark.parametrize("n", [5, 24, 25, 3000])
def test_float_and_array_forms_give_the_same_bits(n):
    x = RNG.uniform(-20.0, 20.0, n)
    y = RNG.uniform(-20.0, 20.0, n)
    s, c = pm.sincos(x)
    assert [pm.sincos1(v) for v in x.tolist()] == list(zip(s.tolist(), c.tolist(), strict=True))
    assert [pm.atan2_1(b, a) for a, b in zip(x.tolist(), y.tolist(), strict=True)] == \
        pm.atan2(y, x).tolist()
    assert [pm.hypot1(a, b) for a, b in zip(x.tolist(), y.tolist(), strict=True)] == \
        pm.hypot(x, y).tolist()


def test_the_truths_motion_is_the_filters_model_to_a_few_ulp():
    poses = np.column_stack([RNG.uniform(-5, 5, 2000), RNG.uniform(-5, 5, 2000), RNG.uniform(-4, 4, 2000)])
    v, w = RNG.uniform(-1, 1, 2000), RNG.uniform(-2, 2, 2000)
    a, b = move_portable(poses, v, w, 0.1), move(poses, v, w, 0.1)
    assert np.allclose(a, b, rtol=0.0, atol=1e-14)
    one = [move_portable(p, float(vi), float(wi), 0.1) for p, vi, wi in zip(poses[:50], v[:50], w[:50],
                                                                               strict=True)]
    assert np.array_equal(np.array(one), a[:50])   # one pose or many: the same bits


# -- the same bits under every numpy dispatch ------------------------------------------------
def dispatch_settings() -> list[str]:
    """Values of NPY_DISABLE_CPU_FEATURES that give this machine's numpy other kernels: none,
    without its AVX-512 family (x86-64), and without any dispatched extension."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    found = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    settings = [""]
    avx512 = [f for f in found if "512" in f or f == "X86_V4"]
    if avx512:
        settings.append(" ".join(avx512))
    if found and len(found) > len(avx512):
        settings.append(" ".join(found))
    return settings


def run_checksums(disable: str) -> dict:
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": disable, "PYTHONPATH": str(ROOT)}
    code = ("import json; from tests.portable_checksums import scenario_checksums, kernel_digests; "
            "from beacon_sim.core.maths_fingerprint import maths_fingerprint; "
            "print(json.dumps({'scenarios': scenario_checksums(), 'kernels': kernel_digests(), "
            "'fingerprint': maths_fingerprint()}))")
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True,
                          text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def here() -> dict:
    return {"scenarios": {k: list(v) for k, v in scenario_checksums().items()},
            "kernels": kernel_digests(), "fingerprint": maths_fingerprint()}


def test_every_dispatch_gives_the_same_truth_readings_and_kernels(here):
    settings = dispatch_settings()
    runs = {s: run_checksums(s) for s in settings[1:]}
    for setting, got in runs.items():
        assert got["scenarios"] == here["scenarios"], f"NPY_DISABLE_CPU_FEATURES={setting!r}"
        assert got["kernels"] == here["kernels"], f"NPY_DISABLE_CPU_FEATURES={setting!r}"
    fingerprints = {here["fingerprint"]} | {r["fingerprint"] for r in runs.values()}
    if len(settings) > 1 and any("512" in s for s in settings):
        # The check has teeth here: numpy's own kernels differ between these settings.
        assert len(fingerprints) > 1, "numpy's kernels did not change with the dispatch setting"


def test_the_checksums_are_the_documented_ones(here):
    doc = (ROOT / "docs" / "portability.md").read_text()
    start = doc.index("| scenario | truth checksum |")
    documented = doc[start:doc.index("\n\n", start)].strip()
    want = table({k: tuple(v) for k, v in here["scenarios"].items()})
    assert documented == want, "regenerate with: python tests/portable_checksums.py --table"
    kernels = dict(re.findall(r"`(\w+)`: `([0-9a-f]{12})`", doc))
    assert kernels == here["kernels"]
