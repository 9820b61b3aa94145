"""Filter consistency in the dense-window evidence: the NEES of position + velocity of each method's GNSS-aided run
(docs/guide/theory.rst, 'Experiments').

At every 1 Hz reference epoch from :data:`SKIP_S` after the alignment on, the error of the aided run
e = (position NED [m] of the antenna, velocity NED [m/s]) − reference and the filter's 6×6 position-velocity
covariance P give NEES = eᵀ P⁻¹ e (6 dof). A consistent filter has NEES inside the two-sided 95 % χ²(6) band
on about 95 % of its epochs. Per drive the run keeps only the count of epochs, the count inside and the sum
(:func:`drive_nees`); :func:`nees_summary` pools the epochs over the drives and bootstraps the share over the
drives (the independent units: the epochs of one drive are correlated), seeded. The same quantity as
``scripts/nees_check.py`` (which steps the navigator sample by sample), taken here inside the evidence runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["SKIP_S", "BAND6", "scored_epochs", "epoch_error", "nees6", "drive_nees", "nees_summary"]

SKIP_S = 60.0
"""Seconds after the filter's start that are not scored (the alignment and the first stop's model)."""
BAND6 = (1.2373442457912036, 14.449375335447922)
"""The two-sided 95 % band of χ² with 6 degrees of freedom (scipy.stats.chi2.ppf([0.025, 0.975], 6))."""


def scored_epochs(sc: Any, t: np.ndarray, skip_s: float = SKIP_S) -> tuple[np.ndarray, np.ndarray]:
    """The scored epochs of scenario ``sc`` on the filter's samples ``t``: (sample indices, reference indices),
    one reference epoch per second (the first of each whole second: the integer one of the simulator's 10 Hz
    reference) at least ``skip_s`` after the start (``sc.init.t``), each with the first sample at or after it
    (as :func:`imunoise.nav.metrics.nav_errors` pairs them; 1 µs tolerance). With ``extra["score_span_s"]`` = (a, b)
    only the epochs in [a, b) (one half of the drive, :mod:`imunoise.experiments.drive_halves`)."""
    rt = np.asarray(sc.ref.t, dtype=float)
    t = np.asarray(t, dtype=float)
    sec = np.floor(rt + 1e-6)
    first = np.concatenate([[True], sec[1:] != sec[:-1]])
    a, b = (getattr(sc, "extra", None) or {}).get("score_span_s", (-np.inf, np.inf))
    j = np.flatnonzero(first & (rt >= float(sc.init.t) + skip_s) & (rt <= t[-1] + 1e-6) & (rt >= a) & (rt < b))
    i = np.searchsorted(t, rt[j] - 1e-6, side="left")
    ok = i < t.size
    return i[ok].astype(int), j[ok].astype(int)


def epoch_error(sc: Any, j: int, llh: np.ndarray, euler: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """(ΔN, ΔE, ΔD [m] of the antenna, Δv_N, Δv_E, Δv_D [m/s]) of an estimate against reference epoch ``j``."""
    from imunoise.nav.solution import antenna_llh
    from imunoise.online import ned_offset

    ant = antenna_llh(np.asarray(llh, dtype=float)[None], np.asarray(euler, dtype=float)[None], sc.lever)
    dn, de = ned_offset(ant, sc.ref.llh[j][None])
    return np.array([dn[0], de[0], -(ant[0, 2] - sc.ref.llh[j][2]), *(np.asarray(vel) - sc.ref.vel_ned[j])])


def nees6(e: np.ndarray, P: np.ndarray) -> float:
    """eᵀ P⁻¹ e over position + velocity (the leading 6×6 block of ``P``)."""
    return float(e[:6] @ np.linalg.solve(np.asarray(P)[:6, :6], e[:6]))


def drive_nees(values: Sequence[float]) -> dict[str, float]:
    """One run's NEES values reduced to what the summary needs: epochs, epochs inside :data:`BAND6`, sum."""
    v = np.asarray(values, dtype=float)
    inside = (v >= BAND6[0]) & (v <= BAND6[1])
    return {"n": int(v.size), "inside": int(inside.sum()), "sum": float(v.sum())}


def nees_summary(per_drive: Sequence[dict[str, float] | None], *, n_boot: int = 2000, seed: int = 0) -> dict[str, Any]:
    """Pooled share of epochs inside the band with its 95 % percentile-bootstrap CI over the drives, and the
    mean NEES; ``per_drive`` the :func:`drive_nees` of one method on each drive (None: not measured there)."""
    d = [x for x in per_drive if x and x["n"] > 0]
    if not d:
        return {"epochs": 0, "drives": 0, "share_inside": None, "ci95": None, "mean_nees": None}
    n = np.array([x["n"] for x in d], dtype=float)
    k = np.array([x["inside"] for x in d], dtype=float)
    s = np.array([x["sum"] for x in d], dtype=float)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(d), size=(n_boot, len(d)))
    boot = k[idx].sum(axis=1) / n[idx].sum(axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return {"epochs": int(n.sum()), "drives": len(d), "share_inside": float(k.sum() / n.sum()),
            "ci95": [float(lo), float(hi)], "mean_nees": float(s.sum() / n.sum()), "band": list(BAND6),
            "per_drive": [dict(x) for x in d]}  # so runs can be pooled (scripts/in_use_carry_over.py)
