"""GNSS regimes of the experiments (issue "Evidence with power" §1): ``rtk`` and ``noise:H,V[,RATE[,TAU]]``.

``rtk`` aids the filter with the fixes as recorded (centimetre-level RTK on the shared drive). ``noise:H,V``
degrades them to a meter-level receiver, the paper's regime (its Table 5 RMS 1.3–1.7 m): the fixes are
thinned to ``RATE`` Hz (default: as recorded), and north/east errors of σ ``H`` m and a down error of σ ``V``
m are added, white (``TAU`` absent or 0) or first-order Gauss–Markov with correlation time ``TAU`` s
(x_{k+1} = φ x_k + √(1 − φ²) σ w_k, φ = exp(−Δt/TAU), started stationary), each axis independent. The
fixes' σ columns become √(σ_recorded² + (H, H, V)²): the added noise is independent of what the fixes
already carry, so the filter is told the truth about the noise. On the real drive the recorded RTK σ are
centimetres (σ ≈ H, V); on a simulated drive the simulated fixes already carry 1 / 1 / 2 m, so
``noise:1.5,3`` gives fixes of σ 1.80 / 1.80 / 3.61 m, and says so. The reference is
not changed: on the real drive it is the RTK solution, an independent truth for the degraded aiding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imunoise.errors import ModelError
from imunoise.nav.earth import radii

__all__ = ["GnssRegime", "parse_gnss"]


@dataclass(frozen=True)
class GnssRegime:
    """A GNSS regime: ``kind`` "rtk" or "noise"; σ_H, σ_V (m), ``rate_hz`` (None = as recorded),
    ``tau_s`` (0 = white)."""

    kind: str = "rtk"
    sigma_h: float = 0.0
    sigma_v: float = 0.0
    rate_hz: float | None = None
    tau_s: float = 0.0

    @property
    def label(self) -> str:
        if self.kind == "rtk":
            return "rtk"
        parts = [f"{self.sigma_h:g}", f"{self.sigma_v:g}"]
        if self.rate_hz is not None or self.tau_s:
            parts.append("" if self.rate_hz is None else f"{self.rate_hz:g}")
        if self.tau_s:
            parts.append(f"{self.tau_s:g}")
        return "noise:" + ",".join(parts)

    @property
    def random(self) -> bool:
        return self.kind == "noise"

    def apply(self, gnss, seed: int = 0):
        """The degraded fixes (a new GnssData): thinned, noise added, σ = √(recorded σ² + added σ²) written.
        ``rtk`` returns ``gnss``."""
        if self.kind == "rtk":
            return gnss
        t = np.asarray(gnss.t, dtype=float)
        keep = np.ones(t.size, dtype=bool)
        if self.rate_hz is not None and t.size:
            # the first fix of every 1/RATE bin (4 Hz → 1 Hz keeps every fourth)
            b = np.floor((t - t[0]) * self.rate_hz + 1e-6).astype(np.int64)
            keep = np.concatenate([[True], np.diff(b) > 0])
        t = t[keep]
        llh = np.asarray(gnss.llh, dtype=float)[keep].copy()
        rng = np.random.default_rng(seed)
        sig = np.array([self.sigma_h, self.sigma_h, self.sigma_v])
        w = rng.standard_normal((t.size, 3))
        if self.tau_s > 0 and t.size:
            e = np.empty_like(w)
            e[0] = sig * w[0]
            phi = np.exp(-np.diff(t) / self.tau_s)
            for k in range(1, t.size):
                e[k] = phi[k - 1] * e[k - 1] + math.sqrt(1.0 - phi[k - 1] ** 2) * sig * w[k]
        else:
            e = sig * w
        rm, rn = radii(llh[:, 0])
        llh[:, 0] += e[:, 0] / (rm + llh[:, 2])
        llh[:, 1] += e[:, 1] / ((rn + llh[:, 2]) * np.cos(llh[:, 0]))
        llh[:, 2] -= e[:, 2]
        base = np.asarray(gnss.sigma_ned, dtype=float)[keep]
        return type(gnss)(t=t, llh=llh, sigma_ned=np.sqrt(base * base + sig * sig))


def parse_gnss(text: str | None) -> GnssRegime:
    """``"rtk"`` (or None) or ``"noise:H,V[,RATE[,TAU]]"`` (m, m, Hz, s) → :class:`GnssRegime`."""
    if text is None or text.strip().lower() == "rtk":
        return GnssRegime()
    s = text.strip()
    if not s.lower().startswith("noise:"):
        raise ModelError(f"--gnss must be 'rtk' or 'noise:H,V[,RATE[,TAU]]' (m, m, Hz, s), got {text!r}")
    parts = [p.strip() for p in s[6:].split(",")]
    try:
        vals = [float(p) if p else None for p in parts]
    except ValueError as exc:
        raise ModelError(f"--gnss {text!r}: H, V, RATE, TAU must be numbers (m, m, Hz, s)") from exc
    if not 2 <= len(vals) <= 4 or vals[0] is None or vals[1] is None:
        raise ModelError(f"--gnss {text!r}: give noise:H,V with optional RATE and TAU, e.g. noise:1.5,3,1")
    h, v = vals[0], vals[1]
    rate = vals[2] if len(vals) > 2 else None
    tau = (vals[3] or 0.0) if len(vals) > 3 else 0.0
    if not (h >= 0 and v >= 0 and math.isfinite(h) and math.isfinite(v)):
        raise ModelError(f"--gnss {text!r}: σ_H and σ_V must be finite and ≥ 0 m")
    if rate is not None and not (rate > 0 and math.isfinite(rate)):
        raise ModelError(f"--gnss {text!r}: RATE must be > 0 Hz")
    if not (tau >= 0 and math.isfinite(tau)):
        raise ModelError(f"--gnss {text!r}: TAU must be ≥ 0 s (0 = white noise)")
    return GnssRegime("noise", float(h), float(v), rate, float(tau))
