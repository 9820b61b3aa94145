"""Where the drives of an experiment run: inline, in forked local processes (``--workers``) or on a Dask
cluster (``--scheduler``), with progress counted in units of work (one method on one drive).

A job is a picklable top-level function of one picklable argument that returns a dict; it calls
:func:`tick` after each unit it finishes. The results come back in the order of ``jobs`` whatever ran
them, so an experiment's numbers do not depend on ``workers`` or the scheduler (every random path of a
job is seeded by its arguments).

On Dask, as in :func:`imunoise.batch.run_batch`: ``"local"`` starts a
:class:`~dask.distributed.LocalCluster` of ``workers`` single-threaded processes, ``"threads"`` one in this
process (for debugging and tests), anything else is a scheduler address (``tcp://host:8786``) whose
workers have imunoise installed. Progress then advances by whole jobs (``units`` each), since a remote
worker's ticks do not reach this process.
"""

from __future__ import annotations

import multiprocessing as mp
import threading
from collections.abc import Callable, Sequence
from typing import Any

from imunoise.errors import DataError, ModelError

__all__ = ["run_jobs", "tick"]

_HOOK: Callable[[int], None] | None = None  # where tick() reports: the progress callback or the parent's queue


def tick(n: int = 1) -> None:
    """Report ``n`` finished units of work from inside a job (no-op when nobody listens)."""
    if _HOOK is not None:
        _HOOK(n)


def _init_worker(queue: Any) -> None:
    global _HOOK
    _HOOK = queue.put


def run_jobs(job: Callable[[Any], dict], jobs: Sequence[Any], *, workers: int = 1, scheduler: str | None = None,
             units: int = 1, progress: Callable[[int], None] | None = None) -> list[dict]:
    """``[job(j) for j in jobs]``, spread over ``workers`` forked processes (inline when 1 or a single job),
    or on Dask when ``scheduler`` is given (module docstring). ``progress(n)`` is called in this process
    for every ``n`` units done; ``units``: units per job (Dask progress)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ModelError(f"--workers must be a whole number ≥ 1, got {workers!r}")
    if scheduler:
        return _run_dask(job, jobs, workers, scheduler, units, progress)
    if workers == 1 or len(jobs) <= 1:
        return _run_inline(job, jobs, progress)
    return _run_pool(job, jobs, workers, progress)


def _run_inline(job, jobs, progress) -> list[dict]:
    global _HOOK
    old, _HOOK = _HOOK, progress
    try:
        return [job(j) for j in jobs]
    finally:
        _HOOK = old


def _run_pool(job, jobs, workers: int, progress) -> list[dict]:
    ctx = mp.get_context("fork")
    queue = ctx.SimpleQueue()

    def drain() -> None:  # the workers' ticks, until the sentinel
        while (n := queue.get()) is not None:
            if progress:
                progress(n)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    out: list[Any] = [None] * len(jobs)
    try:
        with ctx.Pool(min(workers, len(jobs)), initializer=_init_worker, initargs=(queue,)) as pool:
            for i, r in pool.imap_unordered(_indexed, [(job, i, j) for i, j in enumerate(jobs)]):
                out[i] = r
    finally:
        queue.put(None)
        reader.join()
    return out


def _indexed(args: tuple) -> tuple[int, dict]:
    job, i, j = args
    return i, job(j)


def _run_dask(job, jobs, workers: int, scheduler: str, units: int, progress) -> list[dict]:
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler in ("local", "threads"):
        # ":0": the scheduler's HTTP endpoint on a free port, not the default 8787 another cluster may hold
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=scheduler == "local",
                               dashboard_address=":0", silence_logs=40)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise DataError(f"--scheduler {scheduler!r}: cannot reach the Dask scheduler ({exc}); give "
                            "tcp://HOST:PORT of a running dask scheduler, or 'local'") from exc
    out: list[Any] = [None] * len(jobs)
    try:
        futures = {client.submit(job, j, pure=False): i for i, j in enumerate(jobs)}
        for fut in as_completed(list(futures)):
            out[futures[fut]] = fut.result()
            if progress:
                progress(units)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return out
