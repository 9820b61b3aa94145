"""The batch Haar wavelet variance of one series or of many segments
(docs/guide/theory.rst, 'Conventions' and 'Wavelet variance', paper Eq. 4)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imunoise.errors import DataError
from imunoise.noise.wv.accumulator import (
    MIN_COEFFICIENTS,
    MIN_SAMPLES,
    WVAccumulator,
    as_segments,
    check_args,
    default_levels,
)
from imunoise.noise.wv.covariance import finish
from imunoise.noise.wv.kernels import LEVEL_CAP
from imunoise.noise.wv.result import WaveletVariance
from imunoise.noise.wv.robust import robust_stats
from imunoise.units import required_freq

__all__ = ["wavelet_variance"]


def wavelet_variance(
    data: np.ndarray | Sequence[np.ndarray],
    *,
    levels: int | None = None,
    robust: bool = False,
    alpha: float = 0.05,
    freq: float | None = None,
    concat: bool = False,
    min_coefficients: int = MIN_COEFFICIENTS,
) -> WaveletVariance:
    """Haar wavelet variance nu^2_j, j = 1..J, with eta3 chi-square CIs (docs/guide/theory.rst, 'Wavelet variance',
    paper Eq. 4).

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
        Sample rate [Hz], required (keyword; no rate is assumed): it sets ``scales_s`` and ``avar``.
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
    freq = required_freq(freq, "wavelet_variance")
    check_args(levels, alpha, min_coefficients)
    segments, is_list = as_segments(data)
    if concat and is_list:
        joined = np.concatenate([seg for seg, _ in segments])
        segments = [(joined, sum(t for _, t in segments))]
    total = sum(seg.shape[0] for seg, _ in segments)
    if total < MIN_SAMPLES:
        raise DataError(f"only {total} samples; the wavelet variance needs at least {MIN_SAMPLES}")
    acc = WVAccumulator(
        levels=levels, freq=freq, alpha=alpha, min_coefficients=min_coefficients, max_levels=LEVEL_CAP
    )
    for seg, seg_sum in segments:
        acc.add_checked(seg, seg_sum / max(seg.shape[0], 1))
    if not robust:
        return acc.result()
    top = min(acc.max_levels, default_levels(acc.max_length))
    rob = robust_stats([seg for seg, _ in segments], top)
    return finish(acc.level_stats(top), min_coefficients, alpha, freq, robust=True, rob=rob)
