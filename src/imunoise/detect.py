"""Static (zero-motion) detection with an adaptive threshold and the angular-rate gate (SPEC §7, paper §2.3).

Pipeline per epoch i (all in one numba kernel shared by the batch and the streaming form, so both give
bit-identical results):

1. Test statistic, paper Eq. (9): T_i = sample standard deviation (ddof = 1) of the last N samples of
   the horizontal specific force, accel x and y separately, T_i ∈ R². The window is updated in O(1)
   per sample (sliding Welford update, re-computed exactly by two passes each time the ring buffer
   wraps, which bounds round-off drift). Until N samples are in the window, T_i = NaN and the epoch is
   not static.
2. Adaptive threshold, SPEC §7 (our stable reading of paper Eq. 10):
   λ_i = (k·λ_{i−1} + 2λ_0 − Δ_i) / (k + 1) when epoch i−1 was static, else λ_i = λ_0;
   clamped to [λ_0/2, 2λ_0]. "T_{i−1} < λ_{i−1}" is read for the two axes as "epoch i−1 was static"
   (both axes below), k is the number of consecutive static epochs ending at i−1, and the jump
   penalty is Δ_i = max(|T_i,x − T_{i−1,x}|, |T_i,y − T_{i−1,y}|) — the larger change, because a jump
   on either axis is evidence of motion. Consequences: while still the threshold climbs toward 2λ_0
   (a hysteresis: a stop is entered below λ_0 and kept below up to 2λ_0), a sharp change of T pulls it
   down, and the first moving epoch resets it to λ_0.
3. static_raw_i = T_i,x < λ_i and T_i,y < λ_i.
4. Segments: runs of static_raw epochs, trimmed by ``margin_s`` at both ends (the trailing window
   makes the start late and the end late, and a false static sample hurts the GMWM more than a
   missed one); kept when the trimmed segment lasts at least ``min_duration_s``.
5. Angular-rate gate: open when |ω| (norm of the three gyro rates) > 30 °/s (SPEC §7): the
   static-derived noise model is not trusted for that epoch.

A time step longer than ``max_gap_samples`` nominal sample periods, or a non-finite accel sample
(streaming only; the batch form refuses such data), restarts the window: the detector needs N new
samples before it can call an epoch static again.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from imunoise.errors import DataError, ImunoiseError

__all__ = [
    "DetectorConfig",
    "StaticSegment",
    "Detection",
    "detect_static",
    "StaticDetector",
    "ChunkDetection",
    "moving_std",
    "adaptive_threshold",
    "angular_rate_gate",
    "learn_lambda0",
    "segment_data",
    "static_metrics",
    "static_truth_from_speed",
]


@dataclass(frozen=True)
class DetectorConfig:
    """Parameters of the static detector (SPEC §7).

    ``window`` N [samples] of Eq. (9); ``lambda0`` λ_0 [m/s²] of Eq. (10) (paper: 0.02, which suits a
    quiet IMU; learn it per sensor with :func:`learn_lambda0`); ``min_duration_s`` minimum length of a
    trimmed segment [s]; ``margin_s`` trimmed at each end of a run [s]; ``gate_rate`` [rad/s] of the
    angular-rate gate; ``adaptive`` False uses the fixed threshold λ_0 (Eq. 9 alone);
    ``max_gap_samples``: a time step longer than this many nominal periods restarts the window.
    """

    window: int = 100
    lambda0: float = 0.02
    min_duration_s: float = 2.0
    margin_s: float = 0.5
    gate_rate: float = float(np.deg2rad(30.0))
    adaptive: bool = True
    max_gap_samples: float = 5.0

    def __post_init__(self) -> None:
        if int(self.window) != self.window or self.window < 2:
            raise ImunoiseError(f"DetectorConfig.window must be an integer ≥ 2 samples, got {self.window!r}")
        for name in ("lambda0", "gate_rate", "max_gap_samples"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v <= 0:
                raise ImunoiseError(f"DetectorConfig.{name} must be a positive finite number, got {v!r}")
        for name in ("min_duration_s", "margin_s"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v < 0:
                raise ImunoiseError(f"DetectorConfig.{name} must be ≥ 0 s, got {v!r}")
        object.__setattr__(self, "window", int(self.window))


@dataclass(frozen=True)
class StaticSegment:
    """A detected static segment: samples ``i0 ≤ i < i1`` (slice convention, ``data[i0:i1]``);
    ``t0`` = t[i0] and ``t1`` = t[i1 − 1] are the times of its first and last sample [s]."""

    t0: float
    t1: float
    i0: int
    i1: int

    @property
    def duration(self) -> float:
        """t1 − t0 [s]."""
        return self.t1 - self.t0

    @property
    def slice(self) -> slice:
        return slice(self.i0, self.i1)


@dataclass(frozen=True, eq=False)
class Detection:
    """Result of :func:`detect_static`. Arrays are per epoch (n samples).

    ``statistic`` (n, 2) T of Eq. (9) for accel x, y [m/s²] (NaN while the window fills);
    ``threshold`` (n,) λ_i [m/s²]; ``static_raw`` the per-epoch test; ``static`` epochs inside the
    kept (trimmed, long enough) ``segments``; ``gate_open`` |ω| > gate_rate.
    """

    t: np.ndarray
    statistic: np.ndarray
    threshold: np.ndarray
    static_raw: np.ndarray
    static: np.ndarray
    segments: list[StaticSegment]
    gate_open: np.ndarray
    config: DetectorConfig = field(default_factory=DetectorConfig)

    @property
    def static_time_s(self) -> float:
        """Total duration of the kept segments [s]."""
        return float(sum(s.duration for s in self.segments))


@dataclass(frozen=True, eq=False)
class ChunkDetection:
    """Per-epoch results of one :meth:`StaticDetector.push_chunk` call (fields as in :class:`Detection`)
    and the segments completed inside the chunk."""

    statistic: np.ndarray
    threshold: np.ndarray
    static_raw: np.ndarray
    gate_open: np.ndarray
    segments: list[StaticSegment]


# --------------------------------------------------------------------------------------------------
# numba kernel. State layout (kept in arrays so that a streaming detector can carry it between calls):
#   buf (N, 2)   ring buffer of accel x, y
#   sf  float64: 0 mean_x, 1 mean_y, 2 m2_x, 3 m2_y, 4 T_prev_x, 5 T_prev_y, 6 lam_prev, 7 t_prev
#   si  int64:   0 count in window, 1 ring position, 2 k (static run length), 3 prev static,
#                4 has t_prev, 5 has T_prev
_SF, _SI = 8, 6


@njit(cache=True)
def _reset(sf, si, lambda0):
    sf[0] = 0.0
    sf[1] = 0.0
    sf[2] = 0.0
    sf[3] = 0.0
    sf[4] = np.nan
    sf[5] = np.nan
    sf[6] = lambda0
    si[0] = 0
    si[1] = 0
    si[2] = 0
    si[3] = 0
    si[5] = 0


@njit(cache=True)
def _kernel(t, ax, ay, wnorm, window, lambda0, gate_rate, adaptive, max_gap, buf, sf, si, T, lam, st, gate):
    n = t.shape[0]
    lo = 0.5 * lambda0
    hi = 2.0 * lambda0
    for i in range(n):
        x = ax[i]
        y = ay[i]
        if si[4] == 1 and t[i] - sf[7] > max_gap:
            _reset(sf, si, lambda0)
        sf[7] = t[i]
        si[4] = 1
        gate[i] = not (wnorm[i] <= gate_rate)  # NaN rate → gate open (conservative)
        if not (np.isfinite(x) and np.isfinite(y)):
            _reset(sf, si, lambda0)
            T[i, 0] = np.nan
            T[i, 1] = np.nan
            lam[i] = lambda0
            st[i] = False
            continue
        pos = si[1]
        if si[0] < window:
            # Welford growth while the window fills
            si[0] += 1
            c = si[0]
            d = x - sf[0]
            sf[0] += d / c
            sf[2] += d * (x - sf[0])
            d = y - sf[1]
            sf[1] += d / c
            sf[3] += d * (y - sf[1])
        else:
            ox = buf[pos, 0]
            oy = buf[pos, 1]
            mx = sf[0] + (x - ox) / window
            sf[2] += (x - ox) * (x - mx + ox - sf[0])
            sf[0] = mx
            my = sf[1] + (y - oy) / window
            sf[3] += (y - oy) * (y - my + oy - sf[1])
            sf[1] = my
        buf[pos, 0] = x
        buf[pos, 1] = y
        pos += 1
        if pos == window:
            pos = 0
        si[1] = pos
        if si[0] == window and pos == 0:
            # exact two-pass recomputation once per lap of the ring buffer (drift control)
            sx = 0.0
            sy = 0.0
            for j in range(window):
                sx += buf[j, 0]
                sy += buf[j, 1]
            sx /= window
            sy /= window
            qx = 0.0
            qy = 0.0
            for j in range(window):
                qx += (buf[j, 0] - sx) ** 2
                qy += (buf[j, 1] - sy) ** 2
            sf[0] = sx
            sf[1] = sy
            sf[2] = qx
            sf[3] = qy
        if si[0] < window:
            T[i, 0] = np.nan
            T[i, 1] = np.nan
            lam[i] = lambda0
            st[i] = False
            continue
        tx = np.sqrt(max(sf[2], 0.0) / (window - 1))
        ty = np.sqrt(max(sf[3], 0.0) / (window - 1))
        if adaptive and si[5] == 1 and si[3] == 1:
            k = si[2]
            jump = max(abs(tx - sf[4]), abs(ty - sf[5]))
            li = (k * sf[6] + 2.0 * lambda0 - jump) / (k + 1)
            li = min(max(li, lo), hi)
        else:
            li = lambda0
        s = tx < li and ty < li
        T[i, 0] = tx
        T[i, 1] = ty
        lam[i] = li
        st[i] = s
        sf[4] = tx
        sf[5] = ty
        sf[6] = li
        si[5] = 1
        si[3] = 1 if s else 0
        si[2] = si[2] + 1 if s else 0


class _KernelState:
    """Mutable state of :func:`_kernel` (ring buffer + scalars)."""

    def __init__(self, config: DetectorConfig, rate_hz: float):
        if not np.isfinite(rate_hz) or rate_hz <= 0:
            raise DataError(f"rate_hz must be a positive sampling rate in Hz, got {rate_hz!r}")
        self.config = config
        self.max_gap = float(config.max_gap_samples) / float(rate_hz)
        self.buf = np.zeros((config.window, 2))
        self.sf = np.zeros(_SF)
        self.si = np.zeros(_SI, dtype=np.int64)
        _reset(self.sf, self.si, float(config.lambda0))

    def run(self, t, ax, ay, wnorm):
        n = t.shape[0]
        T = np.empty((n, 2))
        lam = np.empty(n)
        st = np.zeros(n, dtype=np.bool_)
        gate = np.zeros(n, dtype=np.bool_)
        c = self.config
        _kernel(t, ax, ay, wnorm, c.window, float(c.lambda0), float(c.gate_rate), bool(c.adaptive),
                self.max_gap, self.buf, self.sf, self.si, T, lam, st, gate)
        return T, lam, st, gate


# --------------------------------------------------------------------------------------------------
# small pure pieces (public for tests and for others)


def moving_std(x: np.ndarray, window: int = 100) -> np.ndarray:
    """Trailing moving standard deviation (ddof = 1) over ``window`` samples, paper Eq. (9).

    ``x`` (n,) or (n, m); the first ``window − 1`` outputs are NaN. O(n) via the detector kernel.
    """
    x = np.asarray(x, dtype=float)
    one = x.ndim == 1
    x2 = x[:, None] if one else x
    n, m = x2.shape
    out = np.empty((n, m))
    cfg = DetectorConfig(window=window, lambda0=1.0, adaptive=False)
    t = np.arange(n, dtype=float)
    zeros = np.zeros(n)
    for j in range(0, m, 2):
        state = _KernelState(cfg, 1.0)
        a = np.ascontiguousarray(x2[:, j])
        b = np.ascontiguousarray(x2[:, j + 1]) if j + 1 < m else a
        T, _, _, _ = state.run(t, a, b, zeros)
        out[:, j] = T[:, 0]
        if j + 1 < m:
            out[:, j + 1] = T[:, 1]
    return out[:, 0] if one else out


def adaptive_threshold(statistic: np.ndarray, lambda0: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Threshold λ_i and static decision of SPEC §7 (reading of paper Eq. 10) for a given statistic.

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
    """Gate open where |ω| = ‖gyro‖ > ``gate_rate`` [rad/s] (SPEC §7, paper §2.3; NaN → open)."""
    w = np.linalg.norm(np.atleast_2d(np.asarray(gyro, dtype=float)), axis=1)
    return ~(w <= gate_rate)


def learn_lambda0(
    accel_xy_static: np.ndarray,
    window: int = 100,
    quantile: float = 0.5,
    factor: float = 2.0,
) -> float:
    """Learn λ_0 [m/s²] for one sensor from accel samples recorded at a known stop (SPEC §7).

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
        raise DataError("learn_lambda0: static accel contains NaN/Inf")
    if not (0.0 < quantile <= 1.0) or not factor > 0:
        raise ImunoiseError(f"learn_lambda0: need 0 < quantile ≤ 1 and factor > 0, got {quantile}, {factor}")
    T = moving_std(a[:, :2], window)[window - 1 :]
    lam0 = float(factor * np.quantile(T.ravel(), quantile))
    if not lam0 > 0:
        raise DataError("learn_lambda0: the static accel is constant (T = 0); λ_0 cannot be learned from it")
    return lam0


# --------------------------------------------------------------------------------------------------
# segments


def _trim_run(t: np.ndarray, a: int, b: int, config: DetectorConfig) -> StaticSegment | None:
    """Segment of the static run a..b (inclusive) after trimming, or None if too short."""
    lo = t[a] + config.margin_s
    hi = t[b] - config.margin_s
    i0 = a + int(np.searchsorted(t[a : b + 1], lo, side="left"))
    i1 = a + int(np.searchsorted(t[a : b + 1], hi, side="right"))  # exclusive
    if i1 <= i0 or t[i1 - 1] - t[i0] < config.min_duration_s:
        return None
    return StaticSegment(float(t[i0]), float(t[i1 - 1]), i0, i1)


def _segments_from_raw(t: np.ndarray, static_raw: np.ndarray, config: DetectorConfig) -> list[StaticSegment]:
    s = np.concatenate([[False], static_raw, [False]]).astype(np.int8)
    d = np.diff(s)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    out = []
    for a, b in zip(starts, ends, strict=True):
        seg = _trim_run(t, int(a), int(b), config)
        if seg is not None:
            out.append(seg)
    return out


def _check_inputs(t, accel, gyro) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DataError(f"detect_static: t must be 1-D seconds, got shape {t.shape}")
    n = t.size
    accel = np.asarray(accel, dtype=float)
    gyro = np.asarray(gyro, dtype=float)
    for name, a in (("accel", accel), ("gyro", gyro)):
        if a.shape != (n, 3):
            raise DataError(f"detect_static: {name} must be (n, 3) with n = len(t) = {n}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            k = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
            raise DataError(f"detect_static: {name} has NaN/Inf (first at sample {k}); remove or fill it")
    if not np.all(np.isfinite(t)):
        raise DataError("detect_static: time stamps contain NaN/Inf")
    if n > 1 and np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise DataError(
            f"detect_static: time stamps must increase strictly (sample {k + 1}: {t[k + 1]!r} "
            f"after {t[k]!r}); sort them and drop duplicates"
        )
    return t, accel, gyro


def detect_static(
    t: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    config: DetectorConfig = DetectorConfig(),  # noqa: B008 (frozen, immutable)
    rate_hz: float | None = None,
) -> Detection:
    """Static detection over a whole record (SPEC §7; paper Eq. 9, our reading of Eq. 10).

    ``t`` (n,) s strictly increasing; ``accel`` (n, 3) m/s² and ``gyro`` (n, 3) rad/s in body axes
    (x, y horizontal). ``rate_hz`` (default 1/median Δt) only sets the gap that restarts the window.
    Same per-epoch results as :class:`StaticDetector` fed the same samples.
    """
    t, accel, gyro = _check_inputs(t, accel, gyro)
    n = t.size
    if n < config.window:
        raise DataError(f"detect_static: {n} samples, fewer than the window N = {config.window}")
    if rate_hz is None:
        rate_hz = 1.0 / float(np.median(np.diff(t)))
    state = _KernelState(config, rate_hz)
    wnorm = np.linalg.norm(gyro, axis=1)
    T, lam, st, gate = state.run(
        t, np.ascontiguousarray(accel[:, 0]), np.ascontiguousarray(accel[:, 1]), wnorm
    )
    segments = _segments_from_raw(t, st, config)
    static = np.zeros(n, dtype=bool)
    for s in segments:
        static[s.i0 : s.i1] = True
    return Detection(t=t, statistic=T, threshold=lam, static_raw=st, static=static, segments=segments,
                     gate_open=gate, config=config)


class StaticDetector:
    """Streaming static detector: one sample at a time (or chunks), same results as :func:`detect_static`.

    ``push`` returns the segments completed at this sample (trimmed, long enough; usually empty): a
    segment is known when its run of static epochs ends, i.e. at the first non-static sample, so it is
    reported ``margin_s`` + one sample after its last sample. Call :meth:`finish` at the end of the data
    to close a run still open. ``is_static`` is the raw per-epoch test of the latest sample (the trimmed
    mask is known only in hindsight); ``gate_open``, ``statistic`` (2,) and ``threshold`` are also for
    the latest sample. A non-finite accel sample restarts the window (counted in ``n_rejected``).
    """

    def __init__(self, config: DetectorConfig = DetectorConfig(), rate_hz: float = 100.0):  # noqa: B008
        self.config = config
        self.rate_hz = float(rate_hz)
        self._state = _KernelState(config, self.rate_hz)
        self._n = 0
        self._t_last = -np.inf
        self.is_static = False
        self.gate_open = False
        self.statistic = np.full(2, np.nan)
        self.threshold = float(config.lambda0)
        self.n_rejected = 0
        self._run_start: tuple[int, float] | None = None  # (index, t) of the first sample of the run
        self._run_i0: tuple[int, float] | None = None  # first sample at ≥ t_start + margin
        self._run_tail: deque[tuple[int, float]] = deque()  # candidates for the trimmed end
        self._run_last: tuple[int, float] | None = None
        self._one = {
            "t": np.zeros(1), "ax": np.zeros(1), "ay": np.zeros(1), "w": np.zeros(1), "T": np.zeros((1, 2)),
            "lam": np.zeros(1), "st": np.zeros(1, dtype=np.bool_), "gate": np.zeros(1, dtype=np.bool_),
        }

    @property
    def n_samples(self) -> int:
        return self._n

    def push(self, t: float, accel: np.ndarray, gyro: np.ndarray) -> list[StaticSegment]:
        """Feed one sample: ``t`` [s], ``accel`` (3,) m/s², ``gyro`` (3,) rad/s.

        About 10 µs per call; for replay prefer :meth:`push_chunk` (same results)."""
        t = float(t)
        if not t > self._t_last:
            raise DataError(
                f"StaticDetector.push: time {t!r} does not follow {self._t_last!r}; stamps must increase"
            )
        ax, ay = float(accel[0]), float(accel[1])
        gx, gy, gz = float(gyro[0]), float(gyro[1]), float(gyro[2])
        b = self._one
        b["t"][0] = t
        b["ax"][0] = ax
        b["ay"][0] = ay
        b["w"][0] = np.sqrt(gx * gx + gy * gy + gz * gz)
        c, k = self.config, self._state
        _kernel(b["t"], b["ax"], b["ay"], b["w"], c.window, float(c.lambda0), float(c.gate_rate),
                bool(c.adaptive), k.max_gap, k.buf, k.sf, k.si, b["T"], b["lam"], b["st"], b["gate"])
        if not (np.isfinite(ax) and np.isfinite(ay)):
            self.n_rejected += 1
        self._t_last = t
        i = self._n
        self._n += 1
        self.statistic = b["T"][0].copy()
        self.threshold = float(b["lam"][0])
        self.is_static = bool(b["st"][0])
        self.gate_open = bool(b["gate"][0])
        return self._segment_step(i, t, self.is_static)

    def push_chunk(self, t: np.ndarray, accel: np.ndarray, gyro: np.ndarray) -> ChunkDetection:
        """Feed a chunk of samples (m,), (m, 3), (m, 3): per-epoch results and completed segments,
        identical to feeding the samples one by one with :meth:`push`."""
        t = np.ascontiguousarray(t, dtype=float).reshape(-1)
        accel = np.asarray(accel, dtype=float).reshape(-1, 3)
        gyro = np.asarray(gyro, dtype=float).reshape(-1, 3)
        m = t.size
        if accel.shape[0] != m or gyro.shape[0] != m:
            raise DataError(
                f"StaticDetector.push_chunk: {m} times but accel {accel.shape}, gyro {gyro.shape}"
            )
        if m == 0:
            e = np.zeros(0, dtype=bool)
            return ChunkDetection(np.zeros((0, 2)), np.zeros(0), e, e.copy(), [])
        if not (t[0] > self._t_last and np.all(np.diff(t) > 0)):
            raise DataError(
                "StaticDetector.push_chunk: time stamps must increase strictly, also across chunks "
                f"(chunk starts at {t[0]!r}, previous sample {self._t_last!r})"
            )
        ax = np.ascontiguousarray(accel[:, 0])
        ay = np.ascontiguousarray(accel[:, 1])
        T, lam, st, gate = self._state.run(t, ax, ay, np.sqrt(np.sum(gyro * gyro, axis=1)))
        self.n_rejected += int(np.sum(~(np.isfinite(ax) & np.isfinite(ay))))
        base = self._n
        self._n += m
        self._t_last = float(t[-1])
        self.statistic = T[-1].copy()
        self.threshold = float(lam[-1])
        self.is_static = bool(st[-1])
        self.gate_open = bool(gate[-1])
        return ChunkDetection(T, lam, st, gate, self._segment_chunk(base, t, st))

    def push_many(self, t: np.ndarray, accel: np.ndarray, gyro: np.ndarray) -> list[StaticSegment]:
        """Feed a chunk (m,), (m, 3), (m, 3); returns the segments completed inside it."""
        return self.push_chunk(t, accel, gyro).segments

    def finish(self) -> list[StaticSegment]:
        """Close a run still open at the end of the data (as :func:`detect_static` does)."""
        return self._close_run()

    def _segment_step(self, i: int, t: float, static: bool) -> list[StaticSegment]:
        c = self.config
        if static:
            if self._run_start is None:
                self._run_start = (i, t)
                self._run_i0 = None
                self._run_tail.clear()
            if self._run_i0 is None and t >= self._run_start[1] + c.margin_s:
                self._run_i0 = (i, t)
            tail = self._run_tail
            tail.append((i, t))
            # keep the last sample at or before (t_now − margin) and everything after it
            while len(tail) >= 2 and tail[1][1] <= t - c.margin_s:
                tail.popleft()
            self._run_last = (i, t)
            return []
        return self._close_run()

    def _segment_chunk(self, base: int, tc: np.ndarray, sc: np.ndarray) -> list[StaticSegment]:
        """Chunk form of :meth:`_segment_step` (same rules, vectorised over the runs of the chunk)."""
        margin = self.config.margin_s
        out: list[StaticSegment] = []
        m = tc.size
        if self._run_start is not None and not sc[0]:
            out.extend(self._close_run())
        d = np.diff(np.concatenate([[0], sc.astype(np.int8), [0]]))
        starts = np.flatnonzero(d == 1)
        ends = np.flatnonzero(d == -1) - 1
        for p, q in zip(starts.tolist(), ends.tolist(), strict=True):
            if not (p == 0 and self._run_start is not None):
                self._run_start = (base + p, float(tc[p]))
                self._run_i0 = None
                self._run_tail.clear()
            ts = tc[p : q + 1]
            if self._run_i0 is None:
                j = int(np.searchsorted(ts, self._run_start[1] + margin, side="left"))
                if j < ts.size:
                    self._run_i0 = (base + p + j, float(ts[j]))
            hi = ts[-1] - margin
            cut = int(np.searchsorted(ts, hi, side="right")) - 1  # last sample at or before hi
            tail = self._run_tail
            if cut >= 0:
                tail.clear()
                tail.extend(zip(range(base + p + cut, base + q + 1), ts[cut:].tolist(), strict=True))
            else:
                tail.extend(zip(range(base + p, base + q + 1), ts.tolist(), strict=True))
                while len(tail) >= 2 and tail[1][1] <= hi:
                    tail.popleft()
            self._run_last = (base + q, float(ts[-1]))
            if q < m - 1:
                out.extend(self._close_run())
        return out

    def _close_run(self) -> list[StaticSegment]:
        if self._run_start is None:
            return []
        c = self.config
        i0 = self._run_i0
        t_end = self._run_last[1]
        self._run_start = None
        hi = t_end - c.margin_s
        end = None
        for j, tj in reversed(self._run_tail):
            if tj <= hi:
                end = (j, tj)
                break
        self._run_tail.clear()
        if i0 is None or end is None or end[0] < i0[0] or end[1] - i0[1] < c.min_duration_s:
            return []
        return [StaticSegment(float(i0[1]), float(end[1]), i0[0], end[0] + 1)]


# --------------------------------------------------------------------------------------------------
# using the result


def segment_data(detection: Detection, data: np.ndarray, remove_bias: bool = True) -> list[np.ndarray]:
    """Samples of ``data`` (n, k) inside each static segment, each minus its segment mean when
    ``remove_bias`` (SPEC §7: the bias of a stop is removed before the GMWM)."""
    data = np.asarray(data, dtype=float)
    if data.shape[0] != detection.t.size:
        raise DataError(
            f"segment_data: data has {data.shape[0]} rows, the detection has {detection.t.size} epochs"
        )
    out = []
    for s in detection.segments:
        d = data[s.i0 : s.i1]
        out.append(d - d.mean(axis=0) if remove_bias else d.copy())
    return out


def static_metrics(static_pred: np.ndarray, static_true: np.ndarray) -> dict[str, float]:
    """Epoch-wise precision, recall and F1 of a static mask against the truth (NaN when undefined)."""
    p = np.asarray(static_pred, dtype=bool)
    q = np.asarray(static_true, dtype=bool)
    if p.shape != q.shape:
        raise DataError(f"static_metrics: shapes differ: {p.shape} vs {q.shape}")
    tp = int(np.sum(p & q))
    n_pred, n_true = int(p.sum()), int(q.sum())
    precision = tp / n_pred if n_pred else float("nan")
    recall = tp / n_true if n_true else float("nan")
    if not (n_pred and n_true):
        f1 = float("nan")
    else:
        f1 = 2 * precision * recall / (precision + recall) if tp else 0.0
    return {"precision": precision, "recall": recall, "f1": f1, "n_true": n_true, "n_pred": n_pred}


def static_truth_from_speed(
    t: np.ndarray, t_ref: np.ndarray, vel_ref: np.ndarray, threshold: float = 0.2
) -> np.ndarray:
    """Reference static mask at epochs ``t``: speed ‖v‖ (3-D, from ``vel_ref`` (m, 3) m/s, or a speed
    (m,)) linearly interpolated to ``t``, below ``threshold`` [m/s]. Epochs outside the reference span
    are not static."""
    v = np.asarray(vel_ref, dtype=float)
    speed = np.linalg.norm(v, axis=1) if v.ndim == 2 else v
    s = np.interp(t, t_ref, speed)
    return (s < threshold) & (t >= t_ref[0]) & (t <= t_ref[-1])
