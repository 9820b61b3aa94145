"""Pooled classical wavelet variance over segments added one at a time, its input checks, and the WV
from per-level sufficient statistics (docs/guide/theory.rst, 'Wavelet variance').

Segments. The coefficients are formed inside each segment only and pooled:
nu^2_j = sum_s sum_t W^2 / sum_s M_{j,s} (docs/guide/theory.rst, 'Wavelet variance'). Each segment is de-meaned by its
own mean first (a constant cancels in every W exactly, but would cost digits).
"""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import DataError
from imunoise.noise.wv.covariance import finish
from imunoise.noise.wv.kernels import N_STATS, batch_size, segment_stats, work_buffers
from imunoise.noise.wv.result import WaveletVariance

__all__ = [
    "MIN_COEFFICIENTS",
    "MIN_SAMPLES",
    "WVAccumulator",
    "as_segments",
    "as_series",
    "check_args",
    "default_levels",
    "wavelet_variance_from_sums",
]

#: Default minimum number of (pooled) coefficients M_j for a level to be kept. simts keeps every level
#: up to floor(log2 N), where M_J = N - 2**J + 1 can be as small as 1; we drop levels with M_j < 8 (for a
#: single series that only happens when N is within 6 samples above a power of two; for N = 1e5 the top
#: level has M_16 = 34465, so all 16 simts levels are kept). Pass ``min_coefficients=1`` for simts' set.
MIN_COEFFICIENTS = 8
#: Fewer samples than this (in total) is an error.
MIN_SAMPLES = 16


def as_segments(data) -> tuple[list[tuple[np.ndarray, float]], bool]:
    """Validate input; returns ([(float64 1-D array, its sum), ...], was_a_list)."""
    if (
        isinstance(data, np.ndarray)
        or not isinstance(data, (list, tuple))
        or (len(data) > 0 and all(np.ndim(v) == 0 for v in data))  # a plain list of numbers
    ):
        return [as_series(data, None)], False
    if len(data) == 0:
        raise DataError("no segments given: pass a 1-D array or a non-empty list of 1-D arrays")
    return [as_series(seg, k) for k, seg in enumerate(data)], True


def as_series(x, k: int | None) -> tuple[np.ndarray, float]:
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


def default_levels(length: int) -> int:
    return int(math.floor(math.log2(length))) if length >= 2 else 0


def check_args(levels: int | None, alpha: float, min_coefficients: int) -> None:
    if levels is not None and (int(levels) != levels or levels < 1):
        raise DataError(f"levels must be a positive integer or None, got {levels!r}")
    if not 0.0 < alpha < 1.0:
        raise DataError(f"alpha must be in (0, 1), got {alpha!r}")
    if int(min_coefficients) != min_coefficients or min_coefficients < 1:
        raise DataError(f"min_coefficients must be an integer >= 1, got {min_coefficients!r}")


# ---------------------------------------------------------------------------------------------------
# streaming accumulator (also the engine of the classical batch estimate)


class WVAccumulator:
    """Pooled classical WV over segments added one at a time (docs/guide/theory.rst, 'Wavelet variance').

    Each added segment is a separate stop: no coefficient spans two of them. For one contiguous series
    fed in chunks (a long log read piece by piece) use :class:`imunoise.noise.wv_stream.WVStream`, which forms
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
        check_args(levels, alpha, min_coefficients)
        if freq <= 0 or not math.isfinite(freq):
            raise DataError(f"freq must be a positive sample rate in Hz, got {freq!r}")
        self.levels = None if levels is None else int(levels)
        self.freq = float(freq)
        self.alpha = float(alpha)
        self.min_coefficients = int(min_coefficients)
        self.max_levels = int(self.levels if self.levels is not None else max_levels)
        self._blocks = np.array([batch_size(j) for j in range(1, self.max_levels + 1)], dtype=np.int64)
        self._stats = np.zeros((self.max_levels, N_STATS))
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
        x, total = as_series(segment, self.n_segments)
        self.add_checked(x, total / max(x.shape[0], 1))

    def add_checked(self, x: np.ndarray, mean: float) -> None:
        """:meth:`add` of a segment :func:`as_series` already checked (a contiguous float64 1-D array) with its
        ``mean``."""
        n = x.shape[0]
        self.n_samples += n
        self.n_segments += 1
        self.max_length = max(self.max_length, n)
        if n < 2:
            return
        n_levels = min(self.max_levels, default_levels(n))
        a, b = work_buffers(n)
        stats = segment_stats(x, mean, n_levels, self._blocks[:n_levels], a, b)
        # level 1 sums (x_t - x_{t-1})^2 / 4: zero exactly when the segment is constant
        if stats[0, 0] > 0.0:
            self._n_varying += 1
        self._stats[:n_levels] += stats

    def level_stats(self, top: int) -> np.ndarray:
        """The pooled per-level sums of the first ``top`` levels (rows: levels; columns: the kernel's
        ``N_STATS`` sums), as :func:`~imunoise.noise.wv.result.finish` takes them (a view: do not write)."""
        return self._stats[:top]

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
        top = min(self.max_levels, default_levels(self.max_length))
        return finish(
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
    if arr.ndim != 2 or arr.shape[1] != N_STATS:
        raise DataError(f"sums has shape {arr.shape}; expected (levels, {N_STATS}) per-level statistics")
    return finish(arr, int(min_coefficients), float(alpha), float(freq), robust=False, rob=None)
