"""Haar wavelet variance (WV) of one series or of many segments
(docs/guide/theory.rst, 'Conventions' and 'Wavelet variance', paper Eq. 4).

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
nu^2_j = sum_s sum_t W^2 / sum_s M_{j,s} (docs/guide/theory.rst, 'Wavelet variance'); ``concat=True`` concatenates
instead (the paper's way).
:class:`WVAccumulator` keeps the per-level sums, so adding a stop costs only its own samples.
Modules: :mod:`~imunoise.noise.wv.batch` (:func:`wavelet_variance`), :mod:`~imunoise.noise.wv.accumulator` (pooled
sums, :class:`WVAccumulator`), :mod:`~imunoise.noise.wv.covariance` (eta3 CIs and the covariance of nu^2),
:mod:`~imunoise.noise.wv.robust` (Huber M-scale), :mod:`~imunoise.noise.wv.kernels` (numba),
:mod:`~imunoise.noise.wv.result`
(:class:`WaveletVariance`). Streaming over chunks of one series: :mod:`imunoise.noise.wv_stream`. The modelling
stage of the data path IMU → detection → modelling → filter.
"""

from __future__ import annotations

from imunoise.noise.wv.accumulator import MIN_COEFFICIENTS, MIN_SAMPLES, WVAccumulator, wavelet_variance_from_sums
from imunoise.noise.wv.batch import wavelet_variance
from imunoise.noise.wv.covariance import COV_PRIOR_BATCHES
from imunoise.noise.wv.kernels import batch_size, level_pass  # noqa: F401 - level_pass: the kernel imunoise.noise.wv_stream shares
from imunoise.noise.wv.result import WaveletVariance, diagonal_weights, scale_runs
from imunoise.noise.wv.robust import HUBER_C, huber_efficiency, huber_scale

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
