"""How long to record: the 95 % interval of the exported N and K and the horizon of a fitted axis as functions of
the record length L, and the length a target precision needs (docs/guide/theory.rst, 'Record length').

N and K are the pair the exports write from the model (:func:`imunoise.noise.equivalent_noise.equivalent_noise`
over Δt .. the fit's horizon; for a WN + RW model the WN and RW terms themselves). Their intervals are the delta
method on a log scale, as the fit's own (:meth:`imunoise.noise.fitting.result.GMWMFit.confidence_intervals`),
with the parameter covariance the fit would have at length L
(:func:`imunoise.noise.fitting.length_covariance.predicted_cov`).
The gradient of (log N, log K) is taken once per axis by central differences through the mapping; the cap at the
data's Allan bound (its rule 4) is a property of this record's data and is left out. A quantity the model does
not identify (no random walk, or a slot only bounded from above) has no interval: K is then a bound, which a
longer record does not turn into a value by itself.

The precision quoted is the half-width ±100·(hi − lo)/(2·value) %. Coverage at the record's own length and the
width a short pilot predicts for a longer record are measured in docs/evidence/record_length.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import norm

from imunoise.errors import ImunoiseError, ModelError
from imunoise.noise.equivalent_noise import default_horizon_s, equivalent_noise
from imunoise.noise.fitting.length_covariance import horizon_at, length_for_horizon, predicted_cov, record_length_s
from imunoise.noise.fitting.params import kind_codes, theta_to_u, u_to_theta
from imunoise.noise.wv.accumulator import MIN_COEFFICIENTS

__all__ = ["LengthPrediction", "LengthPredictor", "half_width_pct", "length_for_horizon", "record_length_s"]

NOT_IDENTIFIED = 1e-9  # as imunoise.export.noise: a slot below this fraction of its cap sits at its bound 0
MAX_FACTOR = 1e4  # the inversion searches lengths up to this factor beyond the record


def half_width_pct(value: float, ci: tuple[float, float]) -> float:
    """±100·(hi − lo)/(2·value) %: half the interval's width relative to the value (NaN when not available)."""
    lo, hi = ci
    if not (math.isfinite(lo) and math.isfinite(hi) and value > 0):
        return math.nan
    return 100.0 * (hi - lo) / (2.0 * value)


@dataclass(frozen=True)
class LengthPrediction:
    """What a record of ``length_s`` seconds would give: N and K with their intervals (low, high) [NaN where the
    model does not identify the slot] and the horizon [s of averaging time]."""

    length_s: float
    horizon_s: float
    N: float
    N_ci: tuple[float, float]
    K: float
    K_ci: tuple[float, float]

    def pct(self, which: str) -> float:
        """Half-width of N's or K's interval in % of the value (NaN when not available)."""
        return half_width_pct(getattr(self, which), getattr(self, which + "_ci"))


def _pair(model: Any, freq: float, horizon_s: float) -> tuple[float, float]:
    """The model's exported (N, K) without the data's cap; NaN for a slot the model does not identify."""
    eq = equivalent_noise(model, freq, horizon_s=horizon_s)
    n = eq.N if eq.sigma2 > NOT_IDENTIFIED * max(eq.sigma2_cap, 1e-300) else math.nan
    k = eq.K if eq.gamma2 > NOT_IDENTIFIED * max(eq.gamma2_cap, 1e-300) else math.nan
    return n, k


class LengthPredictor:
    """The intervals of one fitted axis at any record length (module docstring).

    Parameters
    ----------
    fit
        A :class:`~imunoise.noise.fitting.result.GMWMFit` with its parameter covariance.
    pooled
        The fit is of pooled stops whose total static time is ``record_s`` (required then): a longer calibration
        is more stops of the same kind.
    record_s
        The length the fit came from [s] (default: the single record its WV was computed on).
    level
        Coverage of the intervals.
    law
        Covariance of the WV at length L (:data:`imunoise.noise.fitting.length_covariance.LAWS`).
    """

    def __init__(self, fit: Any, *, pooled: bool = False, record_s: float | None = None, level: float = 0.95,
                 law: str = "model") -> None:
        if pooled and record_s is None:
            raise ModelError("a pooled fit needs the total static time it came from (record_s)")
        if fit.param_cov_u is None or np.any(np.isnan(fit.param_cov_u)):
            raise ModelError(f"the fit of {fit.model} has no parameter covariance: no interval to predict")
        self.fit, self.pooled, self.law = fit, pooled, law
        self._wv_cov: dict = {}  # the WV covariance integrals per set of levels (model_wv_cov)
        self.record_s = record_length_s(fit) if record_s is None else float(record_s)
        self.z = float(norm.ppf(0.5 + level / 2))
        f = float(fit.freq)
        h = float(default_horizon_s(fit))
        self.values = dict(zip("NK", _pair(fit.model, f, h)))
        kinds = kind_codes(fit.model)
        u0 = theta_to_u(fit.model.vector, kinds, 1.0)
        free = ~np.isfinite(np.diag(fit.param_cov_u))
        self.grads: dict[str, np.ndarray | None] = {}
        g = {k: np.zeros(u0.size) for k in "NK"}
        for i in range(u0.size):  # the step of GMWMFit.confidence_intervals
            step = 1e-6 * max(1.0, abs(u0[i]))
            up, dn = u0.copy(), u0.copy()
            up[i] += step
            dn[i] -= step
            try:
                pu = _pair(fit.model.with_vector(u_to_theta(up, kinds, 1.0)), f, h)
                pd = _pair(fit.model.with_vector(u_to_theta(dn, kinds, 1.0)), f, h)
            except ImunoiseError:
                pu = pd = (math.nan, math.nan)
            for k, a, b in zip("NK", pu, pd):
                g[k][i] = (math.log(a) - math.log(b)) / (2 * step) if a > 0 and b > 0 else math.nan
        for k in "NK":
            ok = math.isfinite(self.values[k]) and np.all(np.isfinite(g[k])) and not np.any(np.abs(g[k][free]) > 1e-9)
            self.grads[k] = np.where(free, 0.0, g[k]) if ok else None

    def predict(self, length_s: float) -> LengthPrediction:
        """N, K with their intervals and the horizon a record (or static time) of ``length_s`` s would give."""
        cov = predicted_cov(self.fit, length_s, pooled=self.pooled, record_s=self.record_s, law=self.law,
                            cache=self._wv_cov)
        free = np.isinf(np.diag(cov))
        cov = np.where(np.isinf(cov), 0.0, cov)
        out = {}
        for k in "NK":
            v, g = self.values[k], self.grads[k]
            if g is None or np.any(np.abs(g[free]) > 1e-9):  # not identified (at this length)
                out[k] = (v, (math.nan, math.nan))
                continue
            se = math.sqrt(max(float(g @ cov @ g), 0.0))
            w = min(self.z * se, 700.0)  # a level or two of data: a width that saturates instead of overflowing
            out[k] = (v, (v * math.exp(-w), v * math.exp(w)))
        return LengthPrediction(float(length_s), horizon_at(self.fit, length_s, self.pooled, self.record_s),
                                out["N"][0], out["N"][1], out["K"][0], out["K"][1])

    def length_for(self, which: str, target_pct: float) -> float:
        """The length [s] at which ``which`` ("N" or "K") has a ±``target_pct`` % interval (bisection on log L
        between one level's worth of data, or the record / :data:`MAX_FACTOR` for pooled stops, and
        :data:`MAX_FACTOR` times the record); that shortest length when it already reaches it, inf when even the
        longest does not, NaN when the quantity has no interval."""
        if which not in ("N", "K"):
            raise ModelError(f"which must be 'N' or 'K', got {which!r}")
        if not (math.isfinite(target_pct) and target_pct > 0):
            raise ModelError(f"--target must be a positive percentage, got {target_pct}")
        rec = self.record_s

        def pct(length: float) -> float:
            return self.predict(length).pct(which)

        here = pct(rec)
        if not math.isfinite(here):
            return math.nan
        if here > target_pct:
            lo, hi = rec, rec * MAX_FACTOR
            if not pct(hi) <= target_pct:
                return math.inf
        else:
            # one record: level 1 alone (n − 1 ≥ MIN_COEFFICIENTS); pooled stops: the search's own floor
            lo = rec / MAX_FACTOR if self.pooled else (MIN_COEFFICIENTS + 1.0) / float(self.fit.freq)
            hi = rec
            if pct(lo) <= target_pct:  # NaN (not identified that short) is not
                return lo
        for _ in range(60):  # the half-width falls with L (monotone, see the tests)
            mid = math.sqrt(lo * hi)
            if not pct(mid) <= target_pct:  # NaN: too short to identify it
                lo = mid
            else:
                hi = mid
            if hi / lo < 1.0 + 1e-6:
                break
        return hi
