"""The detector's statistics as small pure pieces: the Eq. 9 moving standard deviation, the adaptive
threshold of Eq. 10 (reference implementation), the angular-rate gate, λ_0 learned from a known stop, and the
kernel state that drives :func:`imunoise.detect.kernels.detector_kernel` (docs/guide/theory.rst, 'Static detection',
paper §2.3)."""

from __future__ import annotations

import numpy as np

from imunoise.detect.config import DetectorConfig
from imunoise.detect.kernels import N_SF, N_SI, detector_kernel, reset_state
from imunoise.errors import DataError, ModelError

__all__ = ["KernelState", "adaptive_threshold", "angular_rate_gate", "learn_lambda0", "moving_std"]


class KernelState:
    """Mutable state of :func:`imunoise.detect.kernels.detector_kernel` (ring buffer + scalars)."""

    def __init__(self, config: DetectorConfig, rate_hz: float):
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            rate = float("nan")
        if not (np.isfinite(rate) and rate > 0):
            raise DataError(f"rate_hz must be the positive nominal sampling rate in Hz (e.g. 100.0), got {rate_hz!r}")
        self.config = config
        self.max_gap = float(config.max_gap_samples) / rate
        self.buf = np.zeros((config.window, 2))
        self.sf = np.zeros(N_SF)
        self.si = np.zeros(N_SI, dtype=np.int64)
        reset_state(self.sf, self.si, float(config.lambda0))

    def run(self, t, accel, gyro, T, lam, st, gate) -> None:
        """Advance over ``t`` (m,), ``accel``/``gyro`` (m, 3) C-contiguous; outputs written in place."""
        c = self.config
        detector_kernel(t, accel, gyro, c.window, float(c.lambda0), float(c.gate_rate), bool(c.adaptive),
                        self.max_gap, self.buf, self.sf, self.si, T, lam, st, gate)


# --------------------------------------------------------------------------------------------------
# small pure pieces (public for tests and for others)


def moving_std(x: np.ndarray, window: int = 100) -> np.ndarray:
    """Trailing moving standard deviation (ddof = 1) over ``window`` samples, paper Eq. (9).

    ``x`` (n,) or (n, m); the first ``window − 1`` outputs are NaN. O(n) via the detector kernel.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim not in (1, 2):
        raise DataError(f"moving_std: x must be (n,) or (n, m) samples, got shape {x.shape}")
    one = x.ndim == 1
    x2 = x[:, None] if one else x
    n, m = x2.shape
    out = np.empty((n, m))
    cfg = DetectorConfig(window=window, lambda0=1.0, adaptive=False)
    t = np.arange(n, dtype=float)
    gyro = np.zeros((n, 3))
    lam, st, gate = np.empty(n), np.empty(n, dtype=np.bool_), np.empty(n, dtype=np.bool_)
    for j in range(0, m, 2):
        state = KernelState(cfg, 1.0)
        acc = np.zeros((n, 3))
        acc[:, 0] = x2[:, j]
        acc[:, 1] = x2[:, j + 1] if j + 1 < m else x2[:, j]
        T = np.empty((n, 2))
        state.run(t, acc, gyro, T, lam, st, gate)
        out[:, j] = T[:, 0]
        if j + 1 < m:
            out[:, j + 1] = T[:, 1]
    return out[:, 0] if one else out


def adaptive_threshold(statistic: np.ndarray, lambda0: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Threshold λ_i and static decision of docs/guide/theory.rst, 'Static detection' (reading of paper Eq. 10) for a
    given statistic.

    ``statistic`` (n, 2) (or (n,) for one axis, treated as both). Returns (λ (n,), static (n,) bool).
    A NaN statistic is "not static" and resets λ to λ_0. Pure Python reference implementation, used
    by the tests to check the kernel; O(n).
    """
    T = np.asarray(statistic, dtype=float)
    if T.ndim == 1:
        T = np.column_stack([T, T])
    n = T.shape[0]
    lam = np.empty(n)
    st = np.zeros(n, dtype=bool)
    k, prev_static, prev_T, prev_lam = 0, False, None, lambda0
    for i in range(n):
        if not np.all(np.isfinite(T[i])):
            lam[i], st[i] = lambda0, False
            k, prev_static, prev_T, prev_lam = 0, False, None, lambda0
            continue
        if prev_T is not None and prev_static:
            jump = max(abs(T[i, 0] - prev_T[0]), abs(T[i, 1] - prev_T[1]))
            li = min(max((k * prev_lam + 2.0 * lambda0 - jump) / (k + 1), 0.5 * lambda0), 2.0 * lambda0)
        else:
            li = lambda0
        s = bool(T[i, 0] < li and T[i, 1] < li)
        lam[i], st[i] = li, s
        k = k + 1 if s else 0
        prev_static, prev_T, prev_lam = s, T[i], li
    return lam, st


def angular_rate_gate(gyro: np.ndarray, gate_rate: float = float(np.deg2rad(30.0))) -> np.ndarray:
    """Gate open where ‖ω‖ = ‖gyro‖ > ``gate_rate`` [rad/s] (docs/guide/theory.rst, 'Static detection', paper §2.3; NaN
    → open)."""
    w = np.linalg.norm(np.atleast_2d(np.asarray(gyro, dtype=float)), axis=1)
    return ~(w <= gate_rate)


def learn_lambda0(
    accel_xy_static: np.ndarray,
    window: int = 100,
    quantile: float = 0.5,
    factor: float = 2.0,
) -> float:
    """Learn λ_0 [m/s²] for one sensor from accel samples recorded at a known stop
    (docs/guide/theory.rst, 'Static detection').

    Rule: λ_0 = ``factor`` × the ``quantile`` of the Eq. (9) statistic T (moving std over ``window``
    samples, accel x and y pooled) on the static samples; by default twice the median. At rest T
    scatters around the noise (plus idle-vibration) σ with a relative spread ≈ 1/√(2(N−1)) (7 % at
    N = 100), so λ_0 ≈ 2σ: a stop is entered when T < 2σ and, with the adaptive threshold, kept while
    T < up to 4σ. The median, not a high quantile, because a "known stop" often holds a few
    disturbances (a door, a passenger moving: on drive_0708 T reaches 6σ for a few seconds within the
    first 30 s), and the median ignores them as long as they cover less than half of the windows.
    ``accel_xy_static`` (n, ≥2), columns x, y first (m/s², body frame); needs at least 2·window samples
    so that the quantile rests on ≥ window + 1 statistics.
    """
    a = np.asarray(accel_xy_static, dtype=float)
    if a.ndim != 2 or a.shape[1] < 2:
        raise DataError(f"learn_lambda0: accel must be (n, 2) or (n, 3) [m/s²], got shape {a.shape}")
    if a.shape[0] < 2 * window:
        raise DataError(
            f"learn_lambda0: {a.shape[0]} static samples, need ≥ 2·window = {2 * window}; "
            "give a longer known stop (e.g. --learn-from with more seconds)"
        )
    if not np.all(np.isfinite(a[:, :2])):
        raise DataError(
            "learn_lambda0: the static accel contains NaN/Inf; choose a known stop without gaps or fill them"
        )
    if not (0.0 < quantile <= 1.0) or not (factor > 0 and np.isfinite(factor)):
        raise ModelError(
            f"learn_lambda0: need 0 < quantile ≤ 1 and a finite factor > 0 (defaults 0.5 and 2), got "
            f"quantile={quantile!r}, factor={factor!r}"
        )
    T = moving_std(a[:, :2], window)[window - 1 :]
    lam0 = float(factor * np.quantile(T.ravel(), quantile))
    if not lam0 > 0:
        raise DataError("learn_lambda0: the static accel is constant (T = 0); λ_0 cannot be learned from it")
    return lam0

