"""Dask for ``eval --scheduler`` and ``grade --scheduler``: the client, the number of
workers, tasks sent and gathered in order (:func:`on_dask`), a lost worker told apart
(:class:`ClusterError`), the workers' lean settings (:data:`DASK_LEAN_CONFIG`) and memory
limit (:func:`init_worker`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from beacon_sim.core.threads import limit_blas_threads

#: Dask settings for the workers (and the client) of ``eval --scheduler`` and grading
#: (docs/performance.md): with no task to run, a Dask cluster still spends CPU on
#: its event loops' ticks, its memory and system monitors and the workers' sampling
#: profiler, in proportion to the wall time: 115 ms of CPU a second for a LocalCluster of
#: 2 workers with Dask's defaults, 16 ms with these, so eval on Dask costs within a few per
#: cent of local processes. None of them changes a result. Apply with
#: ``dask.config.set(DASK_LEAN_CONFIG)`` before a LocalCluster is made, or as a worker's
#: YAML / ``DASK_...`` environment (docs/performance.md).
DASK_LEAN_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


class ClusterError(RuntimeError):
    """The Dask cluster lost a task (its worker died, the scheduler went away), or it has had
    no worker for :data:`NO_WORKER_TIMEOUT_S`."""


#: How long [s] a Dask cluster may have no worker, before the first task or after the last
#: worker left mid-run, before :func:`on_dask` gives up with one line (a ClusterError;
#: ``eval``/``grade --scheduler``: exit status 2) instead of waiting for ever.
NO_WORKER_TIMEOUT_S = 30.0
#: How often [s] :func:`on_dask` looks for finished tasks, and for workers, while it waits.
_POLL_S = 0.05


#: The exceptions of ``dask.distributed`` that mean a task was lost, not that it raised.
_LOST = ("KilledWorker", "CommClosedError", "CancelledError", "FutureCancelledError")


def dask_client(scheduler: Any) -> tuple[Any, bool]:
    """A ``dask.distributed`` Client for ``scheduler`` (a Client: itself; a cluster or an
    address: a new one) and whether it is ours to close."""
    from dask.distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    return Client(scheduler, timeout="20s", set_as_default=False), True


def dask_workers(scheduler: Any) -> int:
    """How many workers the Dask cluster has now."""
    client, own = dask_client(scheduler)
    try:
        return len(client.scheduler_info().get("workers", {}))
    finally:
        if own:
            client.close()


def on_dask(scheduler: Any, fn: Callable[..., Any], tasks: list[Any],
            done: Callable[[int, Any], None],
            lost: Callable[[int, Exception], None] | None = None, shared: Any = None) -> None:
    """``fn(task)`` for every task on Dask, ``done(index, result)`` as each finishes; each
    result is released once gathered (the scheduler forgets it: never computed again).
    ``shared``: data every task needs (grading's simulated runs), sent to every worker once
    (scattered) instead of once per task, and given as ``fn(task, shared)``.

    A task that raised or whose worker died: ``lost(index, exc)`` when given (grading:
    that task's student fails, the others go on), else a one-line :class:`ClusterError`
    for a lost worker and the exception itself otherwise.

    A cluster with no worker at the start, or none left while tasks are pending, for
    :data:`NO_WORKER_TIMEOUT_S`: a one-line :class:`ClusterError` (even with ``lost``: no
    task can finish)."""
    from dask.distributed import as_completed

    client, own = dask_client(scheduler)
    data = None
    try:
        _wait_for_a_worker(client)
        if shared is not None:
            (data,) = client.scatter([shared], broadcast=True, hash=False)
            futures = client.map(fn, list(tasks), shared=data, pure=False)
        else:
            futures = client.map(fn, list(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in _as_completed_while_workers(client, as_completed(futures, loop=client.loop)):
            i = index[fut.key]
            try:
                result = fut.result()
            except Exception as exc:  # the worker died or the cluster went away: one line
                fut.release()
                if lost is not None:
                    lost(i, exc)
                    continue
                if type(exc).__name__ in _LOST:
                    raise ClusterError(f"Dask: task {i + 1} of {len(futures)} was lost "
                                       f"({type(exc).__name__}: {str(exc)[:200]})") from None
                raise
            fut.release()
            done(i, result)
    finally:
        if data is not None:
            data.release()
        if own:
            client.close()


def _workers_now(client: Any) -> int:
    """The cluster's workers as the scheduler counts them now."""
    return len(client.scheduler_info().get("workers", {}))


def _no_worker(client: Any) -> ClusterError:
    where = getattr(client.scheduler, "address", None) or "the scheduler"
    return ClusterError(f"Dask: no worker at {where} for {NO_WORKER_TIMEOUT_S:g} s "
                        "(start workers: dask worker ADDRESS)")


def _wait_for_a_worker(client: Any) -> None:
    """Return once the cluster has a worker; a :class:`ClusterError` after
    :data:`NO_WORKER_TIMEOUT_S` without one."""
    try:
        client.wait_for_workers(1, timeout=NO_WORKER_TIMEOUT_S)
    except TimeoutError:
        raise _no_worker(client) from None


def _as_completed_while_workers(client: Any, finished: Any) -> Any:
    """The futures of ``finished`` (a Dask ``as_completed``) as they finish, while the cluster
    keeps a worker: a :class:`ClusterError` once it has had none for :data:`NO_WORKER_TIMEOUT_S`
    with tasks pending (Dask itself would wait for ever)."""
    idle_since: float | None = None
    looked = 0.0
    while not finished.is_empty():
        batch = finished.next_batch(block=False)
        if batch:
            idle_since = None
            yield from batch
            continue
        now = time.monotonic()
        if now - looked >= 0.5:
            looked = now
            if _workers_now(client) > 0:
                idle_since = None
            elif idle_since is None:
                idle_since = now
            elif now - idle_since >= NO_WORKER_TIMEOUT_S:
                raise _no_worker(client)
        time.sleep(_POLL_S)


def limit_worker_memory(gb: float) -> None:
    """A local worker's address-space limit, so a filter that hoards memory gets a
    MemoryError (a failed run) instead of the kernel's out-of-memory killer."""
    if gb <= 0:
        return
    try:
        import resource

        limit = int(gb * 2**30)
        _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard != resource.RLIM_INFINITY:
            limit = min(limit, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


#: A local evaluation worker's address-space limit [GB]: a filter that hoards memory fails
#: its run with a MemoryError instead of the kernel killing the worker (and the sweep).
WORKER_MEMORY_GB = 4.0


def init_worker(memory_gb: float = WORKER_MEMORY_GB) -> None:
    """Set up a local worker process: one BLAS thread, and the memory limit."""
    limit_blas_threads()
    limit_worker_memory(memory_gb)
