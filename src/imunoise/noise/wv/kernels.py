"""Numba kernels of the Haar wavelet variance: window-sum pyramid, per-level sums and batch statistics
(paper Eq. 4, docs/guide/theory.rst, 'Wavelet variance').

Window sums S_m(t) of length m = 2**(j-1) are built by the pyramid recursion S_2m(t) = S_m(t) + S_m(t-m),
and W_{j,t} = (S_m(t) - S_m(t-m)) / (2m). One vectorised pass over memory per two levels, O(N*J) in total;
every subtraction is between two sums over m samples of the (de-meaned) data, so no digits are lost to a
large running total as with a global cumulative sum.
"""

from __future__ import annotations

import threading

import numpy as np
from numba import njit, uint64

__all__ = [
    "LEVEL_CAP",
    "N_STATS",
    "batch_size",
    "batch_stats",
    "huber_mean_rho",
    "level_coefficients",
    "level_pass",
    "segment_stats",
    "work_buffers",
]

LEVEL_CAP = 48  # more levels than any series can have (2**48 samples)
N_STATS = 5  # per level: sum W^2, M, sum_b S_b^2, sum_b n_b S_b, sum_b n_b^2


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
    # Public: the streaming estimator (imunoise.noise.wv_stream) runs the same kernel over its rings.
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
def segment_stats(x, mean, n_levels, blocks, a, b):  # pragma: no cover - compiled
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


def work_buffers(n: int) -> tuple[np.ndarray, np.ndarray]:
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
def level_coefficients(a, out, m):  # pragma: no cover - compiled
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
def huber_mean_rho(w2, s, c2):  # pragma: no cover - compiled
    acc = 0.0
    lim = c2 * s
    for i in range(w2.shape[0]):
        v = w2[i]
        acc += v if v < lim else lim
    return acc / (w2.shape[0] * s)


@njit(cache=True)
def batch_stats(u, bsize, t_first):  # pragma: no cover - compiled
    # sum_b S_b^2, sum_b n_b S_b, sum_b n_b^2 over batches of u (u[i] at time t_first + i), batches
    # ending where the time index is a multiple of bsize (as in segment_stats)
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

