"""The particle filter's results bit for bit as before the 0.3.0 speed work (a5d21dd): the
SHA-256 of every estimate, particle, weight and HUD figure over scripted ticks
(``pf_trace.py``), for the main options; a change of results, or of the order of the random
draws, fails here.

A filter's arithmetic is not portable (docs/portability.md): numpy's kernels and OpenBLAS's
dot and matrix products round differently by processor. So the digests are pinned for one
maths that every x86-64 machine with AVX2 can run: numpy's dispatch capped below AVX-512
(``NPY_DISABLE_CPU_FEATURES``) and OpenBLAS's Haswell kernels (``OPENBLAS_CORETYPE``); the
traces run in a subprocess under it. a5d21dd's particle filter gives exactly these digests
under it (checked when they were pinned). Elsewhere (ARM64, another BLAS, another
numpy) the test says why it cannot run.

To re-record after a deliberate change of results: ``python tests/filters/test_particle_bits.py``.
"""

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pf_trace import RUNS

RECORDED_NUMPY = "2.4"
ROOT = Path(__file__).resolve().parents[2]

#: (case, motion noise, start) -> SHA-256 under the pinned maths (a5d21dd's).
BEFORE = {
    ("default", "plain", "gaussian"): "33ccefe8c13497a2e110634ec82c44c451d890b933c9b9840bc5ec51df03ba3f",
    ("float64", "plain", "gaussian"): "81955bd9bd625a204673214ae22596b9b12f5a77041f0e9d716e028fac27fbc2",
    ("kld", "plain", "gaussian"): "31a3a32facd724a9136deb0e31cbf3ee7e9511ae005e1c5859769ee26241b82b",
    ("seed002", "plain", "gaussian"): "99feec2c36fbc107946fea36b30534a3bdb2a406df7915dce0e827b36e46e319",
    ("temper", "plain", "gaussian"): "4fcb157ccf0c6fd6c900e4b1f88cbaba2df8a549f4e0492b8956bbedce08c8d3",
    ("cluster_heading", "plain", "gaussian"):
        "294a12d119bd7da19e9b4f7a210caeac8b482dd379d26595c67607bc43174d3c",
    ("mean_fit", "plain", "gaussian"): "dc69246ec16d682b3414bf885e34dd28962fa5c643cd6302e73f21f09a91bcb6",
    ("residual", "plain", "gaussian"): "02b01e1b223b6555565c3a47d532c67db1b0668031b004b8d2955889c9b8e33a",
    ("multinomial", "plain", "gaussian"): "fdedfb90d5fe32745f5aa4824c7bdd03efec434d1cc948a6c438567e3cc3d43a",
    ("default", "pose_std", "gaussian"): "5a3db5d6579306654ed1fb4096fee5556ae3931a8e5f4f0b1808753ee682dd7c",
    ("default", "plain", "uniform"): "090737f0623c6df0297db36465edd6419ae7435d702e6fede4bf47d84e473eb9",
    ("kld", "pose_std", "uniform"): "81a6b143afd273f52ba5f183f76e120d0f84c4b9f3d95e059d6510e08ecf14d2",
}


def pinned_maths_env() -> dict[str, str]:
    """The environment that runs the pinned maths: numpy without its AVX-512 kernels, OpenBLAS
    with its Haswell kernels."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    avx512 = [f for f in __cpu_dispatch__ if __cpu_features__.get(f) and ("512" in f or f == "X86_V4")]
    return {"NPY_DISABLE_CPU_FEATURES": " ".join(avx512), "OPENBLAS_CORETYPE": "Haswell"}


def why_not_here() -> str | None:
    """Why this machine cannot run the pinned maths, or None."""
    if not np.__version__.startswith(RECORDED_NUMPY):
        return f"pinned with numpy {RECORDED_NUMPY}.x; other versions may round differently"
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return "pinned for x86-64 (numpy's and OpenBLAS's kernels differ on other processors)"
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:
        from numpy.core._multiarray_umath import __cpu_features__
    if not (__cpu_features__.get("AVX2") and __cpu_features__.get("FMA3")):
        return "pinned with AVX2 and FMA kernels; this processor has neither"
    from threadpoolctl import threadpool_info
    if not any(i.get("internal_api") == "openblas" for i in threadpool_info()):
        return "pinned with OpenBLAS's kernels; this numpy uses another BLAS"
    return None


def traces() -> dict[tuple[str, str, str], str]:
    """Every run's digest, computed in a subprocess under the pinned maths."""
    code = ("import json, sys; sys.path.insert(0, 'tests'); from pf_trace import RUNS, trace; "
            "print(json.dumps([[list(r), trace(r[0], r[1], start=r[2])] for r in RUNS]))")
    env = {**os.environ, **pinned_maths_env(), "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return {tuple(r): h for r, h in json.loads(done.stdout.strip().splitlines()[-1])}


def test_every_run_has_a_recorded_hash():
    assert set(BEFORE) == set(RUNS)


@pytest.mark.skipif(why_not_here() is not None, reason=str(why_not_here()))
def test_results_are_bit_for_bit_those_before_the_speed_work():
    got = traces()
    wrong = [r for r in RUNS if got[r] != BEFORE[r]]
    assert not wrong, f"{len(wrong)} of {len(RUNS)} runs differ, the first {wrong[0]}"


if __name__ == "__main__":
    for run, digest in traces().items():
        print(f'    {run!r}: "{digest}",'.replace("'", '"'))
