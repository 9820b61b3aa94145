"""The overlapping Allan variance on a dense log grid or the octave grid, with its χ² intervals
(docs/guide/theory.rst, 'Baselines').

What practitioners do, made reproducible. The overlapping Allan variance at averaging time τ = mΔt is

    AVAR(m) = Σ_k (ȳ_{k+m}(m) − ȳ_k(m))² / (2(N − 2m + 1)),

computed from cumulative sums for any m (the dense log grid), and on the octave grid m = 2^{j−1} it is
exactly 2ν²_j of the Haar wavelet variance (docs/guide/theory.rst, 'Conventions'), so it comes from
:func:`imunoise.noise.wv.wavelet_variance`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from imunoise.errors import DataError
from imunoise.noise.wv import WaveletVariance, wavelet_variance
from imunoise.units import required_freq

__all__ = ["AllanVariance", "allan_variance", "chi2_ci"]


@dataclass(frozen=True)
class AllanVariance:
    """Overlapping Allan variance on a grid of averaging times (s), with η3 chi-square CIs."""

    tau: np.ndarray  # averaging time, s
    avar: np.ndarray
    dof: np.ndarray  # equivalent degrees of freedom η = max(n_terms / (2m), 1)
    ci_low: np.ndarray
    ci_high: np.ndarray
    freq: float
    grid: str  # "octave" or "dense"

    @property
    def adev(self) -> np.ndarray:
        return np.sqrt(self.avar)


def chi2_ci(avar: np.ndarray, eta: np.ndarray, alpha: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    from scipy.special import gammaincinv

    lo = eta * avar / (2.0 * gammaincinv(eta / 2.0, 1.0 - alpha / 2.0))
    hi = eta * avar / (2.0 * gammaincinv(eta / 2.0, alpha / 2.0))
    return lo, hi


@njit(cache=True)
def _avar_sums(c, ms):  # pragma: no cover - compiled
    # Σ_k (c[k+2m] − 2c[k+m] + c[k])² and the number of terms, per m; c = cumulative sum with c[0] = 0
    n = c.shape[0] - 1
    tot = np.zeros(ms.shape[0])
    cnt = np.zeros(ms.shape[0])
    for i in range(ms.shape[0]):
        m = ms[i]
        if n < 2 * m:
            continue
        s = 0.0
        for k in range(n - 2 * m + 1):
            d = c[k + 2 * m] - 2.0 * c[k + m] + c[k]
            s += d * d
        tot[i] = s
        cnt[i] = n - 2 * m + 1
    return tot, cnt


def _segments(data: Any) -> list[np.ndarray]:
    segs = data if isinstance(data, (list, tuple)) else [data]
    out = []
    for s in segs:
        x = np.asarray(s, dtype=float).reshape(-1)
        if not np.all(np.isfinite(x)):
            raise DataError("the data contain NaN or Inf; remove or interpolate them before the Allan variance")
        out.append(x - x.mean() if x.size else x)
    return out


def allan_variance(
    data: Any,
    *,
    freq: float | None = None,
    grid: str = "octave",
    points_per_decade: int = 10,
    wv: WaveletVariance | None = None,
) -> AllanVariance:
    """Overlapping AVAR of a series or list of segments (pooled, never across a junction).

    ``grid="octave"``: m = 2^{j−1} via the identity AVAR = 2ν²_j (a ready ``wv`` may be passed);
    ``grid="dense"``: m on a log grid with ``points_per_decade`` points, from cumulative sums.
    """
    freq = required_freq(freq, "allan_variance")
    if grid == "octave":
        if wv is None:
            wv = wavelet_variance(data, freq=freq)
        tau, avar = wv.scales / 2.0 / freq, 2.0 * wv.variance
        eta = np.maximum(wv.n_coefficients / wv.scales, 1.0)
        lo, hi = 2.0 * wv.ci_low, 2.0 * wv.ci_high
        return AllanVariance(tau, avar, eta, lo, hi, float(freq), "octave")
    if grid != "dense":
        raise DataError(f"unknown Allan grid {grid!r}; use 'octave' or 'dense'")
    segs = _segments(data)
    n_max = max(s.size for s in segs)
    if n_max < 4:
        raise DataError("need at least 4 samples for an Allan variance")
    m_all = np.unique(
        np.round(
            np.logspace(
                0,
                math.log10(n_max / 2),
                max(int(points_per_decade * math.log10(n_max / 2)), 1) + 1,
            )
        ).astype(np.int64)
    )
    tot = np.zeros(m_all.size)
    cnt = np.zeros(m_all.size)
    for seg in segs:
        t, c = _avar_sums(np.concatenate([[0.0], np.cumsum(seg)]), m_all)
        tot += t
        cnt += c
    keep = cnt > 0
    m_arr = m_all[keep].astype(float)
    avar = tot[keep] / (2.0 * m_arr * m_arr * cnt[keep])
    eta = np.maximum(cnt[keep] / (2.0 * m_arr), 1.0)
    lo, hi = chi2_ci(avar, eta)
    return AllanVariance(m_arr / freq, avar, eta, lo, hi, float(freq), "dense")
