"""The stops of one log: λ_0 learned on its quietest stretch, the detector, the rate gate and the speed check
(paper Eq. 9; docs/guide/theory.rst, 'Static detection'; :mod:`imunoise.calibrate`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from imunoise.calibrate.logs import ImuLog
from imunoise.detect import Detection, DetectorConfig, StaticSegment, detect_static, learn_lambda0, moving_std
from imunoise.detect.both_ways import detect_static_both_ways
from imunoise.errors import DataError, ModelError

STILL_CONTRAST = 0.6
"""The quietest stretch counts as a stop only when its gyros are quiet too: median moving std of the gyros
there ≤ this × their 90th percentile over the log. Cruising vibration can quiet the accelerometers' Eq. 9
statistic to a stop's level, not the gyros' (simulator: 0.93 on a log without a stop; 0.32 on a drive
with stops, 0.30 on drive_0708)."""

MAX_STOPS_PER_MIN = 1.0
"""Stops per minute of log above which a log without a speed source is taken to hold cruising called stops
(:func:`implausible_stops`), counted when it has at least :data:`MIN_STOPS_CHECKED` stops. Measured on
simulated 30-min drives without a speed source (development seeds 3600–3611, docs/evidence/calibrate_stops.md):
0.47 per minute under the default motion law (the true stops), 1.40–1.93 under law ``none`` (cruising whose
noise equals a stop's); drive_0708: 0.44 per minute."""

MIN_STOPS_CHECKED = 10
"""Fewer stops than this are not judged by their rate (a short log with a few real stops)."""

LEARN_S = 10.0
"""Seconds of the quietest stretch λ_0 is learned from (the online engine's ``learn_lambda0_s``)."""

# --------------------------------------------------------------------------------------------------
# stops
# --------------------------------------------------------------------------------------------------
#: one modelled stop of a log: the detector's segment type (samples i0 ≤ i < i1, times t0..t1 [s]), after the
#: rate gate and the navigation check have cut it
Stop = StaticSegment


@dataclass(eq=False)
class LogStops:
    """Detection outcome of one log.

    Attributes
    ----------
    log : ImuLog
        The log.
    lambda0 : float
        λ_0 [m/s²] used, and ``lambda0_source`` how it was chosen.
    lambda0_source : str
        How λ_0 was chosen.
    detection : imunoise.detect.Detection
        The detector's per-epoch output and its segments (before the gate and the speed check).
    stops : list of Stop
        The segments modelled.
    dropped : list of str
        What the rate gate and the speed check removed, one line each.
    samples : list of numpy.ndarray, optional
        A streamed log's stop samples, (len, 6) per stop in :data:`imunoise.imu.AXES` order (a whole log's are
        sliced from ``log``).
    """

    log: ImuLog
    lambda0: float
    lambda0_source: str
    detection: Any
    stops: list[Stop]
    dropped: list[str]
    samples: list[np.ndarray] | None = None

    def stop_samples(self, k: int) -> list[np.ndarray]:
        """Samples of axis ``k`` (index in :data:`imunoise.imu.AXES`) of each stop, in order."""
        if self.samples is not None:
            return [x[:, k] for x in self.samples]
        data = self.log.gyro if k < 3 else self.log.accel
        return [data[s.i0 : s.i1, k % 3] for s in self.stops]

    @property
    def static_s(self) -> float:
        return float(sum(s.duration for s in self.stops))


def learn_lambda0_quietest(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, *, window: int = 100,
                           learn_s: float = LEARN_S, rate_hz: float | None = None) -> tuple[float, float, float]:
    """λ_0 learned (:func:`imunoise.detect.learn_lambda0`) on the quietest ``learn_s`` seconds of a log.

    The stretch is the one whose median Eq. 9 statistic (max of accel x, y) is smallest, searched in steps of
    half its length: the first stop of a log that starts with one, otherwise its longest still moment.

    Parameters
    ----------
    t : numpy.ndarray
        (n,) time [s].
    accel : numpy.ndarray
        (n, ≥2) specific force [m/s²].
    gyro : numpy.ndarray
        (n, 3) angular rate [rad/s] (the stillness contrast, :data:`STILL_CONTRAST`).
    window : int
        N of Eq. 9 [samples].
    learn_s : float
        Length of the stretch [s].
    rate_hz : float, optional
        Sample rate (default 1/median Δt).

    Returns
    -------
    (float, float, float)
        λ_0 [m/s²], the start time of the stretch [s], and its gyro contrast (median moving std of the gyros
        there / their 90th percentile over the log; a stop when ≤ :data:`STILL_CONTRAST`).
    """
    t = np.asarray(t, dtype=float)
    G = moving_std(np.asarray(gyro, dtype=float), window).max(axis=1)
    return _quietest(t, np.asarray(accel, dtype=float), G, window, learn_s, rate_hz)


def _quietest(t: np.ndarray, accel: np.ndarray, G: np.ndarray, window: int, learn_s: float,
              rate_hz: float | None) -> tuple[float, float, float]:
    """:func:`learn_lambda0_quietest` given the gyros' moving std ``G`` (n,) (max over the axes), so a streamed
    log need not hold its gyros."""
    f = float(rate_hz) if rate_hz else 1.0 / float(np.median(np.diff(t)))
    m = max(int(round(learn_s * f)), 2 * int(window))
    n = t.size
    if n < m:
        raise DataError(
            f"the log holds {n} samples ({n / f:.1f} s); learning λ0 needs ≥ {m} ({m / f:.1f} s); give a longer "
            "log or --lambda0"
        )
    T = moving_std(accel[:, :2], window).max(axis=1)
    step = max(m // 2, 1)
    best, best_i = math.inf, 0
    for i in range(0, n - m + 1, step):
        seg = T[i + window - 1 : i + m]
        seg = seg[np.isfinite(seg)]
        if seg.size and (med := float(np.median(seg))) < best:
            best, best_i = med, i
    lam = learn_lambda0(accel[best_i : best_i + m], window=window)
    q90 = float(np.nanquantile(G, 0.9))
    contrast = float(np.nanmedian(G[best_i + window - 1 : best_i + m])) / q90 if q90 > 0 else 1.0
    return lam, float(t[best_i]), contrast


def choose_lambda0(t: np.ndarray, accel: np.ndarray, G: Callable[[], np.ndarray], window: int, f: float,
                    lambda0: float | None, learn_from_s: float | None, learn_s: float) -> tuple[float, str, str | None]:
    """λ_0, how it was chosen, and why the log has no stop (its quietest stretch is not still) or None; ``G()``
    gives the gyros' moving std (only the quietest-stretch rule needs it)."""
    if lambda0 is not None:
        if not (math.isfinite(lambda0) and lambda0 > 0):
            raise ModelError(f"λ0 must be a positive threshold in m/s², got {lambda0!r}")
        return float(lambda0), "given", None
    if learn_from_s is not None:
        m = t < t[0] + learn_from_s
        return learn_lambda0(accel[m], window=window), f"learned from the first {learn_from_s:g} s", None
    lam, t_q, contrast = _quietest(t, accel, G(), window, learn_s, f)
    src = f"learned from the quietest {learn_s:g} s (from {t_q - t[0]:.1f} s into the log)"
    why = None
    if contrast > STILL_CONTRAST:
        why = (f"its quietest {learn_s:g} s are no stop: the gyros' moving std there is {contrast:.2f} × their "
               f"90th percentile (a stop: ≤ {STILL_CONTRAST:g}); give --lambda0 or --learn-from if it has one")
    return lam, src, why


STREAM_END_TRIM_S = 0.5
"""Seconds cut from the end of each forward-only (streamed) stop on top of the detector's ``margin_s``.
The whole-log path detects both ways (:func:`imunoise.detect.both_ways.detect_static_both_ways`) and keeps
no motion; the stream has only the forward pass, whose trailing window lags a slow departure. Measured on
simulated drives (docs/evidence/calibrate_stops.md): the forward segments, after the 0.5 s margin, end up to
0.34 s after the vehicle starts to move (299 of 312 stops, development seeds 3600–3623, both laws; the
both-ways segments end 0.92–1.04 s before); 0.5 s covers that with 0.16 s to spare."""


def end_trimmed(seg: StaticSegment, t: np.ndarray, trim_s: float, min_duration_s: float) -> StaticSegment | None:
    """``seg`` (its samples' times ``t``) without its last ``trim_s`` seconds; None when less than
    ``min_duration_s`` is left."""
    j = int(np.searchsorted(t, t[-1] - trim_s, side="right"))  # samples at or before the new end
    if j < 1 or t[j - 1] - t[0] < min_duration_s:
        return None
    return StaticSegment(seg.t0, float(t[j - 1]), seg.i0, seg.i0 + j)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    e = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2], strict=True)]


def cut_segment(seg: Stop, t: np.ndarray, gate: np.ndarray, speed: tuple[np.ndarray, np.ndarray] | None, f: float,
                 cfg: DetectorConfig) -> tuple[list[Stop], list[str]]:
    """One detected segment cut by the rate gate and (with a speed) the online engine's stop check.

    ``t`` and ``gate`` are the segment's own samples (``seg.i0 .. seg.i1``), so the whole-log and the streamed
    path (which holds only the open stop) share this step; ``speed`` is the log's speed source (t [s],
    speed [m/s]), read at the segment's samples and ``stop_edge_s`` past either end (:func:`edge_verdict`).
    Returns the stops (log indices) and one line per cut."""
    from imunoise.online import OnlineConfig

    oc = OnlineConfig()
    min_len = cfg.min_duration_s * f + 1.0
    stops: list[Stop] = []
    dropped: list[str] = []
    pieces = [(seg.i0 + a, seg.i0 + b) for a, b in _runs(~gate)]
    if len(pieces) != 1 or pieces[0] != (seg.i0, seg.i1):
        dropped.append(f"{seg.t0:.2f}–{seg.t1:.2f} s: angular rate above the gate "
                       f"({math.degrees(cfg.gate_rate):.0f} °/s) in {int(gate.sum())} samples")
    for a, b in pieces:
        if b - a < min_len - 1e-9:
            continue
        tp = t[a - seg.i0 : b - seg.i0]
        ta, tb = float(tp[0]), float(tp[-1])
        if speed is None:
            stops.append(Stop(ta, tb, a, b))
            continue
        keep, why = edge_verdict(tp, speed, f, max_speed=oc.stop_max_speed, edge_s=oc.stop_edge_s,
                                 min_len=min_len)
        if why:
            dropped.append(why)
        for p, q in keep:
            stops.append(Stop(float(tp[p]), float(tp[q - 1]), a + p, a + q))
    return stops, dropped


def edge_verdict(t: np.ndarray, speed: tuple[np.ndarray, np.ndarray], f: float, *, max_speed: float, edge_s: float,
                 min_len: float) -> tuple[list[tuple[int, int]], str]:
    """The online engine's stop check (:func:`imunoise.online.stop_verdict`) of one piece of a stop, looking
    ``edge_s`` past both of its ends.

    Why past the ends: a stop's first and last samples are where motion leaks in (the detector's window lags
    a slow departure), and there the vehicle is still slower than ``max_speed``; the speed reached within
    ``edge_s`` after the end (or before the start) is what says the piece ran into the departure. So the check
    runs on the piece extended by ``edge_s`` at the sample rate on either side (speed read on the speed
    source's own time line), every sample within ``edge_s`` of a faster one is dropped, and the pieces of at
    least ``min_len`` samples are kept.

    Returns the kept (start, end) sample ranges of ``t`` and one line saying what was dropped ("" if nothing).
    """
    from imunoise.online import stop_verdict

    n = t.size
    e = int(round(edge_s * f))
    step = np.arange(1, e + 1) / f
    t_ext = np.concatenate([t[0] - step[::-1], t, t[-1] + step])
    v = speed_at(t_ext, speed)
    m = t_ext.size
    verdict = stop_verdict(v, np.zeros(m), np.isfinite(v), np.full(m, np.nan), rate_hz=f, max_speed=max_speed,
                           sigma_k=0.0, chi2=0.0, edge_s=edge_s, min_duration_s=0.0)
    kept = np.zeros(m, dtype=bool)
    for p, q in verdict.keep:
        kept[p:q] = True
    keep = [(p, q) for p, q in _runs(kept[e : e + n]) if q - p >= min_len - 1e-9]
    n_kept = sum(q - p for p, q in keep)
    if n_kept == n:
        return keep, ""
    ok = np.isfinite(v)
    j = int(np.argmax(np.where(ok, v, -np.inf)))
    where = "before its start" if j < e else "after its end" if j >= e + n else "inside it"
    vmax = float(v[j]) if ok.any() else math.nan
    return keep, (f"{t[0]:.2f}–{t[-1]:.2f} s: speed {vmax:.2f} m/s > {max_speed:g} m/s {where} (within "
                  f"{edge_s:g} s; {(n - n_kept) / f:.1f} s dropped)")


def _detection(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, cfg: DetectorConfig, f: float,
               both_ways: bool) -> Detection:
    """Both ways, or forward with each segment's end cut by :data:`STREAM_END_TRIM_S` (the streamed rule)."""
    if both_ways:
        return detect_static_both_ways(t, accel, gyro, cfg, rate_hz=f)
    det = detect_static(t, accel, gyro, cfg, rate_hz=f)
    segs = [s for seg in det.segments
            if (s := end_trimmed(seg, t[seg.slice], STREAM_END_TRIM_S, cfg.min_duration_s)) is not None]
    static = np.zeros(t.size, dtype=bool)
    for s in segs:
        static[s.slice] = True
    return replace(det, segments=segs, static=static)


def implausible_stops(ls: LogStops, max_per_min: float = MAX_STOPS_PER_MIN) -> str | None:
    """Why the stops of a log without a speed source look like cruising (None when they do not, or when the
    log has a speed): more than ``max_per_min`` stops per minute of log, and at least :data:`MIN_STOPS_CHECKED`.
    Where the noise while moving equals the noise at rest (a smooth ride, an IMU mounted on a damped plate),
    no IMU statistic tells a steady cruise from a stop; only a speed does."""
    if ls.log.speed is not None or not math.isfinite(max_per_min):
        return None
    n = len(ls.stops)
    minutes = ls.log.duration_s / 60.0
    if n < MIN_STOPS_CHECKED or minutes <= 0 or n / minutes <= max_per_min:
        return None
    return (f"{ls.log.name}: {n} stops in {minutes:.1f} min ({n / minutes:.2f} per minute, more than "
            f"{max_per_min:g}) without a speed source: steady cruising is taken for stops when the IMU is as quiet "
            "moving as at rest; give --gnss or --ref (a speed tells the stops from the cruise), or "
            "--max-stop-rate if these stops are real")


def speed_at(t: np.ndarray, speed: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Speed interpolated at ``t`` (NaN outside the speed's span); per sample, so any slice of a log gives
    the same values as the whole."""
    ts, vs = speed
    inside = (t >= ts[0]) & (t <= ts[-1])
    return np.where(inside, np.interp(t, ts, vs), np.nan)


def detect_stops(
    log: ImuLog,
    config: DetectorConfig | None = None,
    *,
    lambda0: float | None = None,
    learn_from_s: float | None = None,
    learn_s: float = LEARN_S,
    both_ways: bool = True,
) -> LogStops:
    """The stops of one log that are modelled (module docstring): λ_0 learned, detector, rate gate, speed check.

    Parameters
    ----------
    log : ImuLog
        The log.
    config : DetectorConfig, optional
        Detector settings; its ``lambda0`` is replaced by the learned one unless ``lambda0`` is given.
    lambda0 : float, optional
        A fixed λ_0 [m/s²] (no learning).
    learn_from_s : float, optional
        Learn λ_0 from the first this many seconds (a known stop at the start, as the online engine).
    learn_s : float
        Length of the quietest stretch λ_0 is learned from otherwise [s].
    both_ways : bool
        Detect forward and time-reversed (:func:`imunoise.detect.both_ways.detect_static_both_ways`, the
        default); False: forward only, each segment's end cut by :data:`STREAM_END_TRIM_S` more, as
        :func:`imunoise.calibrate.stream_stops` does (the same stops as a streamed log).

    Returns
    -------
    LogStops
    """
    base = config or DetectorConfig()
    t, accel, gyro, f = log.t, log.accel, log.gyro, log.rate_hz
    lam, src, why = choose_lambda0(t, accel, lambda: moving_std(gyro, base.window).max(axis=1), base.window, f,
                                    lambda0, learn_from_s, learn_s)
    if why is not None:
        det = _detection(t, accel, gyro, replace(base, lambda0=lam), f, both_ways)
        return LogStops(log, lam, src, det, [], [why])
    cfg = replace(base, lambda0=lam)
    det = _detection(t, accel, gyro, cfg, f, both_ways)
    stops: list[Stop] = []
    dropped: list[str] = []
    for seg in det.segments:
        kept, why = cut_segment(seg, t[seg.slice], det.gate_open[seg.slice], log.speed, f, cfg)
        stops += kept
        dropped += why
    return LogStops(log, lam, src, det, stops, dropped)
