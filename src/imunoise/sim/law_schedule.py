"""What a simulated drive's motion law injects, sample by sample: the input of a law-aware filter (the
``oracle_law`` method of issue 21 §2, the ceiling for every law).

Per IMU sample k and axis j (:data:`imunoise.imu.AXES`), from the law of :mod:`imunoise.sim.motion`:

* ``white_var_scale[k, j]`` = (m^w_{j,k})²: the white-noise variance (PSD) of the axis is σ²_WN·m², so a filter
  multiplies its white PSD by it;
* ``bias_var_scale[k, j]`` = (m^b_{j,k})²: the driving-noise variance of every bias process of the axis (RW γ²,
  AR1 σ²) is multiplied by it (T_c unchanged);
* ``moving[k]``: the moving Gauss–Markov (σ_j, τ_j: ``gm_sigma``, ``gm_tau_s``) evolves over the step into k
  (φ = e^{−Δt/τ}, q = σ²(1 − φ²)); when False it is frozen (Φ = 1, q = 0) — an augmented state per axis with
  σ_j > 0, P0 = σ_j²;
* ``departure_index``: the samples where the vehicle starts from a stop; at each, σ²_step,j (``step_var``) is
  added to the covariance of the axis' bias state;
* the warm-up b(t) = A(1 − e^{−(t − t_0)/τ}) is deterministic and a filter has no state for it: its closest
  random walk over the drive, q_j = A_j² (1 − e^{−T/τ})² / T [unit²/s] (the walk whose variance after the
  drive's length T equals the warm-up's squared total change), is ``warmup_rw_q`` — an approximation, said so.

The arrays are piecewise constant on stops and smooth in motion; :meth:`LawSchedule.change_points` gives the
samples where a filter that re-applies the schedule only when it changes must do so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imunoise.sim.law_terms import departures

__all__ = ["LawSchedule", "law_schedule", "warmup_random_walk"]


@dataclass(frozen=True)
class LawSchedule:
    """Per-sample variances a law injects (module docstring); SI units, axes gyro x, y, z, accel x, y, z."""

    t: np.ndarray  # (n,) s
    white_var_scale: np.ndarray  # (n, 6)
    bias_var_scale: np.ndarray  # (n, 6)
    moving: np.ndarray  # (n,) bool
    gm_sigma: np.ndarray  # (6,) rad/s or m/s²
    gm_tau_s: np.ndarray  # (6,) s
    departure_index: np.ndarray  # (k,) int
    step_var: np.ndarray  # (6,) unit²
    warmup_rw_q: np.ndarray  # (6,) unit²/s

    def change_points(self, rel: float = 0.05) -> np.ndarray:
        """Sample indices (0 included) where a multiplier has moved by more than ``rel`` (relative) since the
        last change point, or the moving flag flips, or a departure happens."""
        n = self.t.size
        out = [0]
        ref_w, ref_b, ref_m = self.white_var_scale[0], self.bias_var_scale[0], self.moving[0]
        dep = set(int(k) for k in self.departure_index)
        for k in range(1, n):
            w, b = self.white_var_scale[k], self.bias_var_scale[k]
            if (self.moving[k] != ref_m or k in dep or np.any(np.abs(w - ref_w) > rel * ref_w)
                    or np.any(np.abs(b - ref_b) > rel * ref_b)):
                out.append(k)
                ref_w, ref_b, ref_m = w, b, self.moving[k]
        return np.array(out, dtype=np.int64)


def warmup_random_walk(amplitude: np.ndarray, tau_s: float, duration_s: float) -> np.ndarray:
    """q = A² (1 − e^{−T/τ})² / T per axis [unit²/s]: the random walk closest to the warm-up over a drive of T."""
    a = np.asarray(amplitude, dtype=float)
    return a * a * (-math.expm1(-duration_s / tau_s)) ** 2 / duration_s


def law_schedule(law, t: np.ndarray, static_mask: np.ndarray, m_white: np.ndarray | None,
                 m_bias: np.ndarray | None) -> LawSchedule:
    """The schedule of ``law`` (a :class:`~imunoise.sim.motion.MotionNoise`) over a drive's samples ``t`` with
    its static mask and the multipliers it injected (None: all 1)."""
    n = len(t)
    ones = np.ones((n, 6))
    mw = ones if m_white is None else np.asarray(m_white, dtype=float)
    mb = ones if m_bias is None else np.asarray(m_bias, dtype=float)
    duration = float(t[-1] - t[0]) if n > 1 else 0.0
    q = (warmup_random_walk(np.array(law.warmup_amplitude), law.warmup_tau_s, duration) if duration > 0
         else np.zeros(6))
    return LawSchedule(
        t=np.asarray(t, dtype=float), white_var_scale=mw * mw, bias_var_scale=mb * mb,
        moving=~np.asarray(static_mask, dtype=bool), gm_sigma=np.array(law.moving_gm_sigma),
        gm_tau_s=np.array(law.moving_gm_tau_s), departure_index=departures(static_mask),
        step_var=np.array(law.departure_step) ** 2, warmup_rw_q=q)
