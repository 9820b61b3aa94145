"""Static (zero-motion) detection with an adaptive threshold and the angular-rate gate
(docs/guide/theory.rst, 'Static detection', paper §2.3).

One implementation: the streaming :class:`StaticDetector` (state carried across calls) drives the numba
kernel of :mod:`imunoise.detect.kernels` and cuts the segments; :func:`detect_static` is that detector fed the
record in chunks, and the online engine feeds it per sample (``push_imu``) or per chunk (``run``). So every
form gives bit-identical results. Pipeline per epoch i:

1. Test statistic, paper Eq. (9): T_i = sample standard deviation (ddof = 1) of the last N samples of
   the horizontal specific force, accel x and y separately, T_i ∈ R². The window is updated in O(1)
   per sample (sliding Welford update, re-computed exactly by two passes each time the ring buffer
   wraps, which bounds round-off drift). Until N samples are in the window, T_i = NaN and the epoch is
   not static.
2. Adaptive threshold, docs/guide/theory.rst, 'Static detection' (our stable reading of paper Eq. 10):
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
5. Angular-rate gate: open when ‖ω‖ (norm of the three gyro rates) > 30 °/s (docs/guide/theory.rst, 'Static detection'):
   the static-derived noise model is not trusted for that epoch.

A time step longer than ``max_gap_samples`` nominal sample periods, or a non-finite accel sample
(streaming only; :func:`detect_static` refuses such data), restarts the window: the detector needs N new
samples before it can call an epoch static again.
"""


from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections import deque

import numpy as np

from imunoise.detect.config import DetectorConfig
from imunoise.detect.kernels import detector_kernel
from imunoise.detect.metrics import static_metrics, static_truth_from_speed
from imunoise.detect.results import ChunkDetection, Detection, StaticSegment, segment_data
from imunoise.detect.statistics import KernelState, adaptive_threshold, angular_rate_gate, learn_lambda0, moving_std
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
    """Static detection over a whole record (docs/guide/theory.rst, 'Static detection'; paper Eq. 9, our reading of Eq.
    10).

    The streaming :class:`StaticDetector` fed the record in chunks of :data:`CHUNK` samples and closed with
    :meth:`StaticDetector.finish`: the same per-epoch results and segments as feeding it sample by sample.

    Parameters
    ----------
    t
        (n,) time [s], strictly increasing, finite.
    accel, gyro
        (n, 3) specific force [m/s²] and angular rate [rad/s] in body axes (x, y horizontal), finite.
    config
        Detector settings (docs/guide/theory.rst, 'Static detection').
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
    """Streaming static detector (docs/guide/theory.rst, 'Static detection'): one sample at a time or chunks; the only
    detector implementation
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
        self._state = KernelState(config, rate_hz)
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
