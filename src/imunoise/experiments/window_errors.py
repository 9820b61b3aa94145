"""The error of one outage window: the branch's errors against the reference from the window start, and the
window's end drift and horizontal RMS (the dense-window evidence's metrics), shared by the methods that run
through the online engine (:mod:`imunoise.experiments.dense`) and the law-aware oracle
(:mod:`imunoise.experiments.oracle_law`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from imunoise.nav.metrics import nav_errors

if TYPE_CHECKING:
    from imunoise.experiments.common import Scenario

__all__ = ["branch_errors", "window_metrics", "window_last_sample", "stored_errors", "navigator_window_metrics"]


def window_metrics(err, start: float, length: float) -> dict:
    """End drift (last reference epoch with start ≤ t < start + length) and horizontal RMS inside."""
    m = (err.t >= start) & (err.t < start + length)
    if not np.any(m):
        return {"drift": None, "rms": None, "drift_v": None}
    h = err.horizontal[m]
    return {"drift": float(h[-1]), "rms": float(np.sqrt(np.mean(h * h))), "drift_v": float(err.vertical[m][-1])}


def branch_errors(res, sc: Scenario, start: float):
    # a copy of the first epoch just before the window start: nav_errors keeps only reference epochs from
    # the first estimate on, and the epochs in [start, t_first] belong to the first sample of the branch
    t = np.concatenate([[start - 1e-6], res.t])
    llh = res.antenna_llh(sc.lever)
    return nav_errors(t, np.vstack([llh[:1], llh]), np.vstack([res.vel_ned[:1], res.vel_ned]),
                      np.vstack([res.euler[:1], res.euler]), sc.ref)


def window_last_sample(t: np.ndarray, ref_t: np.ndarray, start: float, length: float, default: int) -> int:
    """One past the last IMU sample a branch from ``start`` needs for :func:`window_metrics`: the first sample
    at or after the window's last reference epoch (:func:`imunoise.nav.metrics.nav_errors` takes the estimate
    at the first epoch ≥ each reference epoch). The filter is causal, so the samples after it cannot change the
    window's values; ``default`` (never exceeded) when the window holds no reference epoch."""
    r = int(np.searchsorted(ref_t, start + length, side="left")) - 1
    if r < 0 or ref_t[r] < start:
        return default
    return min(int(np.searchsorted(t, ref_t[r], side="left")) + 1, default)


def stored_errors(nav, sc: Scenario, start: float | None = None):
    """The errors (:func:`imunoise.nav.metrics.nav_errors`) of a navigator's stored epochs (an
    :class:`~imunoise.online.OnlineNavigator` with ``store=True``) without closing it, or None when it stored
    nothing that meets the reference. ``finish()`` would build the whole result (every epoch's attitude, the
    per-sample logs over the entire drive) of which the errors need the positions, velocities and attitudes
    at the epochs nav_errors reads: the first at or after each reference epoch, and the first (one in ten at
    100 Hz against a 10 Hz reference). Only those rows are converted (:meth:`imunoise.online.EpochStore.arrays`,
    as :func:`imunoise.online.nav_output.build_result` converts them all), so the errors equal those of the
    finished result to the bit. ``start``: a branch forked at ``start``, with its first epoch copied to just before it
    (:func:`branch_errors`)."""
    from imunoise.nav.solution import antenna_llh

    store = nav.store
    if store is None or not store.n:
        return None
    t = store.t if start is None else np.concatenate([[start - 1e-6], store.t])
    ref_t = np.asarray(sc.ref.t)
    tr = ref_t[(ref_t >= t[0]) & (ref_t <= t[-1])]
    if not tr.size:
        return None
    # the epochs nav_errors reads, in t's numbering, and the first, which bounds the reference epochs it takes
    rows = np.unique(np.concatenate([[0], np.searchsorted(t, tr, side="left")]))
    src = rows if start is None else np.maximum(rows - 1, 0)  # ... in the store's
    _, llh, vel, eul, *_ = store.arrays(src)
    return nav_errors(t[rows], antenna_llh(llh, eul, sc.lever), vel, eul, sc.ref)


def navigator_window_metrics(nav, sc: Scenario, start: float, length: float) -> dict:
    """:func:`window_metrics` of a branch navigator forked at ``start`` (:func:`stored_errors`), equal to
    ``window_metrics(branch_errors(nav.finish(), sc, start), start, length)`` to the bit."""
    err = stored_errors(nav, sc, start)
    if err is None:  # nothing stored, or no reference epoch: the finished result's path (nav_errors says why)
        err = branch_errors(nav.finish(), sc, start)
    return window_metrics(err, start, length)
