"""Which floating-point maths this process runs: a fingerprint of numpy's kernels and BLAS.

The simulation's truth and readings use only the portable kernels of
:mod:`beacon_sim.core.portable_math`, so they are the same bits on every machine. The filters
use numpy's fast kernels (``sin``, ``exp``, ``arctan2``...) and BLAS, whose last bit depends on
the processor (numpy dispatches float64 transcendental functions to AVX-512 code on some x86-64
processors, numpy#23523; OpenBLAS picks its dot and matrix kernels by processor) and
on the numpy build. Two processes whose fingerprints are
equal computed every kernel below identically on the probe inputs; a recording stores the
fingerprint of the machine that made it, so a replay knows whether the estimates can match bit
for bit (same fingerprint) or only within a tolerance (docs/portability.md).
"""

from __future__ import annotations

import hashlib
import platform
from functools import cache

import numpy as np

#: The kernels probed, with the argument transform that keeps each in its domain.
_PROBES = (
    ("sin", lambda x, y: np.sin(x)),
    ("cos", lambda x, y: np.cos(x)),
    ("tan", lambda x, y: np.tan(x)),
    ("arctan2", lambda x, y: np.arctan2(y, x)),
    ("hypot", lambda x, y: np.hypot(x, y)),
    ("exp", lambda x, y: np.exp(x)),
    ("expm1", lambda x, y: np.expm1(x)),
    ("log", lambda x, y: np.log(np.abs(x) + 1e-3)),
    ("log1p", lambda x, y: np.log1p(np.abs(x))),
    ("power", lambda x, y: np.power(np.abs(x) + 0.5, 1.7)),
    ("arcsin", lambda x, y: np.arcsin(np.clip(x / 8.0, -1.0, 1.0))),
    ("sqrt", lambda x, y: np.sqrt(np.abs(x))),
    ("matmul", lambda x, y: (x.reshape(-1, 8) @ y.reshape(8, -1)).ravel()),
    ("sum", lambda x, y: np.cumsum(x.reshape(-1, 16).sum(axis=1))),
    # BLAS (OpenBLAS picks its kernels by processor): long dot products and tall products,
    # in float64 and float32, as the particle filter's weighted means and covariances.
    ("dot", lambda x, y: np.array([np.dot(x, y), np.dot(x[::2], y[1::2])])),
    ("dot32", lambda x, y: np.array([np.dot(x.astype(np.float32), y.astype(np.float32))], dtype=float)),
    ("gemm_tall", lambda x, y: (x[:3000].reshape(3, -1) @ y[:3000].reshape(-1, 3)).ravel()),
    ("gemm_tall32", lambda x, y: (x[:3000].reshape(3, -1).astype(np.float32)
                                  @ y[:3000].reshape(-1, 3).astype(np.float32)).ravel().astype(float)),
    # float32 kernels (the particle filter's default precision)
    ("exp32", lambda x, y: np.exp(x.astype(np.float32)).astype(float)),
    ("sincos32", lambda x, y: np.concatenate([np.sin(x.astype(np.float32)),
                                              np.cos(x.astype(np.float32))]).astype(float)),
    ("arctan2_32", lambda x, y: np.arctan2(y.astype(np.float32), x.astype(np.float32)).astype(float)),
)


def _probe_inputs(n: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """Fixed inputs in [-8, 8), built with integer arithmetic and one exact division (no
    random generator, no transcendental function: the same bits everywhere)."""
    k = np.arange(n, dtype=np.int64)
    x = ((k * 2654435761) % 65536).astype(float) / 4096.0 - 8.0
    y = ((k * 40503 + 977) % 65536).astype(float) / 4096.0 - 8.0
    return x, y


@cache
def kernel_digests() -> dict[str, str]:
    """Each probed kernel's output on the probe inputs, as 12 hex digits of SHA-256."""
    x, y = _probe_inputs()
    out = {}
    with np.errstate(all="ignore"):
        for name, f in _PROBES:
            r = np.ascontiguousarray(f(x, y), dtype="<f8")
            out[name] = hashlib.sha256(r.tobytes()).hexdigest()[:12]
    return out


@cache
def maths_fingerprint() -> str:
    """16 hex digits naming this process's float64 kernels (equal fingerprints: the probed
    kernels agree bit for bit)."""
    h = hashlib.sha256()
    for name, digest in sorted(kernel_digests().items()):
        h.update(f"{name}={digest};".encode())
    return h.hexdigest()[:16]


def maths_description() -> str:
    """A line for people: numpy's version, the processor architecture and the SIMD extensions
    numpy dispatches to (e.g. ``numpy 2.4.6, x86_64, AVX512_SKX``)."""
    return f"numpy {np.__version__}, {platform.machine() or 'unknown machine'}, {_best_simd()}"


def _best_simd() -> str:
    """The highest SIMD extension numpy found and may dispatch to (``baseline`` when none)."""
    import importlib

    for module in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):  # numpy 2, 1
        try:
            umath = importlib.import_module(module)
        except ImportError:
            continue
        features = getattr(umath, "__cpu_features__", {})
        found = [f for f in getattr(umath, "__cpu_dispatch__", ()) if features.get(f)]
        return found[-1] if found else "baseline"
    return "SIMD unknown"
