"""Paired statistics for overlapping outage windows (docs/guide/theory.rst, 'Experiments'; issue "Evidence that holds
outside our own simulator", §4 "Intervals that keep their promise").

Dense outage windows (length L opened every S < L seconds) overlap, so neighbouring windows share most of
their IMU data; and all windows of one drive share its filter state, its model and its bias path. The
independent units are therefore the *clusters*: drives, or units (sensors) above drives when given. The
statistics here are built for that:

* the per-window effect is the paired log-ratio ``log(m_method / m_baseline)`` of one metric (end drift,
  horizontal RMS), so a method that halves the drift on a 50 m window and on a 500 m window counts the
  same; the summary is the geometric-mean ratio ``exp(x̄)``, x̄ = Σ_c S_c / Σ_c n_c the mean log-ratio over
  all windows (S_c, n_c: sum and count of cluster c);
* **C ≥ 2 clusters** — cluster-level t interval ``exp(x̄ ± t_{C−1} · SE)``, with the cluster-robust (CR1)
  standard error of the ratio estimator

      SE² = C/(C − 1) · Σ_c (S_c − x̄ n_c)² / (Σ_c n_c)²,

  which is the variance of the bootstrap that resamples whole clusters, Σ_c (S_c − x̄ n_c)²/(Σ n_c)², with
  the finite-C factor C/(C − 1) (without its Monte Carlo noise); with equal cluster sizes it is s²_c/C of
  the cluster means and the interval is the exact t interval when they are normal. Windows, drives inside a
  unit and their correlation are carried inside each cluster's sum: df = C − 1, whatever the windows count;
* **one cluster** — the fixed-b t of :mod:`imunoise.experiments.fixed_b`: ``exp(x̄ ± c · √(ω̂²/n))`` with the
  Bartlett long-run variance of bandwidth n (Kiefer & Vogelsang 2002) and the critical value c of ``|t|`` for an
  AR(1) series of the drive's length, averaged over the uncertainty of its bias-corrected lag-1
  autocorrelation (a parametric bootstrap-t; 4.77 in the white-noise limit, ~8–9 for 25 windows of AR(0.8));
  no block length, no df. Its scope is said in the output: "one drive: the interval describes this drive's
  windows only" — the drive's random effect is part of its truth, nothing is said about other drives. The
  earlier circular block bootstrap (Politis–White block, :func:`block_bootstrap_interval`) covered 85 % on 25
  AR(0.8) windows; it is kept for the coverage study's comparison and for :func:`gain_share`'s one-cluster case;
* ``n_independent`` counts windows that share no data (starts ≥ L apart); it is reported, no longer a df.

Measured coverage: scripts/coverage_study.py (drive-level random effects plus AR(0.8) within drives) and
tests/experiments/test_coverage.py; the table is in that script's docstring.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from imunoise.errors import DataError, ModelError
from imunoise.experiments.fixed_b import fixed_b_interval

__all__ = ["default_block", "n_independent", "log_ratios", "drive_log_ratios", "politis_white_block",
           "cluster_interval", "block_bootstrap_interval", "bootstrap_ratio", "paired_entry", "gain_share",
           "ONE_DRIVE_SCOPE"]

ONE_DRIVE_SCOPE = "one drive: the interval describes this drive's windows only"
ONE_UNIT_SCOPE = "one unit: the interval describes this unit's windows only"
BIAS_SHARE = 0.1  # one cluster: the block variance may miss at most this share of the long-run variance


def default_block(length_s: float, step_s: float) -> int:
    """Moving-block length (windows) for windows of ``length_s`` opened every ``step_s``: ⌈L/S⌉, the number of
    windows one stretch of data belongs to; 1 for disjoint windows (S ≥ L)."""
    if not (length_s > 0 and step_s > 0):
        raise ModelError(f"window length and step must be > 0 s, got {length_s}, {step_s}")
    return max(1, math.ceil(length_s / step_s - 1e-9))


def n_independent(starts: Sequence[float], length_s: float) -> int:
    """Number of windows of one drive that share no data: greedy count of starts spaced ≥ ``length_s``."""
    n = 0
    last = -math.inf
    for s in sorted(float(x) for x in starts):
        if s >= last + length_s - 1e-9:
            n += 1
            last = s
    return n


def log_ratios(a: Sequence[float | None], b: Sequence[float | None]) -> np.ndarray:
    """Paired ``log(a_k / b_k)``; NaN where either value is missing, non-finite or ≤ 0."""
    x = np.array([np.nan if v is None else v for v in a], dtype=float)
    y = np.array([np.nan if v is None else v for v in b], dtype=float)
    if x.shape != y.shape:
        raise DataError(f"paired values need the same windows, got {x.size} and {y.size}")
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    out = np.full(x.shape, np.nan)
    out[ok] = np.log(x[ok] / y[ok])
    return out


def _flat_top(t: np.ndarray) -> np.ndarray:
    """Flat-top lag window of Politis & Romano (1995): 1 on |t| ≤ ½, 2(1 − |t|) on ½ < |t| ≤ 1, 0 beyond."""
    a = np.abs(t)
    return np.where(a <= 0.5, 1.0, np.where(a <= 1.0, 2.0 * (1.0 - a), 0.0))


def _flat_top_sums(x: np.ndarray) -> tuple[float, float]:
    """(Ĝ, ĝ) of Politis & White (2004) for the finite series ``x`` (see :func:`politis_white_block`): ĝ the
    flat-top estimate of the long-run variance Σ_k R(k), Ĝ that of Σ_k |k| R(k) (the block variance's bias
    constant: a block of b values misses about Ĝ/b of ĝ)."""
    n = x.size
    e = x - x.mean()
    r0 = float(e @ e) / n
    if n < 4 or r0 <= 0.0:
        return 0.0, max(r0, 0.0)
    k_n = max(5, math.ceil(math.log10(n)))
    m_max = min(math.ceil(math.sqrt(n)) + k_n, n - 1)
    acv = np.array([float(e[k:] @ e[:n - k]) / n for k in range(m_max + 1)])
    rho = np.abs(acv[1:] / r0)  # rho[k-1] = |ρ̂(k)|
    crit = 2.0 * math.sqrt(math.log10(n) / n)
    m_hat = next((m for m in range(0, m_max - k_n + 1) if np.all(rho[m:m + k_n] < crit)), None)
    big_m = m_max if m_hat is None else min(2 * max(m_hat, 1), m_max)  # ρ̂(m̂+1) … ρ̂(m̂+K_N) negligible
    k = np.arange(1, big_m + 1)
    lam = _flat_top(k / big_m)
    return 2.0 * float(np.sum(lam * k * acv[1:big_m + 1])), r0 + 2.0 * float(np.sum(lam * acv[1:big_m + 1]))


def politis_white_block(x: Sequence[float]) -> float:
    """Block length of the circular block bootstrap of the mean chosen from the data (Politis & White 2004,
    Eq. 6 and Theorem 3.3, with the constant D_CB = (4/3)·ĝ² of the correction by Patton, Politis & White
    2009).

    m̂ is the smallest lag after which K_N = max(5, ⌈log10 n⌉) sample autocorrelations in a row lie below
    2·√(log10 n / n); M = min(2·max(m̂, 1), ⌈√n⌉ + K_N); with the flat-top window λ (Politis & Romano 1995)
    and the sample autocovariances R̂(k),

        Ĝ = Σ_{|k|≤M} λ(k/M)·|k|·R̂(k),   ĝ = Σ_{|k|≤M} λ(k/M)·R̂(k),   b = (2Ĝ² / ((4/3)ĝ²))^{1/3} · n^{1/3},

    clipped to [1, ⌈min(3√n, n/3)⌉]. Returns 1.0 for a constant series or fewer than 4 values.
    """
    v = np.asarray(x, dtype=float)
    v = v[np.isfinite(v)]
    n = v.size
    g_big, g0 = _flat_top_sums(v)
    if n < 4 or g0 <= 0.0 or g_big == 0.0:
        return 1.0
    b = (2.0 * g_big ** 2 / ((4.0 / 3.0) * g0 ** 2)) ** (1.0 / 3.0) * n ** (1.0 / 3.0)
    return float(min(max(b, 1.0), math.ceil(min(3.0 * math.sqrt(n), n / 3.0))))


def one_cluster_block(x: np.ndarray, floor: int = 1) -> int:
    """Block of the one-cluster interval: the Politis–White choice, lengthened until the estimated bias of
    the block variance Ĝ/b is at most :data:`BIAS_SHARE` of ĝ (PW minimise the variance estimate's MSE;
    an interval needs its bias small), never shorter than ``floor`` (the windows' overlap), and at most n/3
    (three blocks at least)."""
    n = x.size
    g_big, g0 = _flat_top_sums(x)
    b = math.ceil(politis_white_block(x) - 1e-9)
    if g0 > 0.0 and g_big > 0.0:
        b = max(b, math.ceil(g_big / (BIAS_SHARE * g0) - 1e-9))
    return int(max(1, min(max(b, floor), max(floor, n // 3))))


def _cbb_index(n: int, block: int, n_draw: int, rng: np.random.Generator) -> np.ndarray:
    """``n_draw`` circular-block-bootstrap resamples (rows of indices into a series of length ``n``): blocks
    of ``block`` consecutive values wrapped around the end, so each value is drawn equally often."""
    b = max(1, min(block, n))
    m = math.ceil(n / b)
    starts = rng.integers(0, n, size=(n_draw, m))
    return ((starts[:, :, None] + np.arange(b)[None, None, :]) % n).reshape(n_draw, m * b)[:, :n]


def _clusters(groups: Sequence[np.ndarray], units: Sequence | None) -> tuple[list[list[np.ndarray]], str]:
    """Finite values per drive, grouped into clusters: one per drive, or one per unit label when ``units``
    gives each drive's unit (drives nested in units). Empty drives and clusters are dropped."""
    gs = [np.asarray(g, dtype=float) for g in groups]
    gs = [g[np.isfinite(g)] for g in gs]
    if units is None:
        return [[g] for g in gs if g.size], "drive"
    if len(units) != len(gs):
        raise DataError(f"units need one label per drive, got {len(units)} labels for {len(gs)} drives")
    by: dict = {}
    for u, g in zip(units, gs, strict=True):
        if g.size:
            by.setdefault(u, []).append(g)
    return list(by.values()), "unit"


def cluster_interval(groups: Sequence[np.ndarray], block: int | None = None, *, units: Sequence | None = None,
                     level: float = 0.95, n_boot: int = 2000, seed: int = 0) -> dict:
    """Mean of per-window values grouped by drive (and by unit when ``units`` is given) with the interval of
    the module docstring: cluster t (C ≥ 2) or the AR(1)-calibrated fixed-b t (C = 1).

    Parameters
    ----------
    groups
        One array per drive, windows in time order (NaN entries dropped).
    block
        Accepted for compatibility (the overlap ⌈L/S⌉, :func:`default_block`); no interval uses it now.
    units
        Optional unit label per drive: the units become the clusters.
    level, n_boot, seed
        CI level; ``n_boot`` and ``seed`` are accepted for compatibility (both intervals are deterministic).

    Returns
    -------
    dict
        ``mean``, ``ci`` [lo, hi], ``se``, ``df`` (C ≥ 2; None for one cluster), ``n_windows``, ``n_drives``,
        ``n_clusters``, ``cluster`` ("drive" | "unit"), ``interval`` ("cluster t" | "fixed-b t (AR(1)-calibrated)"),
        ``block`` (None; kept in the record), ``critical`` (the multiplier of ``se``), ``scope`` (one cluster:
        :data:`ONE_DRIVE_SCOPE` or the unit's, else None).
    """
    if not (0 < level < 1) or n_boot < 10:
        raise ModelError(f"bootstrap needs 0 < level < 1 and n_boot ≥ 10, got {level}, {n_boot}")
    cl, unit_of = _clusters(groups, units)
    n_drives = sum(len(c) for c in cl)
    out = {"mean": None, "ci": [None, None], "se": None, "df": None, "n_windows": 0, "n_drives": n_drives,
           "n_clusters": len(cl), "cluster": unit_of, "interval": None, "block": None, "critical": None, "scope": None}
    if not cl:
        return out
    s = np.array([sum(float(g.sum()) for g in c) for c in cl])
    cnt = np.array([sum(g.size for g in c) for c in cl], dtype=float)
    mean = float(s.sum() / cnt.sum())
    out.update(mean=mean, n_windows=int(cnt.sum()))
    big_c = len(cl)
    if big_c >= 2:
        resid = s - mean * cnt
        se = math.sqrt(big_c / (big_c - 1) * float(resid @ resid)) / float(cnt.sum())
        df = big_c - 1
        out["interval"] = "cluster t"
    else:
        x = np.concatenate(cl[0])  # one unit holding several drives: its windows in drive order
        if x.size < 2 or float(np.ptp(x)) == 0.0:
            r = {"se": 0.0, "critical": None, "ci": [mean, mean]}
        else:
            r = fixed_b_interval(x, level)
        out.update(ci=r["ci"], se=r["se"], critical=r["critical"], interval="fixed-b t (AR(1)-calibrated)",
                   scope=ONE_DRIVE_SCOPE if n_drives == 1 else ONE_UNIT_SCOPE)
        return out
    half = float(stats.t.ppf(0.5 + level / 2, df)) * se
    out.update(ci=[mean - half, mean + half], se=se, df=df, critical=float(stats.t.ppf(0.5 + level / 2, df)))
    return out


def block_bootstrap_interval(x: np.ndarray, block: int | None = None, *, level: float = 0.95, n_boot: int = 2000,
                             seed: int = 0) -> dict:
    """The earlier one-cluster interval, kept for comparison (scripts/coverage_study.py): a circular block
    bootstrap of the series with the block of :func:`one_cluster_block` (Politis–White, lengthened until the
    block variance's bias Ĝ/b ≤ 10 % of ĝ, ≥ ``block``, ≤ n/3), SE² = Var*(means)·n/(n − b) + Ĝ/(b n) and
    t with df = ⌊n/b⌋ − 1. Returns ``mean``, ``ci``, ``se``, ``df``, ``block``."""
    v = np.asarray(x, dtype=float)
    v = v[np.isfinite(v)]
    n = v.size
    mean = float(v.mean())
    b = min(n, one_cluster_block(v, int(block or 1)))
    if n < 2 or float(np.ptp(v)) == 0.0:
        se = 0.0
    else:
        idx = _cbb_index(n, b, n_boot, np.random.default_rng(seed))
        var_b = float(np.var(v[idx].mean(axis=1), ddof=1)) * n / max(n - b, 1)
        se = math.sqrt(var_b + max(_flat_top_sums(v)[0], 0.0) / (b * n))
    df = max(n // b - 1, 1)
    half = float(stats.t.ppf(0.5 + level / 2, df)) * se
    return {"mean": mean, "ci": [mean - half, mean + half], "se": se, "df": df, "block": b}


def bootstrap_ratio(groups: Sequence[np.ndarray], block: int | None = None, *, n_boot: int = 2000,
                    level: float = 0.95, seed: int = 0, n_indep: int | None = None,
                    units: Sequence | None = None) -> dict:
    """Geometric-mean ratio ``exp(mean log-ratio)`` of paired log-ratios grouped by drive, with the
    cluster-level CI of :func:`cluster_interval` (module docstring). The name is kept from the earlier
    two-level bootstrap; ``n_indep`` is accepted for compatibility and no longer sets the df (clusters do).

    Returns
    -------
    dict
        ``ratio``, ``ci`` [lo, hi], ``se_log``, ``df``, ``n_windows``, ``n_drives``, ``n_clusters``, ``cluster``,
        ``interval``, ``block``, ``scope`` (:func:`cluster_interval`).
    """
    r = cluster_interval(groups, block, units=units, level=level, n_boot=n_boot, seed=seed)
    if r["mean"] is None:
        return {"ratio": None, "ci": [None, None], "se_log": None, **_meta(r)}
    lo, hi = r["ci"]
    return {"ratio": math.exp(r["mean"]), "ci": [math.exp(lo), math.exp(hi)], "se_log": r["se"], **_meta(r)}


def _meta(r: dict) -> dict:
    return {k: r[k] for k in ("df", "n_windows", "n_drives", "n_clusters", "cluster", "interval", "block", "critical",
                              "scope")}


def drive_log_ratios(a, b) -> np.ndarray:
    """Per-window log-ratios of one drive from ``a``, ``b`` given per realisation (rows; e.g. GNSS noise seeds)
    and window (columns), or as one row: the log-ratio averaged over the realisations of each window (they
    share the IMU data, so they sharpen a window's value but are not more windows)."""
    x = np.atleast_2d(np.array([[np.nan if v is None else v for v in row] for row in np.atleast_2d(np.array(
        a, dtype=object))], dtype=float))
    y = np.atleast_2d(np.array([[np.nan if v is None else v for v in row] for row in np.atleast_2d(np.array(
        b, dtype=object))], dtype=float))
    lr = np.vstack([log_ratios(p, q) for p, q in zip(x, y, strict=True)])
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(lr).any(axis=0)
        out = np.full(lr.shape[1], np.nan)
        out[ok] = np.nanmean(lr[:, ok], axis=0)
    return out


def paired_entry(method: str, baseline: str, metric: str, values: dict, block: int | None = None, *,
                 n_independent_total: int | None = None, units: Sequence | None = None, **boot_kw) -> dict:
    """One ``results.json`` ``paired`` entry: ``values[name]`` holds per drive the per-window metric, either one
    list or one list per realisation (:func:`drive_log_ratios`); ``units`` optionally a unit label per drive.

    Returns ``{"method", "baseline", "metric", "ratio", "ci", "n_windows", "n_drives", "n_independent",
    "n_clusters", "cluster", "df", "interval", "block", "critical", "scope", "significant"}``; ``significant`` is True
    only when the CI excludes 1.
    """
    groups = [drive_log_ratios(a, b) for a, b in zip(values[method], values[baseline], strict=True)]
    r = bootstrap_ratio(groups, block, units=units, **boot_kw)
    lo, hi = r["ci"]
    sig = method != baseline and lo is not None and (lo > 1.0 or hi < 1.0)
    return {"method": method, "baseline": baseline, "metric": metric, "ratio": r["ratio"], "ci": r["ci"],
            "n_windows": r["n_windows"], "n_drives": r["n_drives"], "n_independent": n_independent_total,
            "n_clusters": r["n_clusters"], "cluster": r["cluster"], "df": r["df"], "interval": r["interval"],
            "block": r["block"], "critical": r["critical"], "scope": r["scope"], "significant": bool(sig)}


def gain_share(groups: Sequence[np.ndarray], ref_groups: Sequence[np.ndarray], block: int | None = None, *,
               n_boot: int = 2000, level: float = 0.95, seed: int = 0, units: Sequence | None = None) -> dict:
    """Share of a reference's log-gain that a method captures: ``Σ log(m/plain) / Σ log(ref/plain)`` over the
    windows where both are finite (= log ratio_m / log ratio_ref of the geometric means there; issue 13,
    acceptance 1, with ref = the oracle), with a percentile CI from a bootstrap that resamples whole clusters
    (drives, or units when ``units`` is given) with replacement; with one cluster, a circular block bootstrap
    of its windows with the block of :func:`one_cluster_block` (the longer of the two series' choices).
    Numerator and denominator share every draw (paired).

    Returns
    -------
    dict
        ``share`` (None if the reference gains nothing), ``ci`` [lo, hi] (percentile; replicates whose reference
        gain is 0 are dropped), ``n_windows``, ``n_drives``, ``n_clusters``, ``scope`` (one cluster only).
    """
    if len(groups) != len(ref_groups):
        raise DataError(f"gain share needs the same drives, got {len(groups)} and {len(ref_groups)}")
    if units is not None and len(units) != len(groups):
        raise DataError(f"units need one label per drive, got {len(units)} labels for {len(groups)} drives")
    by: dict = {}
    for j, (g, r) in enumerate(zip(groups, ref_groups, strict=True)):
        g, r = np.asarray(g, dtype=float), np.asarray(r, dtype=float)
        if g.shape != r.shape:
            raise DataError(f"gain share needs the same windows per drive, got {g.size} and {r.size}")
        ok = np.isfinite(g) & np.isfinite(r)
        if ok.any():
            by.setdefault(j if units is None else units[j], []).append((g[ok], r[ok]))
    pairs = [(np.concatenate([p[0] for p in c]), np.concatenate([p[1] for p in c])) for c in by.values()]
    n_win = int(sum(g.size for g, _ in pairs))
    n_drives = sum(len(c) for c in by.values())
    base = {"n_windows": n_win, "n_drives": n_drives, "n_clusters": len(pairs), "scope": None}
    den = float(sum(r.sum() for _, r in pairs))
    if not pairs or den == 0.0:
        return {"share": None, "ci": [None, None], **base}
    if not (0 < level < 1) or n_boot < 10:
        raise ModelError(f"bootstrap needs 0 < level < 1 and n_boot ≥ 10, got {level}, {n_boot}")
    share = float(sum(g.sum() for g, _ in pairs)) / den
    rng = np.random.default_rng(seed)
    if len(pairs) >= 2:
        num_c = np.array([g.sum() for g, _ in pairs])
        den_c = np.array([r.sum() for _, r in pairs])
        pick = rng.integers(0, len(pairs), size=(n_boot, len(pairs)))
        num_b, den_b = num_c[pick].sum(axis=1), den_c[pick].sum(axis=1)
    else:
        g, r = pairs[0]
        b = min(g.size, max(one_cluster_block(g, int(block or 1)), one_cluster_block(r, int(block or 1))))
        idx = _cbb_index(g.size, b, n_boot, rng)
        num_b, den_b = g[idx].sum(axis=1), r[idx].sum(axis=1)
        base["scope"] = ONE_DRIVE_SCOPE if n_drives == 1 else ONE_UNIT_SCOPE
    ok = den_b != 0.0
    q = np.quantile(num_b[ok] / den_b[ok], [0.5 - level / 2, 0.5 + level / 2])
    return {"share": share, "ci": [float(q[0]), float(q[1])], **base}
