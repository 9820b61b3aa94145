"""Haar wavelet variance (WV) of one series or of many segments (SPEC §1 and §3, paper Eq. 4).

Conventions (same as R ``simts``/``gmwm``, so numbers compare one for one): level j = 1..J, Haar MODWT
filter of width tau_j = 2**j samples, m = 2**(j-1) and

    W_{j,t} = 1/2 [ mean(x_{t-m+1..t}) - mean(x_{t-2m+1..t-m}) ],

nu^2_j = Var(W_{j,t}), estimated without bias from the M_j = N - tau_j + 1 boundary-free coefficients
(paper Eq. 4). Overlapping Allan variance at averaging time m*dt equals 2*nu^2_j.

How it is computed. Window sums S_m(t) of length m = 2**(j-1) are built by the pyramid recursion
S_2m(t) = S_m(t) + S_m(t-m), and W_{j,t} = (S_m(t) - S_m(t-m)) / (2m). One vectorised pass over memory
per two levels (numba), O(N*J) in total; every subtraction is between two sums over m samples of the
(de-meaned) data, so no digits are lost to a large running total as with a global cumulative sum.
Each segment is de-meaned by its own mean first (a constant cancels in every W exactly, but would cost
digits).

Segments. For a list of 1-D arrays the coefficients are formed inside each segment only and pooled:
nu^2_j = sum_s sum_t W^2 / sum_s M_{j,s} (SPEC §3); ``concat=True`` concatenates instead (the paper's way).
:class:`WVAccumulator` keeps the per-level sums, so adding a stop costs only its own samples.

Covariance of nu^2 (``WaveletVariance.cov``). Diagonal. Per level the long-run variance of W^2_{j,t} is
estimated by non-overlapping batch means (asymptotically the Bartlett lag-window estimate of the
spectral density of W^2 at frequency 0 with bandwidth = batch length B_j = max(2*tau_j, 256)
coefficients). Batches end where the time index inside a segment is a multiple of B_j, so they never
cross a segment end (first and last batch of a segment may be partial):

    V_bm = K/(K-1) * sum_b (S_b - n_b nu^2)^2 / M^2,   K = M^2 / sum_b n_b^2 (effective batch count).

With few batches (top levels) that estimate is itself very noisy, so it is shrunk towards the variance
the chi-square CI assumes, V_chi = 2 nu^4 / eta3 (eta3 = max(M/2**j, 1)), with a prior weight of
``COV_PRIOR_BATCHES`` = 4 pseudo-batches: V = ((K-1) V_bm + 4 V_chi) / (K - 1 + 4). Monte Carlo
(N = 2**15, white noise and AR1+AR1+WN+RW, 200 replicates): mean V / true Var(nu^2 hat) = 0.8-1.2 at
levels 1-10, then rising to 1.5-6 at the top four levels where the conservative eta3 prior dominates;
the per-realisation scatter of V is 12-20 % at the low levels. For the robust estimate the same is
applied to the influence function of the M-scale (prior divided by the 60 % efficiency). Off-diagonal
terms are 0: estimates of them from one realisation are noisy enough at the top levels to make the
GMWM weight matrix (the inverse) erratic, and a diagonal is positive definite by construction.
Entries are floored at 1e-14 * max(V) (and a tiny absolute value), so the matrix stays invertible even
for short or periodic data.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit, uint64
from scipy.optimize import brentq
from scipy.special import gammaincinv

from imunoise.errors import DataError

__all__ = [
    "COV_PRIOR_BATCHES",
    "HUBER_C",
    "MIN_COEFFICIENTS",
    "MIN_SAMPLES",
    "WVAccumulator",
    "WaveletVariance",
    "batch_size",
    "diagonal_weights",
    "huber_efficiency",
    "huber_scale",
    "scale_runs",
    "wavelet_variance",
    "wavelet_variance_from_sums",
]

#: Default minimum number of (pooled) coefficients M_j for a level to be kept. simts keeps every level
#: up to floor(log2 N), where M_J = N - 2**J + 1 can be as small as 1; we drop levels with M_j < 8 (for a
#: single series that only happens when N is within 6 samples above a power of two; for N = 1e5 the top
#: level has M_16 = 34465, so all 16 simts levels are kept). Pass ``min_coefficients=1`` for simts' set.
MIN_COEFFICIENTS = 8
#: Fewer samples than this (in total) is an error.
MIN_SAMPLES = 16
#: Huber tuning constant of the M-estimate of scale with rho(u) = min(u^2, c^2): 60 % Gaussian efficiency
#: (simts' default efficiency; simts itself uses Tukey's biweight), breakdown point beta/c^2 = 43 %.
HUBER_C = 1.2245090302333765
#: Prior weight (in batches) of the chi-square variance when shrinking the batch-means variance.
COV_PRIOR_BATCHES = 4.0

_LEVEL_CAP = 48  # more levels than any series can have (2**48 samples)
_STATS = 5  # per level: sum W^2, M, sum_b S_b^2, sum_b n_b S_b, sum_b n_b^2


def _huber_constants(c: float) -> tuple[float, float, float]:
    """E rho(Z), Var rho(Z) and E[rho'(Z) Z] for rho(u) = min(u^2, c^2), Z ~ N(0, 1)."""
    from scipy.stats import norm

    p_in = 2.0 * norm.cdf(c) - 1.0
    tail = 1.0 - p_in
    phi = norm.pdf(c)
    e2 = p_in - 2.0 * c * phi
    e4 = 3.0 * p_in - 2.0 * phi * (c**3 + 3.0 * c)
    beta = e2 + c * c * tail
    var = e4 + c**4 * tail - beta**2
    return float(beta), float(var), float(2.0 * e2)


_HUBER_BETA, _HUBER_VAR, _HUBER_D = _huber_constants(HUBER_C)


def huber_efficiency(c: float = HUBER_C) -> float:
    """Gaussian efficiency of the M-scale with rho(u) = min(u^2, c^2) relative to the SD (= 1/2 / avar)."""
    _, var, d = _huber_constants(c)
    return 0.5 * d * d / var


def batch_size(level: int) -> int:
    """Batch length (coefficients) of the batch-means long-run variance at level j: max(2*2**j, 256)."""
    return max(2 * 2**level, 256)


# ---------------------------------------------------------------------------------------------------
# numba kernels
#
# Speed notes: every inner loop runs over slices that start at index 0 (numba then drops the
# negative-index wraparound and LLVM vectorises), two levels are fused per pass over memory, and the
# two work buffers are reused between calls (fresh 8 MB arrays cost more in page faults than the maths).


@njit(cache=True, fastmath=True)
def level_pass(x, y, out, i0, i1, write):  # pragma: no cover - compiled
    # one level over [i0, i1): sum (x - y)^2 and optionally out = x + y, with x = S_m(t), y = S_m(t-m).
    # Public: the streaming estimator (imunoise.wv_stream) runs the same kernel over its rings.
    # Unsigned indices: numba then skips its negative-index fix-up and LLVM vectorises the loop.
    s = 0.0
    if write:
        for k in range(i0, i1):
            i = uint64(k)
            p = x[i]
            q = y[i]
            d = p - q
            s += d * d
            out[i] = p + q
    else:
        for k in range(i0, i1):
            i = uint64(k)
            d = x[i] - y[i]
            s += d * d
    return s


@njit(cache=True, fastmath=True)
def _pass2(x0, x1, x2, x3, out, i0, i1, write):  # pragma: no cover - compiled
    # two levels: x0..x3 = S_m(t), S_m(t-m), S_m(t-2m), S_m(t-3m); level j uses S_m, level j+1 uses
    # S_2m(t) = S_m(t) + S_m(t-m); optionally writes S_4m(t) = S_2m(t) + S_2m(t-2m) (the additions of
    # two single passes, in the same order)
    s1 = 0.0
    s2 = 0.0
    if write:
        for k in range(i0, i1):
            i = uint64(k)
            p0 = x0[i]
            p1 = x1[i]
            d1 = p0 - p1
            u = p0 + p1
            v = x2[i] + x3[i]
            d2 = u - v
            s1 += d1 * d1
            s2 += d2 * d2
            out[i] = u + v
    else:
        for k in range(i0, i1):
            i = uint64(k)
            p0 = x0[i]
            p1 = x1[i]
            d1 = p0 - p1
            d2 = (p0 + p1) - (x2[i] + x3[i])
            s1 += d1 * d1
            s2 += d2 * d2
    return s1, s2


@njit(cache=True)
def _segment_stats(x, mean, n_levels, blocks, a, b):  # pragma: no cover - compiled
    """Per-level sufficient statistics of one segment (row j-1: sum W^2, M, sum S_b^2, sum n_b S_b,
    sum n_b^2 over batches b). Batches of level j end where the local time index t is a multiple of
    blocks[j-1] (or at the segment end); blocks[j] is a multiple of blocks[j-1]."""
    n = x.shape[0]
    stats = np.zeros((n_levels, 5))
    a = a[:n]
    b = b[:n]
    for i in range(n):
        a[i] = x[i] - mean
    m = 1
    j = 0
    while j < n_levels:
        tau = 2 * m
        if tau > n:
            break
        fuse = j + 1 < n_levels and 2 * tau <= n
        # window sums are only written when a later level will read them
        write = j + 1 < n_levels and 2 * tau <= n if not fuse else j + 2 < n_levels and 4 * tau <= n
        sc1 = 1.0 / (4.0 * m * m)
        sc2 = sc1 / 4.0
        bj = blocks[j]
        bk = blocks[j + 1] if fuse else bj
        h0 = tau - 1  # first coefficient of level j
        f0 = 2 * tau - 1  # first coefficient of level j+1 (start of the fused pass)
        hx = a[h0:]
        hy = a[h0 - m : n - m]
        ho = b[h0:]
        if fuse:
            fx0 = a[f0:]
            fx1 = a[f0 - m : n - m]
            fx2 = a[f0 - 2 * m : n - 2 * m]
            fx3 = a[f0 - 3 * m : n - 3 * m]
            fo = b[f0:]
        else:
            fx0 = fx1 = fx2 = fx3 = fo = hx
        cur1 = 0.0
        cnt1 = 0
        cur2 = 0.0
        cnt2 = 0
        t0 = h0
        while t0 < n:
            t1 = min((t0 // bj + 1) * bj, n)
            if fuse and t0 < f0 < t1:
                t1 = f0
            if fuse and t0 >= f0:
                s1, s2 = _pass2(fx0, fx1, fx2, fx3, fo, t0 - f0, t1 - f0, write)
                cur2 += s2 * sc2
                cnt2 += t1 - t0
            else:
                s1 = level_pass(hx, hy, ho, t0 - h0, t1 - h0, write and not fuse)
            cur1 += s1 * sc1
            cnt1 += t1 - t0
            if t1 % bj == 0 or t1 == n:
                stats[j, 0] += cur1
                stats[j, 2] += cur1 * cur1
                stats[j, 3] += cnt1 * cur1
                stats[j, 4] += float(cnt1) * cnt1
                cur1 = 0.0
                cnt1 = 0
            if fuse and cnt2 > 0 and (t1 % bk == 0 or t1 == n):
                stats[j + 1, 0] += cur2
                stats[j + 1, 2] += cur2 * cur2
                stats[j + 1, 3] += cnt2 * cur2
                stats[j + 1, 4] += float(cnt2) * cnt2
                cur2 = 0.0
                cnt2 = 0
            t0 = t1
        stats[j, 1] = n - tau + 1
        if fuse:
            stats[j + 1, 1] = n - 2 * tau + 1
            j += 2
            m *= 4
        else:
            j += 1
            m *= 2
        a, b = b, a
    return stats


_BUFFERS = threading.local()
_BUFFER_CACHE_MAX = 1 << 21  # samples (two 16 MB buffers at most); longer segments get fresh ones


def _work_buffers(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Two float64 work arrays of length >= n, reused between calls of the same thread."""
    if n > _BUFFER_CACHE_MAX:
        return np.empty(n), np.empty(n)
    bufs = getattr(_BUFFERS, "arrays", None)
    if bufs is None or bufs[0].shape[0] < n:
        size = max(n, 1 << 12)
        bufs = (np.empty(size), np.empty(size))
        _BUFFERS.arrays = bufs
    return bufs


@njit(cache=True)
def _level_coefficients(a, out, m):  # pragma: no cover - compiled
    # W_{j,t} for t in [2m-1, n) and out[t] = a[t] + a[t-m]; a holds window sums of length m.
    n = a.shape[0]
    start = 2 * m - 1
    w = np.empty(n - start)
    inv = 1.0 / (2.0 * m)
    for t in range(start, n):
        p = a[t]
        q = a[t - m]
        w[t - start] = (p - q) * inv
        out[t] = p + q
    return w


@njit(cache=True)
def _huber_mean_rho(w2, s, c2):  # pragma: no cover - compiled
    acc = 0.0
    lim = c2 * s
    for i in range(w2.shape[0]):
        v = w2[i]
        acc += v if v < lim else lim
    return acc / (w2.shape[0] * s)


@njit(cache=True)
def _batch_stats(u, bsize, t_first):  # pragma: no cover - compiled
    # sum_b S_b^2, sum_b n_b S_b, sum_b n_b^2 over batches of u (u[i] at time t_first + i), batches
    # ending where the time index is a multiple of bsize (as in _segment_stats)
    n = u.shape[0]
    ss = 0.0
    ns = 0.0
    nn = 0.0
    i0 = 0
    while i0 < n:
        t0 = t_first + i0
        i1 = min((t0 // bsize + 1) * bsize - t_first, n)
        s = 0.0
        for i in range(i0, i1):
            s += u[i]
        cnt = float(i1 - i0)
        ss += s * s
        ns += cnt * s
        nn += cnt * cnt
        i0 = i1
    return ss, ns, nn


# ---------------------------------------------------------------------------------------------------
# result type


@dataclass(frozen=True)
class WaveletVariance:
    """Haar wavelet variance per level (SPEC §3). Arrays are per kept level j (ascending).

    Attributes
    ----------
    scales : numpy.ndarray
        tau_j = 2**j [samples].
    variance : numpy.ndarray
        nu^2_j [u²].
    ci_low : numpy.ndarray
        Lower end of the (1 - alpha) eta3 chi-square interval of nu^2_j.
    ci_high : numpy.ndarray
        Upper end of that interval.
    n_coefficients : numpy.ndarray
        M_j, the wavelet coefficients pooled over segments.
    cov : numpy.ndarray
        The (J, J) covariance of nu^2 hat (diagonal; module docstring).
    freq : float
        Sample rate [Hz].
    robust : bool
        Whether the Huber M-estimate was used.
    alpha : float
        Level of the intervals.
    """

    scales: np.ndarray  # tau_j = 2**j, samples
    variance: np.ndarray  # nu^2_j
    ci_low: np.ndarray
    ci_high: np.ndarray
    n_coefficients: np.ndarray  # M_j, pooled over segments
    cov: np.ndarray  # (J, J) covariance of nu^2 hat (diagonal, see module docstring)
    freq: float = 1.0  # sample rate, Hz
    robust: bool = False
    alpha: float = 0.05

    def __post_init__(self) -> None:
        scales = np.asarray(self.scales, dtype=float).reshape(-1)
        n = scales.shape[0]
        vals = {
            "scales": scales,
            "variance": np.asarray(self.variance, dtype=float).reshape(-1),
            "ci_low": np.asarray(self.ci_low, dtype=float).reshape(-1),
            "ci_high": np.asarray(self.ci_high, dtype=float).reshape(-1),
            "n_coefficients": np.asarray(self.n_coefficients, dtype=np.int64).reshape(-1),
            "cov": np.asarray(self.cov, dtype=float).reshape(n, n),
        }
        for name, arr in vals.items():
            if name != "cov" and arr.shape != (n,):
                raise DataError(f"WaveletVariance.{name} has {arr.shape[0]} entries, scales has {n}")
            object.__setattr__(self, name, arr)
        if n and not np.array_equal(2.0 ** self.levels, scales):
            raise DataError("WaveletVariance.scales must be powers of two (tau_j = 2**j samples)")
        object.__setattr__(self, "freq", float(self.freq))
        object.__setattr__(self, "alpha", float(self.alpha))
        object.__setattr__(self, "robust", bool(self.robust))

    def __len__(self) -> int:
        return int(self.scales.shape[0])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WaveletVariance):
            return NotImplemented
        return (
            all(
                np.array_equal(getattr(self, k), getattr(other, k))
                for k in ("scales", "variance", "ci_low", "ci_high", "n_coefficients", "cov")
            )
            and (self.freq, self.robust, self.alpha) == (other.freq, other.robust, other.alpha)
        )

    __hash__ = None  # type: ignore[assignment]  # holds arrays

    @property
    def scales_s(self) -> np.ndarray:
        """tau_j in seconds (tau_j / freq)."""
        return self.scales / self.freq

    @property
    def levels(self) -> np.ndarray:
        """Level numbers j of the kept levels (scales = 2**levels)."""
        return np.rint(np.log2(self.scales)).astype(np.int64)

    def avar(self) -> tuple[np.ndarray, np.ndarray]:
        """(averaging time m/freq in s with m = 2**(j-1), overlapping Allan variance 2*nu^2_j) (SPEC §1)."""
        return self.scales / 2.0 / self.freq, 2.0 * self.variance

    def to_dict(self) -> dict:
        """Plain-JSON dict (floats round-trip exactly through ``json``)."""
        return {
            "type": "WaveletVariance",
            "version": 1,
            "scales": [float(v) for v in self.scales],
            "variance": [float(v) for v in self.variance],
            "ci_low": [float(v) for v in self.ci_low],
            "ci_high": [float(v) for v in self.ci_high],
            "n_coefficients": [int(v) for v in self.n_coefficients],
            "cov": [[float(v) for v in row] for row in self.cov],
            "freq": float(self.freq),
            "robust": bool(self.robust),
            "alpha": float(self.alpha),
        }

    @classmethod
    def from_dict(cls, d: dict) -> WaveletVariance:
        """Inverse of :meth:`to_dict`."""
        if d.get("type", "WaveletVariance") != "WaveletVariance":
            raise DataError(f"not a WaveletVariance dict (type={d.get('type')!r})")
        try:
            n = len(d["scales"])
            return cls(
                scales=np.asarray(d["scales"], dtype=float),
                variance=np.asarray(d["variance"], dtype=float),
                ci_low=np.asarray(d["ci_low"], dtype=float),
                ci_high=np.asarray(d["ci_high"], dtype=float),
                n_coefficients=np.asarray(d["n_coefficients"], dtype=np.int64),
                cov=np.asarray(d["cov"], dtype=float).reshape(n, n),
                freq=float(d.get("freq", 1.0)),
                robust=bool(d.get("robust", False)),
                alpha=float(d.get("alpha", 0.05)),
            )
        except KeyError as exc:
            raise DataError(f"WaveletVariance dict lacks key {exc}") from None

    def subset(self, mask: np.ndarray | Sequence[bool] | Sequence[int]) -> WaveletVariance:
        """Keep some levels: a boolean mask over the kept levels or integer positions into them."""
        idx = np.asarray(mask)
        if idx.dtype == bool:
            if idx.shape != (len(self),):
                raise DataError(f"subset mask has shape {idx.shape}, expected ({len(self)},)")
            idx = np.flatnonzero(idx)
        idx = idx.astype(np.int64).reshape(-1)
        return WaveletVariance(
            scales=self.scales[idx],
            variance=self.variance[idx],
            ci_low=self.ci_low[idx],
            ci_high=self.ci_high[idx],
            n_coefficients=self.n_coefficients[idx],
            cov=self.cov[np.ix_(idx, idx)],
            freq=self.freq,
            robust=self.robust,
            alpha=self.alpha,
        )


def scale_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of consecutive True entries of a boolean ``mask`` over scales (WV
    levels or Allan τ points), in order; e.g. [F, T, T, F, T] → [(1, 2), (4, 4)]."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask, dtype=bool).ravel().astype(np.int8), [0]]))
    return [(int(a), int(b) - 1) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)]


def diagonal_weights(wv: WaveletVariance) -> np.ndarray:
    """simts' "fast" weights 1/(ci_high - ci_low)^2 per level (the diagonal of its Omega)."""
    return 1.0 / (wv.ci_high - wv.ci_low) ** 2


# ---------------------------------------------------------------------------------------------------
# helpers


def _chi2_ci(variance: np.ndarray, m: np.ndarray, scales: np.ndarray, alpha: float):
    """eta3 chi-square CI (SPEC §3): eta = max(M_j / 2**j, 1), [eta nu^2 / q_{1-a/2}, eta nu^2 / q_{a/2}]."""
    eta = np.maximum(m / scales, 1.0)
    # chi-square quantiles as scipy.stats.chi2.ppf computes them, without its per-call overhead
    lo = eta * variance / (2.0 * gammaincinv(eta / 2.0, 1.0 - alpha / 2.0))
    hi = eta * variance / (2.0 * gammaincinv(eta / 2.0, alpha / 2.0))
    return lo, hi, eta


def _covariance(variance, m, eta, ss, ns, nn, prior_factor=1.0):
    """Diagonal covariance of nu^2 hat: shrunk batch means (see module docstring).

    ``prior_factor`` scales the chi-square prior variance (1/efficiency for the robust estimate).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.maximum(ss - 2.0 * variance * ns + variance**2 * nn, 0.0)
        k_eff = np.where(nn > 0, m.astype(float) ** 2 / nn, 0.0)
        dof = np.maximum(k_eff - 1.0, 0.0)
        v_chi = prior_factor * 2.0 * variance**2 / eta
        v = (q * k_eff / m.astype(float) ** 2 + COV_PRIOR_BATCHES * v_chi) / (dof + COV_PRIOR_BATCHES)
    v = np.where(np.isfinite(v), v, 0.0)
    floor = max(float(v.max(initial=0.0)) * 1e-14, 1e-300)
    return np.diag(np.maximum(v, floor))


def _as_segments(data) -> tuple[list[tuple[np.ndarray, float]], bool]:
    """Validate input; returns ([(float64 1-D array, its sum), ...], was_a_list)."""
    if (
        isinstance(data, np.ndarray)
        or not isinstance(data, (list, tuple))
        or (len(data) > 0 and all(np.ndim(v) == 0 for v in data))  # a plain list of numbers
    ):
        return [_as_series(data, None)], False
    if len(data) == 0:
        raise DataError("no segments given: pass a 1-D array or a non-empty list of 1-D arrays")
    return [_as_series(seg, k) for k, seg in enumerate(data)], True


def _as_series(x, k: int | None) -> tuple[np.ndarray, float]:
    """Validated contiguous float64 1-D copy-or-view of ``x`` and its sum (``k``: segment number)."""
    where = "" if k is None else f" (segment {k})"
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DataError(f"data{where} is not numeric: {exc}") from None
    if arr.ndim != 1:
        raise DataError(
            f"data{where} has shape {arr.shape}; pass one axis as a 1-D array (e.g. x[:, 0]) "
            "or a list of 1-D segments"
        )
    # the sum is finite iff every sample is (barring overflow, which the slow path below reports)
    total = float(arr.sum())
    if not math.isfinite(total):
        bad = ~np.isfinite(arr)
        if not bad.any():
            raise DataError(f"data{where} overflows float64 when summed; rescale it (e.g. to SI units)")
        i = int(np.argmax(bad))
        raise DataError(
            f"data{where} contains a non-finite value ({arr[i]}) at index {i}; "
            "remove or interpolate NaN/Inf samples (or split the series into segments there)"
        )
    return np.ascontiguousarray(arr), total


def _default_levels(length: int) -> int:
    return int(math.floor(math.log2(length))) if length >= 2 else 0


def _check_args(levels: int | None, alpha: float, min_coefficients: int) -> None:
    if levels is not None and (int(levels) != levels or levels < 1):
        raise DataError(f"levels must be a positive integer or None, got {levels!r}")
    if not 0.0 < alpha < 1.0:
        raise DataError(f"alpha must be in (0, 1), got {alpha!r}")
    if int(min_coefficients) != min_coefficients or min_coefficients < 1:
        raise DataError(f"min_coefficients must be an integer >= 1, got {min_coefficients!r}")


# ---------------------------------------------------------------------------------------------------
# streaming accumulator (also the engine of the classical batch estimate)


class WVAccumulator:
    """Pooled classical WV over segments added one at a time (SPEC §3).

    Each added segment is a separate stop: no coefficient spans two of them. For one contiguous series
    fed in chunks (a long log read piece by piece) use :class:`imunoise.wv_stream.WVStream`, which forms
    the coefficients across chunk boundaries and equals ``wavelet_variance`` of the whole series.

    ``add`` costs O(len(segment) * J) and keeps only per-level sums; ``result()`` equals
    ``wavelet_variance(list_of_segments_added)`` with the same ``levels``, ``alpha``, ``freq``.
    Segments of any length >= 1 are accepted (a segment shorter than tau_j adds nothing at level j).

    Parameters
    ----------
    levels : int, optional
        J; default floor(log2 N) of the longest segment added.
    freq : float
        Sample rate [Hz] (for ``scales_s`` and ``avar`` of the result).
    alpha : float
        Level of the chi-square intervals.
    max_levels : int
        Levels accumulated when ``levels`` is not given.
    min_coefficients : int
        Levels with fewer pooled coefficients are dropped from the result.

    Raises
    ------
    DataError
        For a sample rate that is not positive and finite, or bad ``levels``/``alpha``.
    """

    def __init__(
        self,
        *,
        levels: int | None = None,
        freq: float = 1.0,
        alpha: float = 0.05,
        max_levels: int = 30,
        min_coefficients: int = MIN_COEFFICIENTS,
    ) -> None:
        _check_args(levels, alpha, min_coefficients)
        if freq <= 0 or not math.isfinite(freq):
            raise DataError(f"freq must be a positive sample rate in Hz, got {freq!r}")
        self.levels = None if levels is None else int(levels)
        self.freq = float(freq)
        self.alpha = float(alpha)
        self.min_coefficients = int(min_coefficients)
        self.max_levels = int(self.levels if self.levels is not None else max_levels)
        self._blocks = np.array([batch_size(j) for j in range(1, self.max_levels + 1)], dtype=np.int64)
        self._stats = np.zeros((self.max_levels, _STATS))
        self.n_samples = 0
        self.n_segments = 0
        self.max_length = 0
        self._n_varying = 0

    def add(self, segment: np.ndarray) -> None:
        """Add one segment; its coefficients never reach into other segments.

    Parameters
    ----------
    segment : numpy.ndarray
        1-D array of finite samples [u].
    """
        x, total = _as_series(segment, self.n_segments)
        self._add_validated(x, total / max(x.shape[0], 1))

    def _add_validated(self, x: np.ndarray, mean: float) -> None:
        n = x.shape[0]
        self.n_samples += n
        self.n_segments += 1
        self.max_length = max(self.max_length, n)
        if n < 2:
            return
        n_levels = min(self.max_levels, _default_levels(n))
        a, b = _work_buffers(n)
        stats = _segment_stats(x, mean, n_levels, self._blocks[:n_levels], a, b)
        # level 1 sums (x_t - x_{t-1})^2 / 4: zero exactly when the segment is constant
        if stats[0, 0] > 0.0:
            self._n_varying += 1
        self._stats[:n_levels] += stats

    def result(self) -> WaveletVariance:
        """The pooled wavelet variance of everything added so far.

        Returns
        -------
        WaveletVariance

        Raises
        ------
        DataError
            With fewer than the minimum number of samples, or constant data.
        """
        if self.n_samples < MIN_SAMPLES:
            raise DataError(
                f"only {self.n_samples} samples; the wavelet variance needs at least {MIN_SAMPLES}"
            )
        if self._n_varying == 0:
            what = "all samples equal" if self.n_segments == 1 else "all samples equal within every segment"
            raise DataError(
                f"{what}: constant data has no wavelet variance; check the sensor axis, the unit "
                "conversion, or whether the device was logging"
            )
        top = min(self.max_levels, _default_levels(self.max_length))
        return _finish(
            self._stats[:top], self.min_coefficients, self.alpha, self.freq, robust=False, rob=None
        )


def wavelet_variance_from_sums(
    sums: np.ndarray,
    *,
    freq: float = 1.0,
    alpha: float = 0.05,
    min_coefficients: int = MIN_COEFFICIENTS,
) -> WaveletVariance:
    """Classical WV, eta3 CIs and batch-means covariance from per-level sufficient statistics.

    The batch estimator and the streaming ones reduce the data to these sums and finish here, so all
    of them give the same numbers for the same sums (module docstring for the covariance).

    Parameters
    ----------
    sums : numpy.ndarray
        (J, 5) array, row j-1 for level j = 1..J: sum_t W_{j,t}^2, M_j, sum_b S_b^2, sum_b n_b S_b and
        sum_b n_b^2 over the batches b (S_b the sum of W^2 over the n_b coefficients of batch b; batches
        of level j end where the time index t is a multiple of ``batch_size(j)``).
    freq : float
        Sample rate [Hz].
    alpha : float
        Level of the chi-square intervals.
    min_coefficients : int
        Levels with fewer coefficients M_j are dropped.

    Returns
    -------
    WaveletVariance

    Raises
    ------
    DataError
        If ``sums`` is not (J, 5) or no level has ``min_coefficients`` coefficients.
    """
    arr = np.asarray(sums, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != _STATS:
        raise DataError(f"sums has shape {arr.shape}; expected (levels, {_STATS}) per-level statistics")
    return _finish(arr, int(min_coefficients), float(alpha), float(freq), robust=False, rob=None)


def _finish(stats, min_coefficients, alpha, freq, robust, rob):
    j = np.arange(1, stats.shape[0] + 1)
    m = stats[:, 1].astype(np.int64)
    keep = m >= min_coefficients
    if not keep.any():
        raise DataError(
            f"no level has at least {min_coefficients} wavelet coefficients (longest segment too short); "
            "pass longer segments or a smaller min_coefficients"
        )
    j, m, st = j[keep], m[keep], stats[keep]
    scales = 2.0**j
    variance = st[:, 0] / m if rob is None else rob[keep, 0]
    lo, hi, eta = _chi2_ci(variance, m, scales, alpha)
    if rob is None:
        cov = _covariance(variance, m, eta, st[:, 2], st[:, 3], st[:, 4])
    else:
        # batch means of u = nu^2 + IF(w), whose pooled mean equals nu^2 at the M-estimate
        cov = _covariance(
            rob[keep, 1], m, eta, rob[keep, 2], rob[keep, 3], rob[keep, 4], 1.0 / huber_efficiency()
        )
    return WaveletVariance(
        scales=scales,
        variance=variance,
        ci_low=lo,
        ci_high=hi,
        n_coefficients=m,
        cov=cov,
        freq=freq,
        robust=robust,
        alpha=alpha,
    )


# ---------------------------------------------------------------------------------------------------
# robust estimate


def huber_scale(w: np.ndarray, c: float = HUBER_C) -> float:
    """Huber M-estimate of scale^2 of zero-mean ``w``: solves mean(min(w^2/s, c^2)) = E min(Z^2, c^2).

    Consistent for Gaussian w (Fisher-consistency constant beta = E min(Z^2, c^2)); 60 % efficient at
    the default ``HUBER_C``.
    """
    w2 = np.ascontiguousarray(np.asarray(w, dtype=float) ** 2)
    beta = _huber_beta(c)
    c2 = c * c
    s0 = float(np.median(w2)) / 0.454936423119572  # median of chi2_1
    if s0 <= 0.0:
        s0 = float(w2.mean())
        if s0 <= 0.0:
            return 0.0

    def h(log_s: float) -> float:
        return _huber_mean_rho(w2, math.exp(log_s), c2) - beta

    lo, hi = math.log(s0) - 1.0, math.log(s0) + 1.0
    for _ in range(200):
        if h(lo) > 0:
            break
        lo -= 2.0
    for _ in range(200):
        if h(hi) < 0:
            break
        hi += 2.0
    return math.exp(brentq(h, lo, hi, xtol=1e-13, rtol=1e-15, maxiter=200))


def _huber_beta(c: float) -> float:
    return _HUBER_BETA if c == HUBER_C else _huber_constants(c)[0]


def _robust_stats(segments: list[np.ndarray], top: int) -> np.ndarray:
    """Per level: robust nu^2, then batch statistics of its influence function (columns 1..4)."""
    work = [(s - s.mean(), np.empty(s.shape[0])) for s in segments if s.shape[0] >= 2]
    out = np.zeros((top, 5))
    c2 = HUBER_C * HUBER_C
    m = 1
    for j in range(top):
        coeffs = []
        new_work = []
        for a, b in work:
            if a.shape[0] >= 2 * m:
                coeffs.append(_level_coefficients(a, b, m))
                new_work.append((b, a))
        work = new_work
        if not coeffs:
            break
        s2 = huber_scale(np.concatenate(coeffs))
        out[j, 0] = s2
        bsize = batch_size(j + 1)
        # nu^2 hat - nu^2 ~ mean of IF, IF(w) = 2 s2 (rho(w/s) - beta) / D; use u = nu^2 + IF so the batch
        # means formula (centred on the pooled mean) applies unchanged.
        acc = np.zeros(4)
        total_n = 0
        for w in coeffs:
            r = np.minimum(w * w / s2, c2) if s2 > 0 else np.zeros_like(w)
            u = s2 + 2.0 * s2 * (r - _HUBER_BETA) / _HUBER_D
            acc[:3] += np.array(_batch_stats(u, bsize, 2 * m - 1))
            acc[3] += u.sum()
            total_n += w.shape[0]
        mean_u = acc[3] / total_n
        out[j, 1] = mean_u
        out[j, 2:5] = acc[0], acc[1], acc[2]
        m *= 2
    return out


# ---------------------------------------------------------------------------------------------------
# public entry point


def wavelet_variance(
    data: np.ndarray | Sequence[np.ndarray],
    *,
    levels: int | None = None,
    robust: bool = False,
    alpha: float = 0.05,
    freq: float = 1.0,
    concat: bool = False,
    min_coefficients: int = MIN_COEFFICIENTS,
) -> WaveletVariance:
    """Haar wavelet variance nu^2_j, j = 1..J, with eta3 chi-square CIs (SPEC §3, paper Eq. 4).

    Parameters
    ----------
    data : numpy.ndarray or sequence of numpy.ndarray
        A 1-D array, or a list of 1-D arrays (segments, pooled without crossing junctions).
    levels : int, optional
        J (default floor(log2 N) of the longest segment, like simts).
    robust : bool
        Huber M-estimate of scale of the W_{j,t} per level (``HUBER_C``, 60 % efficiency).
    alpha : float
        Level of the chi-square intervals.
    freq : float
        Sample rate [Hz] (only used for ``scales_s`` and ``avar``).
    concat : bool
        Join the segments of a list first.
    min_coefficients : int
        Levels with fewer pooled coefficients are dropped.

    Returns
    -------
    WaveletVariance

    Raises
    ------
    DataError
        For too few samples, constant or non-finite data, or bad arguments.
    """
    _check_args(levels, alpha, min_coefficients)
    segments, is_list = _as_segments(data)
    if concat and is_list:
        joined = np.concatenate([seg for seg, _ in segments])
        segments = [(joined, sum(t for _, t in segments))]
    total = sum(seg.shape[0] for seg, _ in segments)
    if total < MIN_SAMPLES:
        raise DataError(f"only {total} samples; the wavelet variance needs at least {MIN_SAMPLES}")
    acc = WVAccumulator(
        levels=levels, freq=freq, alpha=alpha, min_coefficients=min_coefficients, max_levels=_LEVEL_CAP
    )
    for seg, seg_sum in segments:
        acc._add_validated(seg, seg_sum / max(seg.shape[0], 1))
    if not robust:
        return acc.result()
    top = min(acc.max_levels, _default_levels(acc.max_length))
    rob = _robust_stats([seg for seg, _ in segments], top)
    return _finish(acc._stats[:top], min_coefficients, alpha, freq, robust=True, rob=rob)
