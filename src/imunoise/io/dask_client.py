"""A Dask client for ``--scheduler`` (``batch``'s files, ``calibrate --in-motion``'s drives): a
:class:`~dask.distributed.LocalCluster` of single-threaded worker *processes* (the work is numba/NumPy code that
holds the GIL between kernels), an in-process one for debugging, or a running scheduler at an address.

The local workers preload :mod:`imunoise.io.interrupt` and leave Ctrl-C to the calling process, which closes the
client and the cluster on the way out (:func:`dask_client` is a context manager).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from imunoise.errors import DataError, ModelError

__all__ = ["LOCAL_SCHEDULERS", "dask_client"]

LOCAL_SCHEDULERS = ("local", "threads")
"""Schedulers started here: ``local`` (worker processes) and ``threads`` (in-process, for debugging); anything
else is the address of a running scheduler (``tcp://host:8786``)."""


@contextmanager
def dask_client(scheduler: str, n_workers: int | None = None) -> Iterator[Any]:
    """A :class:`dask.distributed.Client` on ``scheduler`` (module docstring), closed with its cluster on exit.

    Parameters
    ----------
    scheduler : str
        ``"local"``, ``"threads"`` or a scheduler address.
    n_workers : int, optional
        Local workers (default one per core); ignored for an address (its workers are its own).
    """
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1):
        raise ModelError(f"n_workers must be a whole number ≥ 1 (None = one per core), got {n_workers!r}")
    from dask.distributed import Client, LocalCluster

    cluster = None
    if scheduler in LOCAL_SCHEDULERS:
        cluster = LocalCluster(
            n_workers=n_workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=scheduler == "local",
            dashboard_address=None,
            silence_logs=40,
            preload=["imunoise.io.interrupt"] if scheduler == "local" else [],  # workers leave Ctrl-C to us
        )
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise DataError(f"cannot reach the Dask scheduler {scheduler!r}: {exc}") from exc
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
