"""How many threads numpy's BLAS may use: one, by default, set in this one place.

The filters work on small matrices (3x3, m x 3) and on 1-D arrays of up to a million
particles. A BLAS thread pool buys nothing there and costs a lot on a small shared machine:
OpenBLAS's idle workers spin, so a second thread slows the main one down (on 2 cores
``np.dot`` over 50k-1M elements took 0.4-12 ms with 2 threads, 7-145 us with one; the
particle filter at 100k particles went from 16 to 6 ms a step). The window, headless runs
and the Monte Carlo workers therefore call :func:`limit_blas_threads` once at start.

Change it with the environment variable ``BEACON_SIM_BLAS_THREADS``: a number of threads,
or ``auto`` to leave the BLAS library's own default. The limit is applied with
threadpoolctl (a dependency of the basic install) to the BLAS already loaded; without
threadpoolctl only the standard variables (``OPENBLAS_NUM_THREADS`` ...) are set, which
reach processes started afterwards but not a BLAS that is already loaded.
"""

from __future__ import annotations

import os

#: The environment variable that overrides the default: a number, or "auto".
ENV = "BEACON_SIM_BLAS_THREADS"
#: One thread unless told otherwise.
DEFAULT = 1
#: The variables BLAS libraries read when they load (for child processes).
_LIBRARY_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                 "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")

_applied: object = None   # the threadpoolctl limiter in force (kept so it is not undone)


def wanted_blas_threads(environ: dict[str, str] | None = None) -> int | None:
    """The thread count asked for: ``BEACON_SIM_BLAS_THREADS`` or :data:`DEFAULT`;
    None for ``auto`` (the library decides). A value that is not a positive whole number
    is an error, said plainly."""
    env = os.environ if environ is None else environ
    raw = env.get(ENV, "").strip().lower()
    if not raw:
        return DEFAULT
    if raw == "auto":
        return None
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{ENV}={raw!r}: expected a whole number of threads >= 1, or 'auto'")
    return n


def limit_blas_threads(n: int | str | None = "env") -> int | None:
    """Limit the BLAS thread pools of this process (and of processes it starts) to ``n``
    threads; by default to :func:`wanted_blas_threads`. Returns the limit applied, or
    None when the library's default is kept. Cheap and safe to call again."""
    global _applied
    if n == "env":
        n = wanted_blas_threads()
    if n is None:
        return None
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"BLAS threads: expected a whole number >= 1, got {n!r}")
    for var in _LIBRARY_VARS:   # processes started later (spawn, forkserver, subprocess)
        os.environ[var] = str(n)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:   # pragma: no cover - threadpoolctl is a basic dependency
        return n
    _applied = threadpool_limits(limits=n, user_api="blas")
    return n


def blas_threads() -> list[tuple[str, int]]:
    """(library, threads) of every BLAS loaded in this process, for reports and tests;
    empty without threadpoolctl."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:   # pragma: no cover
        return []
    return [(i.get("internal_api", "?"), int(i["num_threads"])) for i in threadpool_info()
            if i.get("user_api") == "blas"]


__all__ = ["DEFAULT", "ENV", "blas_threads", "limit_blas_threads", "wanted_blas_threads"]
