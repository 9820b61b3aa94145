"""When a zero-velocity update is applied: the one rule of the batch filter (``nav --zupt``) and the online engine.

A ZUPT is due at a sample that is static, in a static run of at least ``after`` samples (the run's first samples
are where a detector's window still straddles the stop's start, and a car is still settling), every ``every``
samples counted from the run's start (the phase belongs to the stop, not to the record, so a stop gets the same
updates whichever sample the run or the span began at), and not while the angular-rate gate is open. The batch
run takes the due samples as its ZUPT mask (:func:`~imunoise.nav.ekf.run_ekf` with ``zupt_every = 1``); the
online engine stops its kernel spans at them and applies the update with its guards (speed, χ²) and the
zero-angular-rate update (:class:`~imunoise.online.nav_parts.Zupt`). The update itself is
:mod:`imunoise.nav.measurements.zupt` (σ ``zupt_sigma``, default :data:`ZUPT_SIGMA`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ZUPT_AFTER", "ZUPT_EVERY", "ZUPT_SIGMA", "static_runs", "zupt_due", "zupt_due_at"]

ZUPT_AFTER = 50
"""Static samples before the first ZUPT of a stop (0.5 s at 100 Hz)."""
ZUPT_EVERY = 10
"""Samples between two ZUPTs of a stop."""
ZUPT_SIGMA = 0.02
"""1σ of the zero-velocity pseudo-measurement [m/s]."""


def static_runs(static: np.ndarray, run0: int = 0) -> np.ndarray:
    """Length of the static run at each sample (0 when not static), continuing a run of ``run0`` samples that
    ended just before the first sample."""
    static = np.asarray(static, dtype=bool)
    idx = np.arange(static.size)
    last_false = np.maximum.accumulate(np.where(static, -1, idx))
    return np.where(last_false >= 0, idx - last_false, run0 + idx + 1).astype(np.int64)


def zupt_due_at(run: int, every: int, after: int, gate: bool = False) -> bool:
    """Whether a ZUPT is due at a sample ending a static run of ``run`` samples (module docstring)."""
    return run >= after and run % every == 0 and not gate


def zupt_due(static: np.ndarray, *, every: int, after: int, run0: int = 0, gate: np.ndarray | None = None
             ) -> np.ndarray:
    """Boolean per sample: a ZUPT is due (:func:`zupt_due_at` of every sample's static run)."""
    runs = static_runs(static, run0)
    due = np.asarray(static, dtype=bool) & (runs >= after) & (runs % every == 0)
    return due if gate is None else due & ~np.asarray(gate, dtype=bool)
