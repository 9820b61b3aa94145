"""The gate on what is exported: the (N, K) pair a file writes against the **data's** Allan variance over the
averaging times the consumer integrates (from its update interval, default :data:`MIN_PERIODS` IMU periods, to
the horizon).

The pair's AV is the exact discrete WV of WN(σ² = N²f) + RW(γ² = K²/f) (AV = 2ν² at T = τ/2f,
:func:`imunoise.noise.fitting.quality.pair_model`). On every level in range with at least
:data:`imunoise.noise.fitting.quality.MIN_DOF` equivalent degrees of freedom the factor between the pair's AV and the
data's is read, and reported with its side (pair above the data = conservative, below = overconfident) and the
inflation of (N, K) that bounds the data over the range. The export is **refused** where no (N, K) pair at
all comes within :data:`TOLERANCE` of the data's AV over the range (:func:`best_pair`): the data hold something
a white-noise + random-walk consumer cannot carry (a vibration, motion leaked into the stops). Where such a pair
exists but the exported one misses by more, the export goes ahead with the miss, the inflation and the closest
pair written into the file (a bias-instability plateau, which the fitted model carries and the pair cannot).

A refusal names its cause (a narrowband line kept in the data, or the range of T where the data's AV leaves the
pair) and offers the data's own Allan reading (N = AD(1 s)·√1 s, K = min AD(T)·√(3/T)) as the pair ``--force``
writes instead (:func:`data_reading`). How :data:`TOLERANCE` was chosen (false refusals on in-family simulation,
power on vibration and departure leaks) is in docs/guide/exports.rst.

The in-use pair (:mod:`imunoise.export.in_use`, a model with an in-motion part) is **not** gated against the data:
the data of the gate are the stops, and the in-use pair describes the drive, where the noise is meant to exceed
the stops' (a factor > 1 reads "above the data" at every T). The gate checks the static pair, as for a model
without the part, and the in-use pair carries its own evidence: each factor must be positive and finite and lie
inside its 95 % interval (:meth:`imunoise.export.in_use.Factor.read` refuses the file otherwise), the interval is
written beside every key, and an interval that holds 1 is said to show no difference while moving.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.noise.wv import WaveletVariance

__all__ = ["MIN_PERIODS", "TOLERANCE", "PairGate", "best_pair", "data_reading", "pair_gate"]

TOLERANCE = 2.0
"""Factor in Allan variance between the exported pair and the data beyond which a level outside the data's band
refuses the export (module docstring; measured in docs/evidence/export_on_real_imus.md)."""
MIN_PERIODS = 4
"""Default shortest averaging time of the gate: this many IMU periods (a filter's update interval is rarely
shorter; set the consumer's with ``--update-interval``)."""


@dataclass(frozen=True)
class PairGate:
    """The exported pair against the data (module docstring)."""

    N: float
    K: float
    tau_range_s: tuple[float, float]
    worst_ratio: float
    worst_at_s: float
    above: bool
    inflation: float
    refused: bool
    cause: str
    reading: tuple[float, float]
    best: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def text(self) -> str:
        side = "above the data (conservative)" if self.above else "below the data (overconfident)"
        s = (f"exported pair vs data AV over T = {self.tau_range_s[0]:.3g}–{self.tau_range_s[1]:.3g} s: worst "
             f"{self.worst_ratio:.3g}× {side} at T = {self.worst_at_s:.3g} s; inflating N and K by "
             f"{self.inflation:.3g}× bounds the data")
        if self.worst_ratio > TOLERANCE and not self.refused:
            s += (f"; the pair closest to the data (within {self.best[2]:.3g}×): N = {self.best[0]:.4g}, "
                  f"K = {self.best[1]:.4g}")
        if self.refused:
            s += (f"; {self.cause}; the data's own reading (what --force writes): N = {self.reading[0]:.4g}, "
                  f"K = {self.reading[1]:.4g}")
        return s

    def to_dict(self) -> dict[str, Any]:
        return {"N": self.N, "K": self.K, "tau_range_s": list(self.tau_range_s), "worst_ratio": self.worst_ratio,
                "worst_at_s": self.worst_at_s, "pair_above_data": self.above, "inflation": self.inflation,
                "refused": self.refused, "cause": self.cause, "tolerance": TOLERANCE,
                "data_reading": {"N": self.reading[0], "K": self.reading[1]},
                "best_pair": {"N": self.best[0], "K": self.best[1], "worst_ratio": self.best[2]}}


def _levels(wv: WaveletVariance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from imunoise.noise.fitting.quality import MIN_DOF

    T = np.asarray(wv.scales, dtype=float) / (2.0 * float(wv.freq))
    eta = np.asarray(wv.n_coefficients, dtype=float) / np.asarray(wv.scales, dtype=float)
    return T, 2.0 * np.asarray(wv.variance, dtype=float), eta >= MIN_DOF


def data_reading(wv: WaveletVariance) -> tuple[float, float]:
    """The data's Allan reading: N = AD(T)·√T at the level nearest T = 1 s, K = min AD(T)·√(3/T) over the
    levels with enough degrees of freedom (the bound a random walk cannot exceed)."""
    T, av, ok = _levels(wv)
    ok = ok if ok.any() else np.ones_like(ok)
    j = int(np.argmin(np.where(ok, np.abs(np.log(T)), np.inf)))
    return float(math.sqrt(av[j] * T[j])), float(np.min(np.sqrt(av[ok] * 3.0 / T[ok])))


def pair_gate(wv: WaveletVariance, N: float, K: float, *, horizon_s: float | None = None,
              update_interval_s: float | None = None, lines: Sequence[dict[str, Any]] = ()) -> PairGate:
    """The gate of one axis's exported pair (module docstring).

    Parameters
    ----------
    wv : WaveletVariance
        The data's WV (with its band).
    N, K : float
        The pair as exported [u/√Hz], [u/s/√Hz].
    horizon_s : float, optional
        Longest averaging time [s] (default: the data's longest level).
    update_interval_s : float, optional
        The consumer's update interval [s] (default :data:`MIN_PERIODS` IMU periods).
    lines : sequence of dict
        Narrowband lines kept in the data (:meth:`imunoise.lines.Line.to_dict`), for the cause.
    """
    from imunoise.noise.fitting.quality import pair_model

    f = float(wv.freq)
    T, av, ok = _levels(wv)
    lo = MIN_PERIODS / f if update_interval_s is None else float(update_interval_s)
    hi = float(T[-1]) if horizon_s is None else float(horizon_s)
    sel = (T >= lo * (1 - 1e-9)) & (T <= hi * (1 + 1e-9))
    if not sel.any():
        sel = np.zeros_like(sel)
        sel[int(np.argmin(np.abs(np.log(T / lo))))] = True
    use = sel & ok if (sel & ok).any() else sel
    # the pair's AV is linear in N² and K²: one white and one random-walk column
    a_wn = 2.0 * pair_model(1.0, 0.0, f).wv(wv.scales)
    a_rw = 2.0 * pair_model(1.0, 1.0, f).wv(wv.scales) - a_wn
    pav = N**2 * a_wn + K**2 * a_rw
    r = pav / av
    factor = np.maximum(r, 1.0 / r)
    j = int(np.argmax(np.where(use, factor, -np.inf)))
    infl = float(math.sqrt(max(1.0, float(np.max(np.where(use, 1.0 / r, 0.0))))))
    bN, bK, best = best_pair(av[use], a_wn[use], a_rw[use], data_reading(wv))
    cause = ""
    if best > TOLERANCE:
        bav = bN**2 * a_wn + bK**2 * a_rw
        bad = use & (np.maximum(bav / av, av / bav) > TOLERANCE)
        tb = T[bad] if bad.any() else T[[j]]
        where = f"T < {tb.max():.3g} s" if tb.min() <= T[use][0] * 1.01 else (
            f"T = {tb.min():.3g}–{tb.max():.3g} s" if tb.size > 1 else f"T = {tb[0]:.3g} s")
        if lines:
            ln = max(lines, key=lambda d: d["share"])
            cause = (f"vibration at {ln['freq_hz']:.3g} Hz ({100 * ln['share']:.2g} % of the variance) dominates "
                     f"{where}; no (N, K) pair comes within {TOLERANCE:g}× of the data (best {best:.3g}×)")
        else:
            cause = (f"no (N, K) pair comes within {TOLERANCE:g}× of the data's AV at {where} (best {best:.3g}×): "
                     "a process the pair cannot carry (bias instability, or motion in the record)")
    return PairGate(float(N), float(K), (float(T[sel][0]), float(T[sel][-1])), float(factor[j]), float(T[j]),
                    bool(r[j] > 1.0), infl, best > TOLERANCE, cause, data_reading(wv), (bN, bK, best))


def best_pair(av: np.ndarray, a_wn: np.ndarray, a_rw: np.ndarray, start: tuple[float, float]
              ) -> tuple[float, float, float]:
    """The (N, K) whose AV N²·a_wn + K²·a_rw comes closest to ``av`` in the worst factor over the levels (a
    log-spaced grid around the data's reading ``start``, refined once): (N, K, worst factor)."""
    n0, k0 = start

    def search(nc: float, kc: float, span_n: float, span_k: float) -> tuple[float, float, float]:
        ns = nc * np.exp(np.linspace(-span_n, span_n, 61))
        ks = kc * np.exp(np.linspace(-span_k, span_k, 81))
        m = (ns[:, None, None] ** 2 * a_wn + ks[None, :, None] ** 2 * a_rw) / av
        worst = np.max(np.abs(np.log(m)), axis=2)
        i, k = np.unravel_index(int(np.argmin(worst)), worst.shape)
        return float(ns[i]), float(ks[k]), float(np.exp(worst[i, k]))

    n1, k1, _ = search(n0, k0, math.log(10.0), math.log(1e4))
    return search(n1, k1, math.log(10.0) / 20, math.log(1e4) / 20)
