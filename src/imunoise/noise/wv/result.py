"""The wavelet variance result type (docs/guide/theory.rst, 'Wavelet variance') and helpers over its levels."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imunoise.errors import DataError

__all__ = ["WaveletVariance", "diagonal_weights", "scale_runs"]


@dataclass(frozen=True)
class WaveletVariance:
    """Haar wavelet variance per level (docs/guide/theory.rst, 'Wavelet variance'). Arrays are per kept level j
    (ascending).

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
        """(averaging time m/freq in s with m = 2**(j-1), overlapping Allan variance 2*nu^2_j)
        (docs/guide/theory.rst, 'Conventions')."""
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
