"""Static (zero-motion) detection with an adaptive threshold and the angular-rate gate (SPEC §7, paper §2.3).

One implementation: the streaming :class:`StaticDetector` (state carried across calls) drives the numba
kernel of :mod:`imunoise.detect.kernels` and cuts the segments; :func:`detect_static` is that detector fed the
record in chunks, and the online engine feeds it per sample (``push_imu``) or per chunk (``run``). So every
form gives bit-identical results. Pipeline per epoch i:

1. Test statistic, paper Eq. (9): T_i = sample standard deviation (ddof = 1) of the last N samples of
   the horizontal specific force, accel x and y separately, T_i ∈ R². The window is updated in O(1)
   per sample (sliding Welford update, re-computed exactly by two passes each time the ring buffer
   wraps, which bounds round-off drift). Until N samples are in the window, T_i = NaN and the epoch is
   not static.
2. Adaptive threshold, SPEC §7 (our stable reading of paper Eq. 10):
   λ_i = (k·λ_{i−1} + 2λ_0 − Δ_i) / (k + 1) when epoch i−1 was static, else λ_i = λ_0;
   clamped to [λ_0/2, 2λ_0]. "T_{i−1} < λ_{i−1}" is read for the two axes as "epoch i−1 was static"
   (both axes below), k is the number of consecutive static epochs ending at i−1, and the jump
   penalty is Δ_i = max(``|T_i,x − T_{i−1,x}|``, ``|T_i,y − T_{i−1,y}|``) — the larger change, because a jump
   on either axis is evidence of motion. Consequences: while still the threshold climbs toward 2λ_0
   (a hysteresis: a stop is entered below λ_0 and kept below up to 2λ_0), a sharp change of T pulls it
   down, and the first moving epoch resets it to λ_0.
3. static_raw_i = T_i,x < λ_i and T_i,y < λ_i.
4. Segments: runs of static_raw epochs, trimmed by ``margin_s`` at both ends (the trailing window
   makes the start late and the end late, and a false static sample hurts the GMWM more than a
   missed one); kept when the trimmed segment lasts at least ``min_duration_s``.
5. Angular-rate gate: open when ‖ω‖ (norm of the three gyro rates) > 30 °/s (SPEC §7): the
   static-derived noise model is not trusted for that epoch.

A time step longer than ``max_gap_samples`` nominal sample periods, or a non-finite accel sample
(streaming only; :func:`detect_static` refuses such data), restarts the window: the detector needs N new
samples before it can call an epoch static again.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from imunoise.detect.kernels import N_SF, N_SI, detector_kernel, reset_state
from imunoise.errors import DataError, ModelError

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
        # invalid settings are a malformed detector model: ModelError (a ValueError), naming the field to fix
        w = self.window
        if isinstance(w, bool) or not isinstance(w, int | np.integer | float) or not np.isfinite(w) \
                or int(w) != w or w < 2:
            raise ModelError(
                f"DetectorConfig.window must be a whole number of samples ≥ 2 (paper: 100), got {w!r}"
            )
        for name, rule in (("lambda0", "> 0 m/s² (paper: 0.02; or learn it with learn_lambda0)"),
                           ("gate_rate", "> 0 rad/s (SPEC §7: 30 °/s = 0.5236 rad/s)"),
                           ("max_gap_samples", "> 0 sample periods (default 5)"),
                           ("min_duration_s", "≥ 0 s (default 2)"), ("margin_s", "≥ 0 s (default 0.5)")):
            try:
                v = float(getattr(self, name))
            except (TypeError, ValueError):
                v = float("nan")
            ok = v >= 0 if name in ("min_duration_s", "margin_s") else v > 0
            if not (np.isfinite(v) and ok):
                raise ModelError(f"DetectorConfig.{name} must be a finite number {rule}, got {getattr(self, name)!r}")
        object.__setattr__(self, "window", int(w))


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
    kept (trimmed, long enough) ``segments``; ``gate_open`` ‖ω‖ > gate_rate.
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
    and the segments completed inside the chunk. ``completed_at[j]`` is the index (counted from the
    detector's first sample) of the sample whose :meth:`StaticDetector.push` would have returned
    ``segments[j]``: the first non-static sample after its run."""

    statistic: np.ndarray
    threshold: np.ndarray
    static_raw: np.ndarray
    gate_open: np.ndarray
    segments: list[StaticSegment]
    completed_at: list[int] = field(default_factory=list)


class _KernelState:
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
        state = _KernelState(cfg, 1.0)
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
    """Gate open where ‖ω‖ = ‖gyro‖ > ``gate_rate`` [rad/s] (SPEC §7, paper §2.3; NaN → open)."""
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


CHUNK = 65_536
"""Samples per :meth:`StaticDetector.push_chunk` call in :func:`detect_static` (large enough that the per-call
overhead is negligible, small enough to stay in cache)."""


def detect_static(
    t: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    config: DetectorConfig = DetectorConfig(),  # noqa: B008 (frozen, immutable)
    rate_hz: float | None = None,
) -> Detection:
    """Static detection over a whole record (SPEC §7; paper Eq. 9, our reading of Eq. 10).

    The streaming :class:`StaticDetector` fed the record in chunks of :data:`CHUNK` samples and closed with
    :meth:`StaticDetector.finish`: the same per-epoch results and segments as feeding it sample by sample.

    Parameters
    ----------
    t
        (n,) time [s], strictly increasing, finite.
    accel, gyro
        (n, 3) specific force [m/s²] and angular rate [rad/s] in body axes (x, y horizontal), finite.
    config
        Detector settings (SPEC §7).
    rate_hz
        Nominal rate [Hz] (default 1/median Δt); only sets the gap that restarts the window.

    Returns
    -------
    Detection
        Per-epoch statistic, threshold, raw test, gate; the kept segments and their mask ``static``.
    """
    t, accel, gyro = _check_inputs(t, accel, gyro)
    n = t.size
    if n < config.window:
        raise DataError(
            f"detect_static: {n} samples, fewer than the window N = {config.window}; give a longer record "
            "or a smaller DetectorConfig.window"
        )
    if rate_hz is None:
        rate_hz = 1.0 / float(np.median(np.diff(t)))
    sd = StaticDetector(config, rate_hz)
    accel = np.ascontiguousarray(accel)
    gyro = np.ascontiguousarray(gyro)
    T = np.empty((n, 2))
    lam = np.empty(n)
    st = np.empty(n, dtype=np.bool_)
    gate = np.empty(n, dtype=np.bool_)
    segments: list[StaticSegment] = []
    for a in range(0, n, CHUNK):
        b = min(a + CHUNK, n)
        # views into the full-length outputs: the chunks are written in place, no copies
        segments.extend(sd._advance(t[a:b], accel[a:b], gyro[a:b], T[a:b], lam[a:b], st[a:b], gate[a:b])[0])
    segments.extend(sd.finish())
    static = np.zeros(n, dtype=bool)
    for s in segments:
        static[s.i0 : s.i1] = True
    return Detection(t=t, statistic=T, threshold=lam, static_raw=st, static=static, segments=segments,
                     gate_open=gate, config=config)


def _as_time(t: object, where: str) -> float:
    try:
        return float(t)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise DataError(f"{where}: time must be a number of seconds, got {t!r}") from exc


_PUSH_SHAPE = "StaticDetector.push: accel and gyro must be 3 numbers each (x, y, z; m/s² and rad/s), got "


def _shape(x: object) -> tuple[int, ...]:
    return x.shape if type(x) is np.ndarray else np.shape(x)


def _runs(static: np.ndarray) -> tuple[list[int], list[int]]:
    """First and last index (inclusive) of each run of True in ``static``."""
    if static.size == 1:  # the per-sample push: skip the array machinery (same result)
        return ([0], [0]) if static[0] else ([], [])
    d = np.diff(np.concatenate([[0], static.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist()


_SHORT = 64
"""Chunks up to this length are segmented on Python floats (bisect), longer ones on arrays (searchsorted):
the same comparisons of the same float64 values, chosen only for speed (a per-sample push is a chunk of 1)."""


def _searchsorted(ts: np.ndarray | list[float], v: float, right: bool) -> int:
    """Number of times in the sorted ``ts`` below ``v`` (at or below when ``right``)."""
    if isinstance(ts, list):
        return bisect_right(ts, v) if right else bisect_left(ts, v)
    return int(np.searchsorted(ts, v, side="right" if right else "left"))


def _as_list(ts: np.ndarray | list[float]) -> list[float]:
    return ts if isinstance(ts, list) else ts.tolist()


class StaticDetector:
    """Streaming static detector (SPEC §7): one sample at a time or chunks; the only detector implementation
    (:func:`detect_static` feeds it the record in chunks, the online engine per sample or per chunk).

    ``push`` returns the segments completed at this sample (trimmed, long enough; usually empty): a
    segment is known when its run of static epochs ends, i.e. at the first non-static sample, so it is
    reported ``margin_s`` + one sample after its last sample. Call :meth:`finish` at the end of the data
    to close a run still open. ``is_static`` is the raw per-epoch test of the latest sample (the trimmed
    mask is known only in hindsight); ``gate_open``, ``statistic`` (2,) and ``threshold`` are also for
    the latest sample. A non-finite accel sample restarts the window (counted in ``n_rejected``).

    Parameters
    ----------
    config
        Detector settings.
    rate_hz
        Nominal sampling rate [Hz] (> 0); sets the time gap (``max_gap_samples`` periods) that restarts the
        window.
    """

    def __init__(self, config: DetectorConfig = DetectorConfig(), rate_hz: float = 100.0):  # noqa: B008
        if not isinstance(config, DetectorConfig):
            raise ModelError(f"StaticDetector: config must be a DetectorConfig, got {type(config).__name__}")
        self.config = config
        self._state = _KernelState(config, rate_hz)
        k = self._state
        self._kargs = (config.window, float(config.lambda0), float(config.gate_rate), bool(config.adaptive),
                       k.max_gap, k.buf, k.sf, k.si)  # the kernel's settings and state, in its argument order
        self.rate_hz = float(rate_hz)
        self._n = 0
        self._t_last = -np.inf
        self.is_static = False
        self.gate_open = False
        self.statistic = np.full(2, np.nan)
        self.threshold = float(config.lambda0)
        self._run_start: tuple[int, float] | None = None  # (index, t) of the first sample of the run
        self._run_i0: tuple[int, float] | None = None  # first sample at ≥ t_start + margin
        self._run_tail: deque[tuple[int, float]] = deque()  # candidates for the trimmed end
        self._run_last: tuple[int, float] | None = None
        # one-sample buffers of push (no allocation per sample)
        self._one = (np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 2)), np.zeros(1),
                     np.zeros(1, dtype=np.bool_), np.zeros(1, dtype=np.bool_))

    @property
    def n_samples(self) -> int:
        """Samples fed so far."""
        return self._n

    @property
    def n_rejected(self) -> int:
        """Samples with a non-finite accel x or y so far (each restarted the window)."""
        return int(self._state.si[6])

    def push(self, t: float, accel: np.ndarray, gyro: np.ndarray) -> list[StaticSegment]:
        """Feed one sample: ``t`` [s], ``accel`` (3,) m/s², ``gyro`` (3,) rad/s. Returns the segments
        completed at this sample. Same code as :meth:`push_chunk` with a chunk of one sample.

        Parameters
        ----------
        t : float
            Time [s]; stamps must increase strictly.
        accel : numpy.ndarray
            Specific force [m/s²], shape (3,).
        gyro : numpy.ndarray
            Angular rate [rad/s], shape (3,).

        Returns
        -------
        list of StaticSegment
            The segments completed at this sample (usually none).
        """
        t = _as_time(t, "StaticDetector.push")
        if not t > self._t_last:
            raise DataError(
                f"StaticDetector.push: time {t!r} does not follow {self._t_last!r}; stamps must increase strictly"
            )
        tb, ab, gb, T, lam, st, gate = self._one
        # shape first: numpy would broadcast a scalar or a 1-element array to the three axes
        if _shape(accel) != (3,) or _shape(gyro) != (3,):
            raise DataError(f"{_PUSH_SHAPE}shapes {np.shape(accel)} and {np.shape(gyro)}")
        try:
            ab[0] = accel
            gb[0] = gyro
        except (TypeError, ValueError) as exc:
            raise DataError(f"{_PUSH_SHAPE}{accel!r} and {gyro!r}") from exc
        tb[0] = t
        return self._advance(tb, ab, gb, T, lam, st, gate)[0]

    def push_chunk(self, t: np.ndarray, accel: np.ndarray, gyro: np.ndarray) -> ChunkDetection:
        """Feed a chunk of samples (m,), (m, 3), (m, 3): per-epoch results and completed segments,
        identical to feeding the samples one by one with :meth:`push`.

        Parameters
        ----------
        t : numpy.ndarray
            Times [s], shape (m,), increasing and after the last sample fed.
        accel, gyro : numpy.ndarray
            Specific force [m/s²] and angular rate [rad/s], shape (m, 3).

        Returns
        -------
        ChunkDetection
            Per-epoch statistic, threshold, static and gate flags, and the completed segments.
        """
        try:
            t = np.ascontiguousarray(t, dtype=float).reshape(-1)
            accel = np.ascontiguousarray(accel, dtype=float)
            gyro = np.ascontiguousarray(gyro, dtype=float)
        except (TypeError, ValueError) as exc:
            raise DataError(f"StaticDetector.push_chunk: t, accel, gyro must be numeric arrays ({exc})") from exc
        m = t.size
        if accel.shape != (m, 3) or gyro.shape != (m, 3):
            raise DataError(
                f"StaticDetector.push_chunk: accel and gyro must be (m, 3) with m = len(t) = {m}, got "
                f"{accel.shape} and {gyro.shape}"
            )
        if m == 0:
            e = np.zeros(0, dtype=bool)
            return ChunkDetection(np.zeros((0, 2)), np.zeros(0), e, e.copy(), [], [])
        T = np.empty((m, 2))
        lam = np.empty(m)
        st = np.empty(m, dtype=np.bool_)
        gate = np.empty(m, dtype=np.bool_)
        segs, done = self._advance(t, accel, gyro, T, lam, st, gate)
        return ChunkDetection(T, lam, st, gate, segs, done)

    def push_many(self, t: np.ndarray, accel: np.ndarray, gyro: np.ndarray) -> list[StaticSegment]:
        """Feed a chunk (m,), (m, 3), (m, 3); returns the segments completed inside it."""
        return self.push_chunk(t, accel, gyro).segments

    def finish(self) -> list[StaticSegment]:
        """Close a run still open at the end of the data (as :func:`detect_static` does)."""
        return self._close_run()

    def _advance(self, t, accel, gyro, T, lam, st, gate) -> tuple[list[StaticSegment], list[int]]:
        """The one step of every form: run the kernel over the chunk (outputs written into ``T``, ``lam``,
        ``st``, ``gate``), update the latest-sample attributes, cut the segments. ``t`` (m ≥ 1,) and
        ``accel``/``gyro`` (m, 3) C-contiguous float arrays."""
        m = t.size
        if not (float(t[0]) > self._t_last and (m == 1 or bool(np.all(t[1:] > t[:-1])))):
            raise DataError(
                "StaticDetector: time stamps must increase strictly, also across chunks "
                f"(chunk starts at {t[0]!r}, previous sample {self._t_last!r}); sort them and drop duplicates"
            )
        detector_kernel(t, accel, gyro, *self._kargs, T, lam, st, gate)
        base = self._n
        self._n += m
        self._t_last = float(t[-1])
        self.statistic = T[-1].copy()
        self.threshold = float(lam[-1])
        self.is_static = bool(st[-1])
        self.gate_open = bool(gate[-1])
        return self._segment_chunk(base, t, st)

    def _segment_chunk(self, base: int, tc: np.ndarray, sc: np.ndarray) -> tuple[list[StaticSegment], list[int]]:
        """Segments completed in the chunk (samples ``base`` …) and the index of the sample completing each.

        A run is trimmed by ``margin_s`` at both ends and kept when the trimmed part lasts ≥ ``min_duration_s``
        (module docstring, step 4); a run may span chunks (its start and end candidates are carried)."""
        margin = self.config.margin_s
        out: list[StaticSegment] = []
        done: list[int] = []
        m = tc.size
        seq = tc.tolist() if m <= _SHORT else tc
        if self._run_start is not None and not sc[0]:
            for s in self._close_run():
                out.append(s)
                done.append(base)
        starts, ends = _runs(sc)
        for p, q in zip(starts, ends, strict=True):
            if not (p == 0 and self._run_start is not None):
                self._run_start = (base + p, float(seq[p]))
                self._run_i0 = None
                self._run_tail.clear()
            ts = seq[p : q + 1]
            t_last = float(ts[-1])
            if self._run_i0 is None:
                j = _searchsorted(ts, self._run_start[1] + margin, right=False)
                if j < len(ts):
                    self._run_i0 = (base + p + j, float(ts[j]))
            hi = t_last - margin
            cut = _searchsorted(ts, hi, right=True) - 1  # last sample at or before hi
            tail = self._run_tail
            # keep the last sample at or before (t_now − margin) and everything after it
            if cut >= 0:
                tail.clear()
                tail.extend(zip(range(base + p + cut, base + q + 1), _as_list(ts[cut:]), strict=True))
            else:
                tail.extend(zip(range(base + p, base + q + 1), _as_list(ts), strict=True))
                while len(tail) >= 2 and tail[1][1] <= hi:
                    tail.popleft()
            self._run_last = (base + q, t_last)
            if q < m - 1:
                for s in self._close_run():
                    out.append(s)
                    done.append(base + q + 1)
        return out, done

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
