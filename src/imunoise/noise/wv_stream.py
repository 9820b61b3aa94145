"""Wavelet variance of ONE contiguous series fed in chunks, in memory set by the coarsest level
(docs/guide/theory.rst, 'Wavelet variance').

:class:`WVStream` gives what :func:`imunoise.noise.wv.wavelet_variance` gives for the whole series (same
levels, nu^2_j, CIs, M_j and batch-means covariance, to rounding), for a series that is read piece by
piece: a 10 h log at 1 kHz is 3.6e7 samples per axis, and the batch estimator holds three copies of it.
(:class:`imunoise.noise.wv.WVAccumulator` instead pools chunks as separate stops: no coefficient spans a
chunk boundary, so it loses the top levels.)

How. The batch pyramid of window sums, S_2m(t) = S_m(t) + S_m(t-m) and W_{j,t} = (S_m(t) - S_m(t-m))/(2m)
with m = 2**(j-1), is run forward in time: level j keeps a ring of the last m values of S_m (slot
t mod m holds S_m(t-m) until S_m(t) replaces it), so every coefficient is formed exactly once, from the
same additions of the same window sums as in the batch. Rings for levels 1..J hold 1 + 2 + ... + 2**(J-1)
= 2**J - 1 values per column, whatever N is. Chunks are cut into blocks of ``BLOCK`` samples so the two
work arrays stay in cache; inside a block a level reads S_m(t-m) from the block itself where it can
(vectorised, like the batch) and from the ring for the first m samples.

Numerics. The batch subtracts the series mean first; a stream cannot know it, so each column subtracts
the mean of its first chunk (a constant cancels in every W exactly; it only keeps the window sums small).
Per level, the squared differences of a run of at most ``BLOCK`` samples inside one batch-means batch are
summed in a plain loop, and the runs are added with Neumaier's compensated summation, so the totals of
1e8 coefficients carry no visible rounding. The scale 1/(4 m^2) is a power of two (exact).

Levels and memory. The level count follows the batch rule from the N seen so far: J = floor(log2 N)
unless ``levels`` or ``max_scale_s`` caps it. The ring of level j is created when N reaches 2**(j-1)
(its first window sum); with a cap J the rings never exceed 2**J - 1 values per column (:attr:`buffer_len`).
Without a cap the rings are ready for level floor(log2 N) + 1, so up to 2**(floor(log2 N)+1) - 1 <= 2N - 1
values are allocated; the newest ring is written slot by slot and untouched pages of ``numpy.empty`` cost
no memory, so the resident size stays about N values per column: below the batch's three N-length arrays.
The robust (Huber) estimate needs every coefficient of a level at once and is not streamed.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import DataError
from imunoise.noise.wv import (
    MIN_COEFFICIENTS,
    MIN_SAMPLES,
    WaveletVariance,
    batch_size,
    level_pass,
    wavelet_variance_from_sums,
)
from imunoise.units import required_freq

__all__ = ["BLOCK", "WVStream"]

#: Samples per column processed in one pass over the levels (two work arrays of this size stay in cache).
BLOCK = 1 << 15

_LEVEL_CAP = 48  # more levels than any stream can have (2**48 samples)
# per level and column: open batch (sum, compensation), total of closed batches (sum, compensation),
# sum_b S_b^2, sum_b n_b S_b, sum_b n_b^2
_STATE = 7


# ---------------------------------------------------------------------------------------------------
# numba kernels


@njit(cache=True)
def _run_ring(a, ring, out, i0, i1, t0, mask, write):  # pragma: no cover - compiled
    # as level_pass, with S_m(t-m) read from the ring slot t mod m that still holds it; cut where the
    # slot index wraps so each piece is a pair of contiguous slices
    s = 0.0
    i = i0
    zero = i0 - i0  # an int64 0, not the literal 0: level_pass keeps the one specialisation wv.py compiles
    while i < i1:
        p = (t0 + i) & mask
        e = min(i1, i + mask + 1 - p)
        s += level_pass(a[i:], ring[p:], out[i:], zero, e - i, write)
        i = e
    return s


@njit(cache=True)
def _neumaier(s, c, x):  # pragma: no cover - compiled
    # compensated s + x (Neumaier): returns the new sum and compensation (not under fastmath)
    t = s + x
    if abs(s) >= abs(x):
        c += (s - t) + x
    else:
        c += (x - t) + s
    return t, c


@njit(cache=True)
def _close_batch(st, cnt, scale):  # pragma: no cover - compiled
    # fold the open batch of every column into the totals (docs/guide/theory.rst, 'Wavelet variance' batch means, wv
    # module docstring)
    for c in range(st.shape[0]):
        sb = (st[c, 0] + st[c, 1]) * scale
        st[c, 2], st[c, 3] = _neumaier(st[c, 2], st[c, 3], sb)
        st[c, 4] += sb * sb
        st[c, 5] += cnt * sb
        st[c, 6] += float(cnt) * cnt
        st[c, 0] = 0.0
        st[c, 1] = 0.0


@njit(cache=True)
def _level_block(a, out, ring, t0, m, bsize, st, cnt, write):  # pragma: no cover - compiled
    """One level over one block: a[c, i] = S_m(t0 + i) of column c; writes S_2m to ``out`` (if
    ``write``), adds the W^2 of the coefficients t >= 2m - 1 to the open batch, closes batches that end
    at a multiple of ``bsize``, stores the block's last m window sums in ``ring``; returns the new count
    of coefficients in the open batch."""
    k_cols, n = a.shape
    mask = m - 1
    scale = 1.0 / (4.0 * m * m)  # W = d / (2m); a power of two
    i = max(0, 2 * m - 1 - t0)  # first coefficient of this level in the block
    while i < n:
        end = min(n, (((t0 + i) // bsize) + 1) * bsize - t0)
        for c in range(k_cols):
            s = 0.0
            if i < m:
                s += _run_ring(a[c], ring[c], out[c], i, min(end, m), t0, mask, write)
            if end > m:
                lo = max(i, m)
                s += level_pass(a[c, m:], a[c, : n - m], out[c, m:], lo - m, end - m, write)
            st[c, 0], st[c, 1] = _neumaier(st[c, 0], st[c, 1], s)
        cnt += end - i
        if (t0 + end) % bsize == 0:
            _close_batch(st, cnt, scale)
            cnt = 0
        i = end
    # S_m(t) goes to slot t mod m, where S_m(t + m) will look for it (only t >= m - 1 is a full window)
    first = max(0, n - m, m - 1 - t0)
    i = first
    while i < n:
        p = (t0 + i) & mask
        e = min(n, i + mask + 1 - p)
        for c in range(k_cols):
            ring[c, p : p + e - i] = a[c, i:e]
        i = e
    return cnt


# ---------------------------------------------------------------------------------------------------
# the stream


class WVStream:
    """Classical Haar WV of one contiguous series (or of k axes sampled together) added in chunks.

    ``result()`` equals ``wavelet_variance(series_so_far, levels=..., freq=..., alpha=...,
    min_coefficients=...)`` to rounding (1e-9 relative for 1e8 samples), however the series was cut.
    Memory: 2**J - 1 window sums per column for J levels, plus two ``BLOCK``-sample work arrays
    (module docstring).

    Parameters
    ----------
    levels : int, optional
        J, the number of levels kept; default floor(log2 N) of the samples seen, like the batch.
    max_scale_s : float, optional
        Largest scale tau_J = 2**J / freq [s] to compute: J = floor(log2(max_scale_s * freq)). Give
        ``levels`` or ``max_scale_s``, not both. Either one fixes the memory.
    freq : float
        Sample rate [Hz], required (as :func:`~imunoise.noise.selection.select_model` requires it).
    alpha : float
        Level of the chi-square intervals.
    min_coefficients : int
        Levels with fewer coefficients are dropped from the result (as in the batch).

    Attributes
    ----------
    n_samples : int
        Samples (rows) added so far.
    n_columns : int or None
        Number of columns, fixed by the first non-empty chunk (None before it).

    Raises
    ------
    DataError
        For a bad sample rate, ``levels``, ``max_scale_s``, ``alpha`` or ``min_coefficients``.
    """

    def __init__(
        self,
        *,
        levels: int | None = None,
        max_scale_s: float | None = None,
        freq: float | None = None,
        alpha: float = 0.05,
        min_coefficients: int = MIN_COEFFICIENTS,
    ) -> None:
        freq = required_freq(freq, "WVStream")  # no rate is assumed: refused in one line naming freq=
        if not 0.0 < alpha < 1.0:
            raise DataError(f"alpha must be in (0, 1), got {alpha!r}")
        if int(min_coefficients) != min_coefficients or min_coefficients < 1:
            raise DataError(f"min_coefficients must be an integer >= 1, got {min_coefficients!r}")
        self.freq = float(freq)
        self.alpha = float(alpha)
        self.min_coefficients = int(min_coefficients)
        self.levels = _level_cap(levels, max_scale_s, self.freq)
        self.n_samples = 0
        self.n_columns: int | None = None
        self._ndim = 0
        self._offset = np.zeros(0)
        self._rings: list[np.ndarray] = []
        self._state = np.zeros((0, 0, _STATE))
        self._counts = np.zeros(0, dtype=np.int64)
        self._work: tuple[np.ndarray, ...] = ()

    @property
    def max_levels(self) -> int:
        """Levels accumulated: ``levels`` if capped, else 48 (more than any stream reaches)."""
        return self.levels if self.levels is not None else _LEVEL_CAP

    @property
    def buffer_len(self) -> int:
        """Window sums held per column (all rings): 2**(number of rings) - 1, at most 2**J - 1 with a cap J."""
        return sum(r.shape[1] for r in self._rings)

    def add(self, chunk: np.ndarray) -> None:
        """Append the next samples of the series.

        Parameters
        ----------
        chunk : numpy.ndarray
            (n,) samples of one series (or one sample as a scalar), or (n, k) rows of k columns (e.g. six
            IMU axes); any n >= 0. The first non-empty chunk fixes the shape; later ones must match it.

        Raises
        ------
        DataError
            For non-numeric or non-finite samples, or a shape that does not match earlier chunks.
        """
        x, ndim = self._validated(chunk)
        n = x.shape[0]
        if n == 0:
            return
        if self.n_columns is None:
            self._start(x, ndim)
        cols = x.T  # (k, n) view; each block is copied into contiguous rows
        for b0 in range(0, n, BLOCK):
            self._add_block(cols[:, b0 : b0 + BLOCK])

    def result(self) -> WaveletVariance | list[WaveletVariance]:
        """The wavelet variance of the series seen so far.

        Returns
        -------
        WaveletVariance or list of WaveletVariance
            One per column for (n, k) chunks, else one.

        Raises
        ------
        DataError
            With fewer than 16 samples, constant data, or no level with ``min_coefficients`` coefficients.
        """
        if self.n_samples < MIN_SAMPLES:
            raise DataError(f"only {self.n_samples} samples; the wavelet variance needs at least {MIN_SAMPLES}")
        top = min(self.max_levels, int(math.floor(math.log2(self.n_samples))))
        out = []
        for c in range(self.n_columns):
            sums = self._sums(c, top)
            if sums[0, 0] == 0.0:
                where = f" in column {c}" if self._ndim == 2 else ""
                raise DataError(
                    f"all samples equal{where}: constant data has no wavelet variance; check the sensor "
                    "axis, the unit conversion, or whether the device was logging"
                )
            out.append(
                wavelet_variance_from_sums(
                    sums, freq=self.freq, alpha=self.alpha, min_coefficients=self.min_coefficients
                )
            )
        return out[0] if self._ndim == 1 else out

    # -- internals ---------------------------------------------------------------------------------

    def _validated(self, chunk) -> tuple[np.ndarray, int]:
        """(n, k) float64 view of a chunk and its ndim."""
        try:
            x = np.asarray(chunk, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise DataError(f"chunk is not numeric: {exc}") from None
        if x.ndim == 0:  # one sample of a single series
            x = x.reshape(1)
        if x.ndim > 2:
            raise DataError(f"chunk has shape {x.shape}; pass (n,) samples or (n, k) rows of k columns")
        if x.ndim == 2 and x.shape[1] == 0:
            raise DataError(f"chunk has shape {x.shape}: no columns")
        if x.shape[0] == 0:
            return x.reshape(0, 1 if x.ndim == 1 else x.shape[1]), x.ndim
        if self.n_columns is not None:
            k = 1 if x.ndim == 1 else x.shape[1]
            if x.ndim != self._ndim or k != self.n_columns:
                want = "(n,)" if self._ndim == 1 else f"(n, {self.n_columns})"
                raise DataError(f"chunk has shape {x.shape} but the stream holds {want} chunks")
        if not math.isfinite(float(x.sum())):
            bad = ~np.isfinite(x)
            if not bad.any():
                raise DataError("chunk overflows float64 when summed; rescale it (e.g. to SI units)")
            row = int(np.argmax(bad.any(axis=1) if x.ndim == 2 else bad))
            col = "" if x.ndim == 1 else f", column {int(np.argmax(bad[row]))}"
            raise DataError(
                f"non-finite sample at index {self.n_samples + row}{col} of the stream; remove or "
                "interpolate NaN/Inf samples (or feed the pieces between them to separate streams)"
            )
        return (x if x.ndim == 2 else x[:, None]), x.ndim

    def _start(self, x: np.ndarray, ndim: int) -> None:
        k = x.shape[1]
        self.n_columns = k
        self._ndim = ndim
        # a constant cancels in every W; the first chunk's mean keeps the window sums small
        self._offset = x.mean(axis=0)
        self._state = np.zeros((0, k, _STATE))
        self._work = (np.empty(k * BLOCK), np.empty(k * BLOCK))

    def _grow(self, n_total: int) -> None:
        """Create the rings of the levels whose first window sum falls in the first ``n_total`` samples."""
        want = min(self.max_levels, int(math.floor(math.log2(n_total))) + 1)
        have = len(self._rings)
        if want <= have:
            return
        k = self.n_columns
        # numpy.empty: pages of a new ring cost memory only once written (slot by slot as samples arrive)
        self._rings += [np.empty((k, 1 << lev)) for lev in range(have, want)]
        self._state = np.concatenate([self._state, np.zeros((want - have, k, _STATE))])
        self._counts = np.concatenate([self._counts, np.zeros(want - have, dtype=np.int64)])

    def _add_block(self, cols: np.ndarray) -> None:
        n = cols.shape[1]
        t0 = self.n_samples
        self._grow(t0 + n)
        # C-contiguous (k, n) views: every row slice the kernels see is contiguous (vectorised loops)
        k = self.n_columns
        a, b = (w[: k * n].reshape(k, n) for w in self._work)
        np.subtract(cols, self._offset[:, None], out=a)
        top = len(self._rings)
        for lev in range(top):
            m = 1 << lev
            if t0 + n < m:  # no full window of this level yet
                break
            write = lev + 1 < top and t0 + n >= 2 * m
            self._counts[lev] = _level_block(
                a, b, self._rings[lev], t0, m, batch_size(lev + 1), self._state[lev], self._counts[lev], write
            )
            a, b = b, a  # S_2m is the next level's input; the old input is no longer needed
        self.n_samples = t0 + n

    def _sums(self, c: int, top: int) -> np.ndarray:
        """(top, 5) per-level statistics of column c, the open batch closed at the current end."""
        sums = np.zeros((top, 5))
        for lev in range(min(top, len(self._rings))):
            st = self._state[lev, c]
            total, comp, ss, ns, nn = st[2], st[3], st[4], st[5], st[6]
            cnt = int(self._counts[lev])
            if cnt > 0:
                sb = (st[0] + st[1]) / (4.0 * 4.0**lev)
                total, comp = _neumaier(total, comp, sb)
                ss, ns, nn = ss + sb * sb, ns + cnt * sb, nn + float(cnt) * cnt
            sums[lev] = (total + comp, self.n_samples - 2 ** (lev + 1) + 1, ss, ns, nn)
        return sums


def _level_cap(levels: int | None, max_scale_s: float | None, freq: float) -> int | None:
    """J from ``levels`` or ``max_scale_s`` (None: no cap), validated."""
    if levels is not None and max_scale_s is not None:
        raise DataError("give levels or max_scale_s, not both")
    if levels is not None:
        if isinstance(levels, bool) or int(levels) != levels or levels < 1:
            raise DataError(f"levels must be a positive integer or None, got {levels!r}")
        return int(levels)
    if max_scale_s is None:
        return None
    if not (isinstance(max_scale_s, (int, float)) and math.isfinite(max_scale_s) and max_scale_s > 0):
        raise DataError(f"max_scale_s must be a positive time in seconds, got {max_scale_s!r}")
    # tolerance so that e.g. 0.256 s at 1 kHz (exactly 2**8 samples in decimal) gives 8
    j = int(math.floor(math.log2(max_scale_s * freq) + 1e-9))
    if j < 1:
        raise DataError(
            f"max_scale_s={max_scale_s!r} s is below the finest scale 2/freq = {2.0 / freq!r} s at "
            f"freq={freq!r} Hz; pass max_scale_s >= {2.0 / freq!r} or check freq"
        )
    return j
