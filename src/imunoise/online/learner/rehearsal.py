"""Shadow filters and rehearsed outages: the data a round needs and one round's scores and NIS.

A shadow is a copy of the live filter running a candidate model on the same IMU samples and GNSS fixes a few
seconds behind (the batch kernel, :meth:`~imunoise.nav.step_filter.LooselyCoupledEKF.rehearse`). A round, for
every active shadow: (1) a copy of it runs ``outage_s`` on without GNSS and is scored by the log RMS horizontal
distance between its antenna position and every fix of that span (the drift the candidate would have had,
measured against GNSS the filter had anyway; one fix's noise would swamp the differences); (2) the shadow itself
advances ``every_s`` with the fixes, collecting the NIS of each fix (position; velocity where aided), taking a
new static model at the time the live filter took it, and adding its departure-step variance at every start
from a stop of at least ``min_stop_s``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.nav.earth import radii
from imunoise.nav.solution import antenna_llh
from imunoise.online.learner.candidates import Spec, compose, departure_variance

__all__ = ["SampleBuffer", "run_round", "ned_offset", "horizontal_distance", "add_departure", "static_runs"]


def ned_offset(llh_a: np.ndarray, llh_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """North and east offsets [m] of rows of ``llh_a`` from ``llh_b`` ((n, 3) lat/lon rad, h m; local flat
    Earth)."""
    a = np.atleast_2d(llh_a)
    b = np.atleast_2d(llh_b)
    rm, rn = radii(b[:, 0])
    return (a[:, 0] - b[:, 0]) * (rm + b[:, 2]), (a[:, 1] - b[:, 1]) * (rn + b[:, 2]) * np.cos(b[:, 0])


def horizontal_distance(llh_a: np.ndarray, llh_b: np.ndarray) -> np.ndarray:
    """Horizontal distance [m] between rows of two (n, 3) lat/lon [rad]/h [m] arrays (local flat Earth)."""
    dn, de = ned_offset(llh_a, llh_b)
    return np.hypot(dn, de)


def static_runs(static: np.ndarray, run0: int) -> np.ndarray:
    """Length of the raw static run at each sample (0 when not static), continuing ``run0``."""
    n = static.size
    idx = np.arange(n)
    last_false = np.maximum.accumulate(np.where(static, -1, idx))
    return np.where(last_false >= 0, idx - last_false, run0 + idx + 1).astype(np.int64)


def add_departure(ekf: Any, var: Sequence[float]) -> None:
    """A departure from a stop: the bias covariance of axis a grows by ``var[a]`` (P refers to the current
    epoch first; cross-covariances untouched): :meth:`LooselyCoupledEKF.add_bias_variance`."""
    ekf.add_bias_variance(var)


class SampleBuffer:
    """The IMU samples (t, Δθ, Δv, departure flag) and used fixes the shadows have not passed yet."""

    def __init__(self, min_stop_n: int) -> None:
        n0 = 4096
        self.t = np.empty(n0)
        self.dth = np.empty((n0, 3))
        self.dv = np.empty((n0, 3))
        self.dep = np.zeros(n0, dtype=bool)
        self.n = 0
        self.run = 0  # raw static run length at the last sample
        self.min_stop_n = int(min_stop_n)
        self.fixes: list[tuple[float, np.ndarray, np.ndarray]] = []

    def add(self, t: np.ndarray, dth: np.ndarray, dv: np.ndarray, static: np.ndarray, keep_from: float) -> None:
        m = t.size
        runs = static_runs(static, self.run)
        prev = np.concatenate([[self.run], runs[:-1]])
        dep = ~static & (prev >= self.min_stop_n)
        self.run = int(runs[-1]) if m else self.run
        if self.n + m > self.t.size:
            i = max(int(np.searchsorted(self.t[: self.n], keep_from, side="left")), 0) if math.isfinite(keep_from) \
                else self.n
            k = self.n - i
            size = self.t.size
            while k + m > size:
                size *= 2
            nt, nth, nv, nd = np.empty(size), np.empty((size, 3)), np.empty((size, 3)), np.zeros(size, dtype=bool)
            old = slice(i, self.n)
            nt[:k], nth[:k], nv[:k], nd[:k] = self.t[old], self.dth[old], self.dv[old], self.dep[old]
            self.t, self.dth, self.dv, self.dep, self.n = nt, nth, nv, nd, k
        s = slice(self.n, self.n + m)
        self.t[s], self.dth[s], self.dv[s], self.dep[s] = t, dth, dv, dep
        self.n += m

    def restart_at_last(self) -> None:
        """Keep only the last sample (the shadows start there)."""
        j = self.n - 1
        self.t[0], self.dth[0], self.dv[0], self.dep[0] = self.t[j], self.dth[j], self.dv[j], self.dep[j]
        self.n = 1

    def fix_arrays(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        fl = self.fixes
        return (np.array([fl[k][0] for k in idx], dtype=float), np.array([fl[k][1] for k in idx]).reshape(-1, 3),
                np.array([fl[k][2] for k in idx]).reshape(-1, 3))


def _light_copy(e: Any) -> Any:
    """A copy of a filter whose state arrays are its own (the layout, read-only, is shared)."""
    c = copy.copy(e)
    c.nav, c.xm, c.P, c.acc = e.nav.copy(), e.xm.copy(), e.P.copy(), e.acc.copy()
    return c


def _pieces(j0: int, j1: int, dep_idx: np.ndarray) -> list[tuple[int, int, bool]]:
    """Sample ranges [a, b] (inclusive ends shared) from j0 to j1 − 1 split after each departure sample; the
    flag says whether a departure's variance is added at b."""
    out = []
    a = j0
    for d in dep_idx:
        if a < d < j1:
            out.append((a, int(d), True))
            a = int(d)
    out.append((a, j1 - 1, False))
    return [p for p in out if p[1] > p[0]]


def _advance(e: Any, t, dth, dv, j0: int, j1: int, fixes, dep_idx: np.ndarray, var, with_nis: bool,
             nll: list | None = None) -> tuple:
    """Shadow ``e`` in place over samples j0..j1−1 with ``fixes`` (t, llh, σ) there and the departure
    variance ``var`` after each departure sample; returns (rows llh, rows euler, ΣNIS, #fixes). With a list
    ``nll`` (and ``with_nis``), its first item accumulates the fixes' one-step innovation NLL (likelihood
    statistic)."""
    at, allh, asig = fixes
    llh_parts, eul_parts = [], []
    s_nis, n_nis = 0.0, 0
    kw = {"with_nll": True} if nll is not None else {}
    for a, b, bump in _pieces(j0, j1, dep_idx if var is not None else np.zeros(0, dtype=np.int64)):
        m = (at > t[a]) & (at <= t[b])
        out = e.rehearse(t[a:b + 1], dth[a:b + 1], dv[a:b + 1], at[m], allh[m], asig[m], with_nis=with_nis,
                         in_place=True, **kw)
        llh_parts.append(out[0] if not llh_parts else out[0][1:])
        eul_parts.append(out[1] if not eul_parts else out[1][1:])
        if with_nis:
            g = out[2]
            s_nis += float(np.nansum(g))
            n_nis += int(np.isfinite(g).sum())
            if nll is not None:
                nll[0] += float(np.nansum(out[3]))
        if bump:
            add_departure(e, var)
    if not llh_parts:
        return np.zeros((0, 3)), np.zeros((0, 3)), 0.0, 0
    return np.concatenate(llh_parts), np.concatenate(eul_parts), s_nis, n_nis


def run_round(job: dict, specs: Sequence[Spec], lever: np.ndarray, rate: float, min_speed: float) -> dict:
    """One round (module docstring) for the active shadows of ``job``. Returns ``scores`` (NaN where not
    rehearsed or not active) and ``nis`` (per shadow: ΣNIS position, #position fixes, ΣNIS velocity, #velocity
    fixes; the engine aids with position fixes only, so the velocity columns stay 0). With ``job["nll"]`` (the
    likelihood statistic) also ``nll``: per shadow the Σ one-step innovation NLL of the round's aided fixes (NaN
    where not active), shadow k seeing the fixes' σ × ``job["rscale"][k]`` (R-only nuisance candidates)."""
    t, dth, dv, n_adv, n_out = job["t"], job["dth"], job["dv"], job["n_adv"], job["n_out"]
    ot, ollh, _ = job["out"]
    dep_idx = np.flatnonzero(job["dep"])
    no_fix = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    shadows = job["shadows"]
    k_ref = next(k for k, e in enumerate(shadows) if e is not None)
    # one speed test per round (the current model's shadow), so every candidate is scored alike
    rehearse = ot.size > 0 and shadows[k_ref].view.speed_h >= min_speed
    ks = np.minimum(np.searchsorted(t[:n_out], ot, side="left"), n_out - 1)
    scores = np.full(len(shadows), np.nan)
    nis = np.zeros((len(shadows), 4))
    want_nll = bool(job.get("nll", False))
    nll_out = np.full(len(shadows), np.nan)
    for k, e in enumerate(shadows):
        if e is None:
            continue
        var = departure_variance(specs[k])
        nll_sum = [0.0] if want_nll else None
        adv = job["adv"]
        if want_nll and job["rscale"][k] != 1.0:
            adv = (adv[0], adv[1], adv[2] * job["rscale"][k])
        if rehearse:
            llh, eul, _, _ = _advance(_light_copy(e), t, dth, dv, 0, n_out, no_fix, dep_idx, var, False)
            dn, de = ned_offset(antenna_llh(llh[ks], eul[ks], lever), ollh)
            scores[k] = math.log(max(float(np.sqrt(np.mean(dn * dn + de * de))), 1e-3))
        j0 = 0
        for ts, models in job["statics"]:
            j1 = int(np.searchsorted(t[:n_adv], ts, side="right"))
            if j1 - j0 >= 2:
                _, _, s, n = _advance(e, t, dth, dv, j0, j1, adv, dep_idx, var, True, nll_sum)
                nis[k, 0] += s
                nis[k, 1] += n
                j0 = j1 - 1
            e.swap_model(compose(models, specs[k], rate), preserve=True)
        _, _, s, n = _advance(e, t, dth, dv, j0, n_adv, adv, dep_idx, var, True, nll_sum)
        nis[k, 0] += s
        nis[k, 1] += n
        if nll_sum is not None:
            nll_out[k] = nll_sum[0]
    res = {"scores": scores, "nis": nis, "rehearsed": bool(rehearse)}
    if want_nll:
        res["nll"] = nll_out
    return res
