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

__all__ = ["branch_errors", "window_metrics"]


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
