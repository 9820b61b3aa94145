"""Innovation-based adaptive process noise: the established baseline for learning noise in motion.

Covariance matching (Mehra 1972; Sage & Husa 1969, in the forgetting-factor form of e.g. Yang & Gao 2006):
if the filter's model is right, the GNSS position innovation ν has covariance S = HPHᵀ + R, so the
normalised innovation squared NIS = νᵀS⁻¹ν has mean m = 3 (3 dof). A mean above 3 says the filter is too
confident; with the measurement noise taken as given, the usual lever is the process noise.

Here the lever is the bias-state process noise: every ``every_s`` seconds the random-walk γ² and the
Gauss–Markov (AR1) driving variance σ² of each axis are multiplied by one factor α relative to the
nominal models (white noise untouched), and swapped into the filter with the states carried over
(:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.swap_model` with ``preserve=True``; same structure, so every
state is kept). α follows the exponentially weighted NIS mean m̄ (forgetting factor ``forget`` per fix)
in integral form, α ← clip(α·(m̄/3)^gain, lo, hi): it keeps moving while the innovations disagree with
S, so it seeks the α with m̄ = 3 instead of a fixed proportional guess. One α for both sensor groups:
position innovations alone do not separate gyro from accelerometer errors.

Each NIS is capped at ``nis_cap`` (χ²(3) at 99.99 %, the filter's gate) so one outlier fix does not pump α.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.model import Model

__all__ = ["AdaptiveConfig", "AdaptiveNoise", "scale_bias_noise"]


@dataclass(frozen=True)
class AdaptiveConfig:
    """Settings of :class:`AdaptiveNoise` (module docstring).

    ``forget``: weight of the past per GNSS fix in the NIS mean (0.98: ~50 fixes); ``gain``: exponent of
    each integral step; ``lo``/``hi``: bounds of α (× nominal); ``every_s``: at most one swap per this many
    seconds of filter time; ``min_ratio``: swap only when α moved by more than this ratio since the last
    swap; ``skip``: fixes ignored at the start (the alignment transient: on a simulated drive with a
    consistent model the NIS mean of the first minute is ~5, which would pump α with nothing wrong in Q);
    ``warmup``: fixes in the mean before the first step; ``nis_cap``: cap of each NIS."""

    forget: float = 0.98
    gain: float = 0.5
    lo: float = 0.25
    hi: float = 16.0
    every_s: float = 10.0
    min_ratio: float = 1.1
    skip: int = 60
    warmup: int = 20
    nis_cap: float = 21.1

    def __post_init__(self) -> None:
        if not (0.0 < self.forget < 1.0):
            raise ModelError(f"AdaptiveConfig.forget must be in (0, 1), got {self.forget}")
        if not (0.0 < self.lo <= 1.0 <= self.hi):
            raise ModelError(f"AdaptiveConfig needs 0 < lo ≤ 1 ≤ hi, got lo={self.lo}, hi={self.hi}")
        if not (self.gain > 0 and self.every_s >= 0 and self.min_ratio >= 1 and self.nis_cap > 0):
            raise ModelError("AdaptiveConfig: gain and nis_cap must be > 0, every_s ≥ 0, min_ratio ≥ 1")


def scale_bias_noise(model: Model, factor: float) -> Model:
    """``model`` with the driving noise of its bias states (RW γ², AR1 σ²) times ``factor``; φ, WN, QN and
    DR unchanged (Q of a bias state is linear in its driving variance): :meth:`Model.scaled` with
    ``bias=factor``."""
    return model.scaled(bias=factor)


class AdaptiveNoise:
    """Online covariance matching of the bias process noise of a :class:`LooselyCoupledEKF` (module
    docstring). Call :meth:`observe` after anything that may have applied a GNSS fix; it reads the EKF's
    ``last_innovation`` and, when due, calls its ``swap_model``.

    Parameters
    ----------
    base_models : sequence
        The nominal six models the factor scales, each carrying its rate (pairs: deprecated,
        :func:`~imunoise.nav.defaults.normalize_axis_models`).
    config : AdaptiveConfig, optional
        Settings.
    """

    def __init__(self, base_models, config: AdaptiveConfig | None = None):
        self.config = config or AdaptiveConfig()
        self.base = list(base_models)
        self.factor = 1.0
        self.applied = 1.0
        self.nis_mean = float("nan")
        self.n = 0
        self.n_fix = 0
        self._sum = 0.0
        self._weight = 0.0
        self._t_seen = -math.inf
        self._t_step = -math.inf
        self.history: list[tuple[float, float, float]] = []  # (t, α, NIS mean) at each step

    def models(self, factor: float | None = None) -> list:
        """The nominal models with the bias noise scaled by ``factor`` (default: the applied α)."""
        f = self.applied if factor is None else factor
        return [(scale_bias_noise(m[0], f), m[1]) if isinstance(m, tuple) else scale_bias_noise(m, f)
                for m in self.base]

    def add_nis(self, nis: float) -> None:
        """One NIS into the exponentially weighted mean (normalised by the weight sum, so early means are
        not biased toward 0)."""
        b = self.config.forget
        self._sum = b * self._sum + min(float(nis), self.config.nis_cap)
        self._weight = b * self._weight + 1.0
        self.nis_mean = self._sum / self._weight
        self.n += 1

    def observe(self, ekf) -> bool:
        """Take the EKF's last GNSS innovation if new; step α when due; swap when it moved. Returns whether
        the filter's models were replaced."""
        last = ekf.last_innovation
        if last is None or last[0] == self._t_seen:
            return False
        t, nu, S, _ = last
        self._t_seen = t
        self.n_fix += 1
        if self.n_fix <= self.config.skip:
            return False
        self.add_nis(float(nu @ np.linalg.solve(S, nu)))
        c = self.config
        if self.n < c.warmup or t - self._t_step < c.every_s:
            return False
        self._t_step = t
        self.factor = float(np.clip(self.factor * (self.nis_mean / 3.0) ** c.gain, c.lo, c.hi))
        self.history.append((t, self.factor, self.nis_mean))
        r = self.factor / self.applied
        if max(r, 1.0 / r) <= c.min_ratio:
            return False
        self.applied = self.factor
        ekf.swap_model(self.models(), preserve=True)
        return True
