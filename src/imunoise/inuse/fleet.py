"""The drives of the in-motion likelihood on Dask (``calibrate --in-motion --scheduler``): a fleet's drives are
independent filter runs, so each evaluation of the pooled NLL (:class:`imunoise.inuse.likelihood.DriveLikelihood`)
runs them in parallel, one task per drive.

The drives and their moving flags go to the workers once (scattered to every worker); an evaluation then sends
only the in-motion filter θ gives. The per-drive NLL terms (one per fix) come back in drive order and the
likelihood sums them in that order, as its serial loop does: the pooled NLL is the serial one to the last bit,
and so is the estimate. The client comes from :func:`imunoise.io.dask_client.dask_client`, the one ``batch`` uses.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.inuse.likelihood import DriveMapper

__all__ = ["SEQUENTIAL", "DaskDriveMap", "fleet_mapper"]

SEQUENTIAL = "sequential"
"""``--scheduler sequential``: the drives one after the other in this process (no Dask)."""


def _timed(fn: Callable[[Any, np.ndarray, Any], Any], drive: Any, moving: np.ndarray,
           imf: Any) -> tuple[Any, float]:
    """``fn(drive, moving, imf)`` and the worker's CPU seconds for it."""
    t0 = time.process_time()
    x = fn(drive, moving, imf)
    return x, time.process_time() - t0


class DaskDriveMap:
    """A :data:`~imunoise.inuse.likelihood.DriveMapper` on a Dask ``client`` (module docstring); ``worker_cpu_s``
    adds up the CPU seconds the workers spent on the runs (the caller's own CPU time does not see them)."""

    def __init__(self, client: Any) -> None:
        self.client = client
        self.worker_cpu_s = 0.0
        self._sent: tuple[Sequence[Any], list, list] | None = None

    def __call__(self, fn: Callable[[Any, np.ndarray, Any], Any], drives: Sequence[Any],
                 moving: Sequence[np.ndarray], imf: Any) -> list[Any]:
        from distributed.comm.core import CommClosedError
        from distributed.scheduler import KilledWorker

        if self._sent is None or self._sent[0] is not drives:
            scatter = self.client.scatter
            self._sent = (drives, scatter(list(drives), broadcast=True, hash=False),
                          scatter(list(moving), broadcast=True, hash=False))
        _, d_fut, m_fut = self._sent
        futures = [self.client.submit(_timed, fn, d, m, imf, pure=False) for d, m in zip(d_fut, m_fut, strict=True)]
        try:
            out = self.client.gather(futures)  # in the order submitted: drive order
        except (OSError, KilledWorker, CommClosedError) as exc:  # the cluster, not a drive: one line, not a trace
            raise DataError(f"--scheduler: the Dask workers were lost during the drives' filter runs ({exc}); "
                            "run again, or without --scheduler") from exc
        self.worker_cpu_s += sum(c for _, c in out)
        return [x for x, _ in out]


@contextmanager
def fleet_mapper(scheduler: str, n_workers: int | None = None) -> Iterator[DriveMapper | None]:
    """The mapper of ``--scheduler``: None for ``"sequential"`` (the likelihood's own loop), else a
    :class:`DaskDriveMap` on ``dask_client(scheduler, n_workers)``, closed with its cluster on exit."""
    if scheduler == SEQUENTIAL:
        yield None
        return
    from imunoise.io.dask_client import dask_client

    with dask_client(scheduler, n_workers) as client:
        yield DaskDriveMap(client)
