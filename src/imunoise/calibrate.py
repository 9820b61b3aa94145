"""Calibrate an IMU from the moving logs people already have: the offline twin of the online engine (SPEC §7, §9).

:func:`calibrate` takes one or more logs of the same IMU (:func:`read_log`: a ROS bag, a table with a column
mapping and units, a KF-GINS increment file or a dataset folder), finds the stops in each
(:func:`detect_stops`), pools the static segments per axis into one wavelet variance, identifies the model
(:func:`imunoise.selection.select_model`, WVIC by default) and states what the stops can say.

Stops, per log (as the online engine does, with the same public pieces):

* λ_0 learned per log (:func:`imunoise.detect.learn_lambda0`, 2 × the median Eq. 9 statistic). The online
  engine learns it from the first seconds, which it assumes are a stop; a log picked from a drawer need not
  start still, so the default here learns it from the *quietest* ``learn_s`` seconds (the stretch with the
  smallest median statistic), which is the first stop when the log starts with one.
* the streaming detector over the whole log (:func:`imunoise.detect.detect_static`: adaptive threshold,
  ``margin_s`` trimmed at both ends, ``min_duration_s``), then the angular-rate gate: samples with
  ‖ω‖ > 30 °/s cut a segment (a turning vehicle is not at rest, whatever its accelerometers say).
* with a speed (a reference trajectory or GNSS), each segment goes through the online engine's stop check
  (:func:`imunoise.online.stop_verdict`): samples faster than ``OnlineConfig.stop_max_speed`` and their
  ``stop_edge_s`` neighbourhood are dropped.
* bias removed per segment (segment mean, SPEC §7); no wavelet coefficient spans two segments
  (:class:`imunoise.wv.WVAccumulator`).

The horizon. Pooled stops support scales up to the longest Haar scale τ_J with at least
:data:`imunoise.wv.MIN_COEFFICIENTS` coefficients; in averaging time T_h = τ_J/(2f)
(:func:`imunoise.equivalent_noise.default_horizon_s`). What that horizon determines, per axis
(:class:`AxisCalibration`):

* the white noise N (and QN, and Gauss–Markov terms with T_c ≤ T_h): values with CIs;
* the bias random walk K: a value only where the random walk rises above the white noise inside the horizon,
  i.e. the crossover averaging time T_x = √3·N/K (where N²/T = K²T/3) is ≤ T_h. Otherwise K is reported as a
  bound that holds for any model: K² ≤ 3·AV(T)/T at every T (the RW's Allan variance K²T/3 is part of the
  total, every other process adds to it), read on the upper limit of the WV's confidence band, K ≤
  min_j √(3·AV_hi(T_j)/T_j) (:func:`k_upper_bound`);
* a Gauss–Markov term with T_c > T_h, or a rate ramp: not determined (a slow AR1 and a random walk are two
  readings of the same rising curve on these scales); their effect is inside the K bound.

The exports (Kalibr, OpenVINS, ORB-SLAM3) follow the project's rules (:mod:`imunoise.export`): the (N, K) pair
matched over τ = update period .. horizon, K capped at the data's Allan bound, the τ range and the worst AV
ratio beside them. The dense Allan curve of the pooled stops is kept with each fit (``extra["data_allan"]``)
for that cap, as ``imunoise fit`` keeps that of its static record.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.detect import DetectorConfig, StaticSegment, detect_static, learn_lambda0, moving_std
from imunoise.errors import DataError, ModelError
from imunoise.imu import AXES

__all__ = [
    "MIN_STATIC_S",
    "LEARN_S",
    "STILL_CONTRAST",
    "RATE_TOLERANCE",
    "K_CI_SPAN",
    "ImuLog",
    "Stop",
    "LogStops",
    "AxisCalibration",
    "CalibrationResult",
    "read_log",
    "learn_lambda0_quietest",
    "detect_stops",
    "stream_stops",
    "k_upper_bound",
    "pooled_fit",
    "calibrate",
]

MIN_STATIC_S = 20.0
"""Pooled static time [s] needed before a model is identified (the online engine's ``min_static_s``): with
less the white noise rests on too few wavelet levels to be told from the rest."""

STILL_CONTRAST = 0.6
"""The quietest stretch counts as a stop only when its gyros are quiet too: median moving std of the gyros
there ≤ this × their 90th percentile over the log. Cruising vibration can quiet the accelerometers' Eq. 9
statistic to a stop's level, not the gyros' (simulator: 0.93 on a log without a stop; 0.32 on a drive
with stops, 0.30 on drive_0708)."""

LEARN_S = 10.0
"""Seconds of the quietest stretch λ_0 is learned from (the online engine's ``learn_lambda0_s``)."""

RATE_TOLERANCE = 0.01
"""Relative difference of sample rates above which two logs are not pooled (their densities differ)."""

K_CI_SPAN = 4.0
"""A fitted K is stated as a value only when its 95 % CI spans less than this factor (±2×); else as a bound."""

GYRO_UNIT, ACCEL_UNIT = "rad/s", "m/s²"


# --------------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------------
@dataclass(eq=False)
class ImuLog:
    """One moving IMU log in SI.

    Attributes
    ----------
    name : str
        Where it came from (for messages and the report).
    t : numpy.ndarray
        (n,) time [s], strictly increasing.
    gyro, accel : numpy.ndarray
        (n, 3) angular rate [rad/s] and specific force [m/s²], body axes x, y, z (x, y horizontal when level).
    rate_hz : float
        Nominal sample rate [Hz].
    speed : tuple of numpy.ndarray, optional
        (t [s], speed [m/s]) of a reference or GNSS in the same time base, for the stop check and the plot.
    meta : dict
        Source details (format, topic, warnings).
    span_s : tuple of float, optional
        (first, last) stamp [s] of a streamed log (:func:`stream_stops`), whose ``t`` is its per-second grid
        and whose ``gyro``/``accel`` are empty.
    """

    name: str
    t: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    rate_hz: float
    speed: tuple[np.ndarray, np.ndarray] | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    span_s: tuple[float, float] | None = None

    @property
    def duration_s(self) -> float:
        if self.span_s is not None:
            return float(self.span_s[1] - self.span_s[0])
        return float(self.t[-1] - self.t[0])


def _speed_of_reference(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    from imunoise.io.kfgins import read_reference

    ref = read_reference(path)
    return np.asarray(ref.t, dtype=float), np.linalg.norm(np.asarray(ref.vel_ned)[:, :2], axis=1)


def _speed_of_gnss(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal speed [m/s] from successive GNSS positions (local spherical Earth: metres per radian = R)."""
    from imunoise.io.navinput import read_nav_gnss

    g = read_nav_gnss(path)
    t = np.asarray(g.t, dtype=float)
    if t.size < 2:
        raise DataError(f"GNSS file {path}: fewer than 2 epochs, no speed can be formed")
    lat, lon = g.llh[:, 0], g.llh[:, 1]
    r = 6_371_000.0
    dn = np.diff(lat) * r
    de = np.diff(lon) * r * np.cos(0.5 * (lat[1:] + lat[:-1]))
    v = np.hypot(dn, de) / np.diff(t)
    return 0.5 * (t[1:] + t[:-1]), v


def read_log(
    path: str | Path,
    *,
    topic: str | None = None,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    time_column: str | int | None = None,
    time_unit: str = "s",
    freq: float | None = None,
    ref: str | Path | None = None,
    gnss: str | Path | None = None,
) -> ImuLog:
    """Read one moving log into an :class:`ImuLog` (SI, six axes).

    Parameters
    ----------
    path : str or Path
        A ROS bag (``.bag``, ``.db3``, ``.mcap``, ROS 2 folder; all six axes of ``topic``), a dataset folder
        with ``dataset.json`` (its IMU, and its reference for the speed), a KF-GINS IMU file (increments, or
        a rate CSV with ``sow,gx,..,az``), or a table/.npz whose columns map to ``gyro_x`` .. ``accel_z``.
    topic : str, optional
        Bag topic.
    columns, units, time_column, time_unit, freq
        As for :func:`imunoise.io.imu_input.read_imu_source` (tables): the six axes must be named.
    ref, gnss : str or Path, optional
        A KF-GINS reference (speed from its velocity) or a GNSS file (KF-GINS, RTKLIB .pos, bag; speed from
        successive positions), same time base as the IMU.

    Returns
    -------
    ImuLog
    """
    from imunoise.io.rosbag import is_bag

    p = Path(path)
    speed = None
    meta: dict[str, Any] = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if p.is_dir() and (p / "dataset.json").exists():
            from imunoise.io.dataset import read_dataset
            from imunoise.io.kfgins import read_imu

            ds = read_dataset(p, required=("imu",))
            imu = read_imu(ds.imu, time_offset=float(ds.imu_time_offset_s or 0.0))
            gyro, accel = imu.rates()
            t, rate = np.asarray(imu.t, dtype=float), float(imu.rate_hz)
            meta["format"] = "dataset"
            if ref is None and gnss is None and ds.ref:
                ref = ds.ref
            elif ref is None and gnss is None and getattr(ds, "gnss", None):
                gnss = ds.gnss
        elif is_bag(p) or columns is not None or p.suffix.lower() in (".npz", ".npy"):
            t, gyro, accel, rate, meta = _read_source(p, topic, columns, units, time_column, time_unit, freq)
        else:
            from imunoise.io.kfgins import read_imu

            imu = read_imu(p)
            gyro, accel = imu.rates()
            t, rate = np.asarray(imu.t, dtype=float), float(imu.rate_hz)
            meta["format"] = "kfgins"
        if ref is not None:
            speed = _speed_of_reference(ref)
            meta["speed_from"] = f"reference {ref}"
        elif gnss is not None:
            speed = _speed_of_gnss(gnss)
            meta["speed_from"] = f"GNSS {gnss}"
    msgs = list(dict.fromkeys(str(w.message) for w in caught))
    if msgs:
        meta["warnings"] = msgs
    return ImuLog(str(path), t, np.ascontiguousarray(gyro), np.ascontiguousarray(accel), rate, speed, meta)


def _read_source(p, topic, columns, units, time_column, time_unit, freq):
    from imunoise.io.imu_input import read_imu_source

    s = read_imu_source(p, topic=topic, columns=columns, units=units, time_column=time_column,
                        time_unit=time_unit, freq=freq)
    missing = [a for a in AXES if a not in s.data]
    if missing:
        raise DataError(
            f"{p}: calibrate needs all six axes, {', '.join(missing)} missing (have {', '.join(s.data)}); map "
            "them with --columns gyro_x=COL,...,accel_z=COL and give --units gyro=...,accel=..."
        )
    for a in AXES:
        want = GYRO_UNIT if a.startswith("gyro") else ACCEL_UNIT
        if s.unit[a] not in (want, "m/s2", "m/s^2") and not (want == ACCEL_UNIT and s.unit[a] in ("m/s2",)):
            raise DataError(f"{p}: axis {a} is in {s.unit[a]!r}, not {want}; give --units gyro=...,accel=...")
    n = len(s)
    t = np.asarray(s.t, dtype=float) if s.t is not None else np.arange(n) / float(s.freq)
    gyro = np.column_stack([s.data[a] for a in AXES[:3]])
    accel = np.column_stack([s.data[a] for a in AXES[3:]])
    meta = {k: v for k, v in s.meta.items() if k in ("format", "topic", "frame_id", "frame")}
    return t, gyro, accel, float(s.freq), meta


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


def _choose_lambda0(t: np.ndarray, accel: np.ndarray, G: Callable[[], np.ndarray], window: int, f: float,
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


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    e = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2], strict=True)]


def _cut_segment(seg: Stop, t: np.ndarray, gate: np.ndarray, speed: np.ndarray | None, f: float,
                 cfg: DetectorConfig) -> tuple[list[Stop], list[str]]:
    """One detected segment cut by the rate gate and (with a speed) the online engine's stop check.

    ``t``, ``gate`` and ``speed`` are the segment's own samples (``seg.i0 .. seg.i1``), so the whole-log and
    the streamed path (which holds only the open stop) share this step. Returns the stops (log indices) and
    one line per cut."""
    from imunoise.online import OnlineConfig, stop_verdict

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
        ta, tb = float(t[a - seg.i0]), float(t[b - 1 - seg.i0])
        if speed is None:
            stops.append(Stop(ta, tb, a, b))
            continue
        v = speed[a - seg.i0 : b - seg.i0]
        n = b - a
        verdict = stop_verdict(v, np.zeros(n), np.isfinite(v), np.full(n, np.nan), rate_hz=f,
                               max_speed=oc.stop_max_speed, sigma_k=0.0, chi2=0.0, edge_s=oc.stop_edge_s,
                               min_duration_s=cfg.min_duration_s)
        if not verdict.whole:
            dropped.append(f"{ta:.2f}–{tb:.2f} s: {verdict.reason.replace(' while GNSS-aided', '')}"
                           f" ({sum(q - p for p, q in verdict.drop) / f:.1f} s dropped)")
        for p, q in verdict.keep:
            stops.append(Stop(float(t[a + p - seg.i0]), float(t[a + q - 1 - seg.i0]), a + p, a + q))
    return stops, dropped


def _speed_at(t: np.ndarray, speed: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
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

    Returns
    -------
    LogStops
    """
    base = config or DetectorConfig()
    t, accel, gyro, f = log.t, log.accel, log.gyro, log.rate_hz
    lam, src, why = _choose_lambda0(t, accel, lambda: moving_std(gyro, base.window).max(axis=1), base.window, f,
                                    lambda0, learn_from_s, learn_s)
    if why is not None:
        det = detect_static(t, accel, gyro, replace(base, lambda0=lam), rate_hz=f)
        return LogStops(log, lam, src, det, [], [why])
    cfg = replace(base, lambda0=lam)
    det = detect_static(t, accel, gyro, cfg, rate_hz=f)
    speed = None if log.speed is None else _speed_at(t, log.speed)
    stops: list[Stop] = []
    dropped: list[str] = []
    for seg in det.segments:
        sp = None if speed is None else speed[seg.slice]
        kept, why = _cut_segment(seg, t[seg.slice], det.gate_open[seg.slice], sp, f, cfg)
        stops += kept
        dropped += why
    return LogStops(log, lam, src, det, stops, dropped)


# --------------------------------------------------------------------------------------------------
# the streamed path (logs too large to hold)
# --------------------------------------------------------------------------------------------------
class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _stream_order(blocks: Any) -> list[int]:
    """Column of each of :data:`AXES` in the blocks, with :func:`_read_source`'s checks of axes and units."""
    missing = [a for a in AXES if a not in blocks.axes]
    if missing:
        raise DataError(
            f"{blocks.source}: calibrate needs all six axes, {', '.join(missing)} missing (have "
            f"{', '.join(blocks.axes)}); map them with --columns gyro_x=COL,...,accel_z=COL and give --units "
            "gyro=...,accel=..."
        )
    for a in AXES:
        want = GYRO_UNIT if a.startswith("gyro") else ACCEL_UNIT
        if blocks.unit[a] not in (want, "m/s2", "m/s^2"):
            raise DataError(f"{blocks.source}: axis {a} is in {blocks.unit[a]!r}, not {want}; give --units "
                            "gyro=...,accel=...")
    return [blocks.axes.index(a) for a in AXES]


def _si_blocks(blocks: Any, freq: float | None) -> Any:
    """``(t, gyro, accel, advance)`` per block of :func:`imunoise.io.imu_stream.open_imu_blocks`: the stamps
    the whole-file reader keeps (or i/f without a time source), repeated stamps dropped (the first kept, as it
    does), increments times the rate."""
    from imunoise.io.imu_stream import StreamOrderError

    order = _stream_order(blocks)
    inc = np.array(blocks.increment, dtype=bool)[order]
    f = float(freq) if freq else blocks.freq
    if inc.any() and f is None:
        raise DataError(f"{blocks.source}: increments without a known rate cannot be streamed; give --freq")
    last = None
    n = 0
    for vals, t_rel, t_abs, adv in blocks.blocks:
        vals = vals[:, order]
        if t_rel is not None and t_rel.size:
            d = np.diff(t_rel, prepend=t_rel[0] if last is None else last)
            if (d < 0).any():
                raise StreamOrderError(f"{blocks.source}: the time stamps go back near sample {n}; a stream keeps "
                                       "the file order — run without --stream (the whole-file path sorts them)")
            keep = d != 0
            keep[0] = keep[0] or last is None
            last = float(t_rel[-1])
            vals, t = vals[keep], t_abs[keep]
        elif t_rel is None:
            t = (n + np.arange(vals.shape[0])) / float(f)
        else:
            t = np.zeros(0)
        if inc.any():
            vals = vals.copy()
            vals[:, inc] *= f
        n += t.size
        if t.size:
            yield t, np.ascontiguousarray(vals[:, :3]), np.ascontiguousarray(vals[:, 3:]), adv
        else:
            yield t, np.zeros((0, 3)), np.zeros((0, 3)), adv


def _gyro_std_stream(window: int) -> Callable[[np.ndarray], np.ndarray]:
    """The gyros' moving std, max over the axes, of a stream of (m, 3) chunks: :func:`moving_std`'s kernel fed
    in chunks (the detector's statistic is chunk-invariant), one float per sample out."""
    from imunoise.detect import StaticDetector

    cfg = DetectorConfig(window=window, lambda0=1.0, adaptive=False)
    pair, single = StaticDetector(cfg, 1.0), StaticDetector(cfg, 1.0)
    n = [0]

    def feed(g: np.ndarray) -> np.ndarray:
        m = g.shape[0]
        idx = np.arange(n[0], n[0] + m, dtype=float)  # moving_std's time base: no gap ever restarts the window
        n[0] += m
        z = np.zeros((m, 3))
        a = pair.push_chunk(idx, np.column_stack([g[:, 0], g[:, 1], z[:, 0]]), z).statistic
        b = single.push_chunk(idx, np.column_stack([g[:, 2], g[:, 2], z[:, 0]]), z).statistic
        return np.maximum(np.maximum(a[:, 0], a[:, 1]), b[:, 0])

    return feed


class _PerSecond:
    """The detector's per-epoch output reduced to bins of ``d`` samples (for the report's figure): first time,
    max statistic per axis, min threshold, any static, any gate."""

    def __init__(self, d: int):
        self.d = d
        self.carry: list[np.ndarray] = []
        self.out: list[np.ndarray] = []

    def add(self, t: np.ndarray, stat: np.ndarray, lam: np.ndarray, st: np.ndarray, gate: np.ndarray) -> None:
        rows = np.column_stack([t, stat, lam, st, gate])
        c = np.concatenate(self.carry + [rows]) if self.carry else rows
        k = c.shape[0] // self.d * self.d
        if k:
            self.out.append(self._reduce(c[:k].reshape(-1, self.d, 6)))
        self.carry = [c[k:]] if k < c.shape[0] else []

    @staticmethod
    def _reduce(b: np.ndarray) -> np.ndarray:
        return np.column_stack([b[:, 0, 0], np.fmax.reduce(b[:, :, 1], axis=1), np.fmax.reduce(b[:, :, 2], axis=1),
                                b[:, :, 3].min(axis=1), b[:, :, 4].max(axis=1), b[:, :, 5].max(axis=1)])

    def series(self) -> np.ndarray:
        parts = self.out + [self._reduce(c[None]) for c in self.carry]
        return np.concatenate(parts) if parts else np.zeros((0, 6))


def stream_stops(
    path: str | Path,
    config: DetectorConfig | None = None,
    *,
    lambda0: float | None = None,
    learn_from_s: float | None = None,
    learn_s: float = LEARN_S,
    topic: str | None = None,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    time_column: str | int | None = None,
    time_unit: str = "s",
    freq: float | None = None,
    ref: str | Path | None = None,
    gnss: str | Path | None = None,
    progress: Callable[[str, int, str], Any] | None = None,
) -> LogStops:
    """:func:`read_log` + :func:`detect_stops` of a bag or table too large to hold, in two passes over
    :func:`imunoise.io.imu_stream.open_imu_blocks` (same stops and stop samples as the whole-log path).

    Pass 1 holds, per sample, the stamp and accel x, y (the rate is the whole-file reader's rule over all the
    stamps; λ_0 is learned exactly as :func:`learn_lambda0_quietest` does, on the quietest ``learn_s`` seconds,
    or from the first ``learn_from_s`` s) and, for the quietest rule, the gyros' moving std: 4 float64 per
    sample (32 B, briefly twice that while the blocks' parts are joined; measured 54 B per sample on a CSV,
    the whole-log path ≈ 1.2 kB), freed before pass 2; the block reader adds a constant (≈ 100 MB for 65536-line
    CSV blocks). Pass 2 feeds the blocks to the
    streaming :class:`imunoise.detect.StaticDetector` and holds only the samples of the open raw static run (the
    candidate stop with its trimming margin); when a segment closes it is cut as :func:`detect_stops` cuts it
    (rate gate, speed check) and its samples are kept, 6 float64 per sample *of a modelled stop* (pooled WV and
    the dense Allan curve of the exports' cap). The detection for the report is kept per second
    (:class:`imunoise.detect.Detection` on that grid; ``log.t`` is the grid, ``log.span_s`` the first and last
    stamp). Stamps must be in time order (:class:`imunoise.io.imu_stream.StreamOrderError` otherwise).

    Parameters
    ----------
    path : str or Path
        A ROS bag or a table (CSV/TXT, .npy, .npz) whose columns map to ``gyro_x`` .. ``accel_z``.
    config, lambda0, learn_from_s, learn_s
        As for :func:`detect_stops`.
    topic, columns, units, time_column, time_unit, freq, ref, gnss
        As for :func:`read_log`.
    progress : callable, optional
        ``progress(desc, total, unit)`` returning a bar with ``update(n)`` and ``close()`` (e.g. tqdm), one per
        pass.

    Returns
    -------
    LogStops
        With ``samples`` (the stops' samples) set.
    """
    from imunoise.detect import Detection, StaticDetector
    from imunoise.io.imu_stream import open_imu_blocks
    from imunoise.io.tabular import clean_time

    base = config or DetectorConfig()
    bar_of = progress or (lambda desc, total, unit: _NoBar())
    src_args = dict(topic=topic, columns=columns, units=units, time_column=time_column, time_unit=time_unit,
                    freq=freq)
    need_g = lambda0 is None and learn_from_s is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        blocks = open_imu_blocks(path, **src_args)
        meta: dict[str, Any] = {k: v for k, v in blocks.meta.items() if k in ("format", "topic", "frame_id", "frame")}
        ts, axy, gs = [], [], []
        g_of = _gyro_std_stream(base.window)
        bar = bar_of("scanning", blocks.size, blocks.size_unit)
        try:
            for t, gyro, accel, adv in _si_blocks(blocks, freq):
                ts.append(t)
                axy.append(accel[:, :2].copy())
                if need_g and t.size:
                    gs.append(g_of(gyro))
                bar.update(adv)
        finally:
            bar.close()
        t_all = np.concatenate(ts) if ts else np.zeros(0)
        if t_all.size < 2:
            raise DataError(f"{path}: fewer than 2 samples")
        if blocks.time_source is not None or blocks.meta.get("_time_source"):
            _, report = clean_time(t_all - t_all[0], source=str(path), freq=freq)
            f = float(freq) if freq else float(report.rate_hz)
        else:
            f = float(freq) if freq else float(blocks.freq)
        accel_xy = np.concatenate(axy)
        del ts, axy
        lam, src, why = _choose_lambda0(t_all, accel_xy, lambda: np.concatenate(gs), base.window, f, lambda0,
                                        learn_from_s, learn_s)
        span = (float(t_all[0]), float(t_all[-1]))
        del t_all, accel_xy
        gs.clear()
        speed = None
        if ref is not None:
            speed = _speed_of_reference(ref)
            meta["speed_from"] = f"reference {ref}"
        elif gnss is not None:
            speed = _speed_of_gnss(gnss)
            meta["speed_from"] = f"GNSS {gnss}"

        cfg = replace(base, lambda0=lam)
        sd = StaticDetector(cfg, f)
        per_s = _PerSecond(max(int(round(f)), 1))
        stops: list[Stop] = []
        dropped: list[str] = [] if why is None else [why]
        samples: list[np.ndarray] = []
        segments: list[StaticSegment] = []
        bt, bx, bg = np.zeros(0), np.zeros((0, 6)), np.zeros(0, dtype=bool)
        buf0 = 0

        def close(segs: list[StaticSegment]) -> None:
            for seg in segs:
                segments.append(seg)
                if why is not None:
                    continue  # no usable stop (λ0 from a stretch that is not still): the detection only
                lo, hi = seg.i0 - buf0, seg.i1 - buf0
                sp = None if speed is None else _speed_at(bt[lo:hi], speed)
                kept, cut = _cut_segment(seg, bt[lo:hi], bg[lo:hi], sp, f, cfg)
                stops.extend(kept)
                dropped.extend(cut)
                samples.extend(bx[s.i0 - buf0 : s.i1 - buf0].copy() for s in kept)

        blocks = open_imu_blocks(path, **src_args)
        bar = bar_of("detecting stops", blocks.size, blocks.size_unit)
        try:
            for t, gyro, accel, adv in _si_blocks(blocks, freq):
                bar.update(adv)
                if not t.size:
                    continue
                first = sd.n_samples
                cd = sd.push_chunk(t, accel, gyro)
                per_s.add(t, cd.statistic, cd.threshold, cd.static_raw, cd.gate_open)
                bt = np.concatenate([bt, t])
                bx = np.concatenate([bx, np.hstack([gyro, accel])])
                bg = np.concatenate([bg, cd.gate_open])
                close(cd.segments)
                # keep only the open raw static run: a segment lies inside its run, trimmed
                if cd.static_raw[-1]:
                    off = np.flatnonzero(~cd.static_raw)
                    keep_from = first + int(off[-1]) + 1 if off.size else buf0
                else:
                    keep_from = sd.n_samples
                bt, bx, bg = bt[keep_from - buf0 :], bx[keep_from - buf0 :], bg[keep_from - buf0 :]
                buf0 = keep_from
            close(sd.finish())
        finally:
            bar.close()
    msgs = list(dict.fromkeys(str(w.message) for w in caught))
    if msgs:
        meta["warnings"] = msgs
    meta["streamed"] = {"n_samples": sd.n_samples, "figure_bin_samples": per_s.d}
    d = per_s.series()
    td = d[:, 0]
    static = np.zeros(td.size, dtype=bool)
    for seg in segments:
        static[np.searchsorted(td, seg.t0, "right") - 1 : np.searchsorted(td, seg.t1, "right")] = True
    det = Detection(t=td, statistic=d[:, 1:3], threshold=d[:, 3], static_raw=d[:, 4] > 0, static=static,
                    segments=segments, gate_open=d[:, 5] > 0, config=cfg)
    log = ImuLog(str(path), td, np.zeros((0, 3)), np.zeros((0, 3)), f, speed, meta, span_s=span)
    return LogStops(log, lam, src, det, stops, dropped, samples)


# --------------------------------------------------------------------------------------------------
# what the horizon determines
# --------------------------------------------------------------------------------------------------
def k_upper_bound(wv: Any) -> tuple[float, float]:
    """Upper bound on the random-walk density K [u/√s] that holds whatever else the sensor has.

    Any model's Allan variance is at least its random walk's, AV(T) ≥ K²T/3 (exact for the Haar form:
    AV(T) = 2ν²(2Tf) = γ²(4m² + 2)/(12m) ≥ γ²m/3 with m = Tf, K² = γ²f), so K ≤ √(3·AV(T)/T) at every
    averaging time; read on the upper limit of the WV's confidence band, the smallest over the levels.

    Parameters
    ----------
    wv : imunoise.wv.WaveletVariance
        The pooled WV (with its chi-square band).

    Returns
    -------
    (float, float)
        The bound [u/√s] and the averaging time T [s] where it is reached.
    """
    T = np.asarray(wv.scales, dtype=float) / (2.0 * float(wv.freq))
    av_hi = 2.0 * np.asarray(wv.ci_high, dtype=float)
    k = np.sqrt(3.0 * av_hi / T)
    j = int(np.nanargmin(k))
    return float(k[j]), float(T[j])


@dataclass(frozen=True)
class AxisCalibration:
    """What the pooled stops say about one axis (module docstring).

    Attributes
    ----------
    axis, unit : str
        Axis name and SI unit of the rate.
    model : str
        The selected structure.
    N : float
        White-noise density as exported [u/√Hz].
    N_ci : tuple of float
        95 % CI of N when N is the model's WN term alone (NaN otherwise, or without a CI).
    K : float
        Random-walk density as exported [u/s/√Hz] (the export's matched, capped value; read ``K_status``).
    K_status : str
        ``"value"`` (the model's RW rises above the white noise inside the horizon and its 95 % CI spans
        less than a factor :data:`K_CI_SPAN`) or ``"bound"``.
    K_fit : float
        The model's own RW density [u/s/√Hz] (0 when it has none): the value when ``K_status`` is ``"value"``.
    K_ci : tuple of float
        95 % CI of the model's RW density (NaN when none).
    K_bound : float
        Upper bound on K that holds for any model (:func:`k_upper_bound`), at ``K_bound_at_s``.
    K_bound_at_s : float
        Averaging time of that bound [s].
    crossover_s : float
        T_x = √3·N/K: where the random walk would overtake the white noise [s].
    horizon_s : float
        Longest averaging time the stops support [s].
    tau_range_s : tuple of float
        Averaging times the exported pair is matched on [s].
    worst_ratio : float
        Worst factor between the pair's AV and the fitted **model's** there (not the data's: ``pair_data``).
    determined, undetermined : tuple of str
        Per process of the model: what the horizon determines, and what it does not (with why).
    band : imunoise.fitting.quality.BandCheck
        The fitted model's WV against the pooled WV's 95 % band (``refused``: outside over a range of scales).
    pair_data : imunoise.fitting.quality.PairCheck
        The exported pair's AV against the **data's** AV and its band over ``tau_range_s``.
    retry : str, optional
        What the selection's richer candidates gave when the selected structure left the band.
    """

    axis: str
    unit: str
    model: str
    N: float
    N_ci: tuple[float, float]
    K: float
    K_status: str
    K_fit: float
    K_ci: tuple[float, float]
    K_bound: float
    K_bound_at_s: float
    crossover_s: float
    horizon_s: float
    tau_range_s: tuple[float, float] | None
    worst_ratio: float
    determined: tuple[str, ...]
    undetermined: tuple[str, ...]
    band: Any = None
    pair_data: Any = None
    retry: str | None = None

    @property
    def refused(self) -> bool:
        """The fit leaves its WV band over a range of scales (:class:`imunoise.fitting.quality.BandCheck`):
        an export is refused without ``--force``."""
        return bool(self.band is not None and self.band.refused)

    @property
    def K_reported(self) -> float:
        """K as a value when determined, else the bound."""
        return self.K_fit if self.K_status == "value" else self.K_bound

    def to_dict(self) -> dict[str, Any]:
        return {
            "axis": self.axis, "unit": self.unit, "model": self.model,
            "N": self.N, "N_ci": list(self.N_ci), "K": self.K, "K_status": self.K_status, "K_fit": self.K_fit,
            "K_ci": list(self.K_ci),
            "K_bound": self.K_bound, "K_bound_at_s": self.K_bound_at_s, "crossover_s": self.crossover_s,
            "horizon_s": self.horizon_s, "tau_range_s": list(self.tau_range_s) if self.tau_range_s else None,
            "worst_av_ratio": self.worst_ratio, "worst_av_ratio_against": "the fitted model",
            "determined": list(self.determined), "undetermined": list(self.undetermined),
            "band": self.band.to_dict() if self.band is not None else None,
            "pair_vs_data": self.pair_data.to_dict() if self.pair_data is not None else None,
            "retry": self.retry, "export_refused": self.refused,
        }


def _axis_calibration(axis: str, fit: Any) -> AxisCalibration:
    from imunoise.equivalent_noise import default_horizon_s
    from imunoise.export import axis_noise
    from imunoise.fitting.quality import band_check, pair_check

    h = float(default_horizon_s(fit))
    a = axis_noise(fit, axis)
    ci = fit.confidence_intervals()
    cont = fit.continuous()
    nan2 = (math.nan, math.nan)
    N_ci = ci.get("WN.noise_density", nan2)
    if not math.isclose(cont.get("WN.noise_density", math.nan), a.N, rel_tol=1e-6):
        N_ci = nan2  # N holds more than the WN term (QN, fast AR1): the term's CI is not N's
    K_ci = ci.get("RW.random_walk", nan2)
    kb, kb_at = k_upper_bound(fit.wv)
    has_rw = any(c.reading == "random_walk" for c in fit.model.components)
    det, und = [], []
    for name, c in zip(fit.model.component_names(), fit.model.components):
        own = {k: v for k, v in cont.items() if k.startswith(name + ".")}
        if c.reading == "white":
            det += [f"{k} = {v:.4g}" for k, v in own.items()]
        elif c.reading == "gauss_markov":
            v = own[f"{name}.tau_c"]
            if v <= h:
                det.append(f"{name}: T_c = {v:.4g} s ≤ horizon {h:.3g} s, σ_GM = {own[name + '.sigma_gm']:.4g}")
            else:
                und.append(f"{name}: T_c = {v:.4g} s beyond the horizon {h:.3g} s (a slow Gauss–Markov term reads "
                           f"as a random walk there): not a value; inside K ≤ {kb:.3g}")
        elif c.reading == "ramp":
            und += [f"{k}: a ramp over {h:.3g} s is a reading of the rising WV, not a value; inside K ≤ {kb:.3g}"
                    for k in own]
    k_fit = a.K_rw
    tx = math.sqrt(3.0) * a.N / k_fit if k_fit > 0 else math.inf
    narrow = math.isfinite(K_ci[0]) and K_ci[0] > 0 and K_ci[1] / K_ci[0] <= K_CI_SPAN
    status = "value" if (has_rw and tx <= h and narrow) else "bound"
    if status == "value":
        det.append(f"K = {k_fit:.4g} (random walk above the white noise from T = {tx:.3g} s ≤ horizon {h:.3g} s)")
    else:
        if not has_rw:
            why = "no random walk in the model up to the horizon"
        elif tx > h:
            why = f"the random walk would overtake the white noise only at T = {tx:.3g} s > horizon {h:.3g} s"
        else:
            why = f"its 95 % CI spans more than a factor {K_CI_SPAN:g}"
        und.append(f"K: {why}; K ≤ {kb:.3g} (the WV band's bound at T = {kb_at:.3g} s)")
    band = band_check(fit.wv, fit.theoretical_wv)
    pair = pair_check(fit.wv, a.N, a.K, a.tau_range_s)
    retry = (fit.extra.get("fit_check") or {}).get("note")
    return AxisCalibration(axis, fit.unit, str(fit.model), a.N, tuple(N_ci), a.K, status, k_fit, tuple(K_ci), kb, kb_at,
                           tx, h, a.tau_range_s, a.worst_ratio, tuple(det), tuple(und), band, pair, retry)


# --------------------------------------------------------------------------------------------------
# the calibration
# --------------------------------------------------------------------------------------------------
@dataclass(eq=False)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    logs : list of LogStops
        Per log: λ_0, the detection, the stops modelled and what was dropped.
    fits : dict
        Per axis the selected :class:`~imunoise.estimator.GMWMFit` (parameters per sample at ``freq_hz``).
    axes : dict
        Per axis the :class:`AxisCalibration`.
    model : imunoise.imu_model.ImuModel
        The six fits as one model (``imu_model.json``; the input of the exports).
    freq_hz : float
        Sample rate [Hz].
    criterion : str
        Selection criterion.
    """

    logs: list[LogStops]
    fits: dict[str, Any]
    axes: dict[str, AxisCalibration]
    model: Any
    freq_hz: float
    criterion: str

    @property
    def static_s(self) -> float:
        """Pooled static time [s]."""
        return float(sum(ls.static_s for ls in self.logs))

    @property
    def n_stops(self) -> int:
        return int(sum(len(ls.stops) for ls in self.logs))

    @property
    def horizon_s(self) -> float:
        """Longest averaging time the pooled stops support [s] (the same on every axis)."""
        return float(max(a.horizon_s for a in self.axes.values()))

    @property
    def longest_stop_s(self) -> float:
        return float(max((s.duration for ls in self.logs for s in ls.stops), default=0.0))

    def summary(self) -> str:
        """Stops, horizon and a table of N and K per axis (values, CIs, bounds)."""
        lines = [
            f"calibration from {len(self.logs)} log(s): {self.n_stops} stops, {self.static_s:.1f} s static "
            f"(longest {self.longest_stop_s:.1f} s) at {self.freq_hz:g} Hz; criterion {self.criterion}",
            f"horizon: averaging times up to {self.horizon_s:.3g} s are supported by the pooled stops",
        ]
        for ls in self.logs:
            lines.append(f"  {ls.log.name}: {ls.log.duration_s:.1f} s, λ0 = {ls.lambda0:.4g} m/s² "
                         f"({ls.lambda0_source}); {len(ls.stops)} stops, {ls.static_s:.1f} s")
        lines += ["", f"  {'axis':<9}{'model':<20}{'N [u/√Hz]':>12}  {'95% CI':^23}  {'K [u/s/√Hz]':>12}  "
                  f"{'K is':<6}{'K bound':>11}  {'T_x [s]':>8}  unit"]
        for ax, a in self.axes.items():
            nci = f"[{a.N_ci[0]:.3e}, {a.N_ci[1]:.3e}]" if math.isfinite(a.N_ci[0]) else "—"
            lines.append(f"  {ax:<9}{a.model:<20}{a.N:>12.4e}  {nci:^23}  {a.K_reported:>12.4e}  {a.K_status:<6}"
                         f"{a.K_bound:>11.3e}  {a.crossover_s:>8.3g}  {a.unit}")
        lines.append("  K: the fitted random walk when it is a value, else the bound that holds (exports: see "
                     "their τ range and AV ratio)")
        lines.append("")
        for ax, a in self.axes.items():
            for u in a.undetermined:
                lines.append(f"  {ax}: not determined: {u}")
        lines += ["", "fit against the data (export refused without --force where the fit leaves its WV band over "
                  "a range of scales):"]
        for ax, a in self.axes.items():
            if a.band is None:
                continue
            tag = "REFUSED" if a.refused else "ok"
            lines.append(f"  {ax:<9}{tag:<8}{a.model}: {a.band.text()}")
            lines.append(f"  {'':<17}{a.pair_data.text()}; pair/model AV: worst {a.worst_ratio:.3g}×")
            if a.retry:
                lines.append(f"  {'':<17}{a.retry}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (stops, λ_0, horizon, per-axis values and bounds)."""
        return {
            "freq_hz": self.freq_hz,
            "criterion": self.criterion,
            "static_s": self.static_s,
            "n_stops": self.n_stops,
            "horizon_s": self.horizon_s,
            "logs": [
                {"name": ls.log.name, "duration_s": ls.log.duration_s, "lambda0_m_s2": ls.lambda0,
                 "lambda0_source": ls.lambda0_source, "static_s": ls.static_s, "dropped": ls.dropped,
                 "stops": [{"t0": s.t0, "t1": s.t1, "duration_s": s.duration} for s in ls.stops],
                 **({"warnings": ls.log.meta["warnings"]} if ls.log.meta.get("warnings") else {})}
                for ls in self.logs
            ],
            "axes": {ax: a.to_dict() for ax, a in self.axes.items()},
        }


def pooled_fit(
    segments: Sequence[np.ndarray],
    *,
    freq: float,
    unit: str = "u",
    complete: str | None = None,
    criterion: str = "wvic",
    weights: str = "efficient",
    seed: int = 0,
) -> Any:
    """The model of one axis from its pooled stops: WV pooled over the segments (no coefficient spans two),
    structure selected (:func:`imunoise.selection.select_model`), its parameters estimated as
    :func:`imunoise.estimator.gmwm` estimates a given structure, and a richer candidate where the selected one
    leaves the WV band (:func:`imunoise.fitting.quality.within_band`).

    Why the re-estimate: the selection fits every candidate on one Ω built from ν̂, which favours the levels
    whose estimate fell low; on drive_0708's accel_z the top level (τ = 20.5 s, 52 coefficients of one stop,
    ν̂ 1/3.7 of the WN line's) pulled that one-step WN estimate to N = 1.53e-3 while the WVIC had ranked WN
    at its likelihood estimate, N = 1.09e-2; iterated, N = 1.04e-2 (σ/√f of the stops 1.08e-2).

    Parameters
    ----------
    segments : sequence of numpy.ndarray
        The stops' samples of the axis, bias removed [u].
    freq : float
        Sample rate [Hz].
    unit, complete, criterion, weights, seed
        As for :func:`imunoise.selection.select_model`.

    Returns
    -------
    GMWMFit
        With ``extra["data_allan"]`` (dense Allan curve of the stops), ``data_span``, ``selection`` and
        ``fit_check`` (the band check and what the retry gave).
    """
    from imunoise.allan import allan_variance, curve_to_dict
    from imunoise.fitting.quality import within_band
    from imunoise.selection import select_model
    from imunoise.wv import WVAccumulator

    acc = WVAccumulator(freq=freq)
    for x in segments:
        acc.add(x)
    ranking = select_model(acc.result(), freq=freq, complete=complete, criterion=criterion, weights=weights,
                           unit=unit, seed=seed)
    settled = within_band(ranking)
    fit = settled.fit
    fit.extra["data_allan"] = curve_to_dict(allan_variance(list(segments), freq=freq, grid="dense"))
    fit.extra["data_span"] = {"n_samples": int(sum(x.size for x in segments)), "n_segments": len(segments)}
    fit.extra["selection"] = {"criterion": criterion, "n_candidates": len(ranking.fits), "selected": settled.selected}
    fit.extra["fit_check"] = settled.to_dict()
    return fit


def _same_samples(a: LogStops, b: LogStops) -> bool:
    """Two logs that hold the same samples (the same file under two names, or a copy): same rate, span and
    stops, and the same samples in their first stop."""
    if a.log.rate_hz != b.log.rate_hz or a.stops != b.stops or not a.stops:
        return False
    sa = a.log.span_s or (float(a.log.t[0]), float(a.log.t[-1]))
    sb = b.log.span_s or (float(b.log.t[0]), float(b.log.t[-1]))
    return sa == sb and all(np.array_equal(x, y) for x, y in zip(a.stop_samples(0)[:1], b.stop_samples(0)[:1],
                                                                    strict=True))


def _refuse_repeats(found: Sequence[LogStops]) -> None:
    """A log given twice would be pooled twice (its stops counted double, the CIs too narrow): refused."""
    seen: dict[str, str] = {}
    for ls in found:
        if not Path(ls.log.name).exists():
            continue  # a log built in memory: its name says nothing, its samples do (below)
        key = str(Path(ls.log.name).resolve())
        if key in seen:
            raise DataError(f"{ls.log.name} is given twice (also as {seen[key]}): a log is pooled once; drop the "
                            "repeat")
        seen[key] = ls.log.name
    for i, a in enumerate(found):
        for b in found[i + 1 :]:
            if _same_samples(a, b):
                raise DataError(f"{b.log.name} holds the same samples as {a.log.name} (same span and stops): a log "
                                "is pooled once; drop the copy")


def _topic_of(found: Sequence[LogStops]) -> dict[str, Any]:
    """The ROS topic the logs were read from, for the model's source and every export that names one
    (``{}`` for logs that are not bags). Bags read on different topics: the first log's, all of them beside it
    (``topics``) and a warning, since an export names one topic."""
    topics = list(dict.fromkeys(t for ls in found if (t := ls.log.meta.get("topic"))))
    if not topics:
        return {}
    if len(topics) > 1:
        from imunoise.io.kfgins import DataWarning

        warnings.warn(f"the logs were read on {len(topics)} topics ({', '.join(topics)}); the exports name the "
                      f"first, {topics[0]}: edit rostopic where the tool reads another", DataWarning, stacklevel=3)
        return {"topic": topics[0], "topics": topics}
    return {"topic": topics[0]}


def _no_stop_error(ls: LogStops, need_s: float) -> DataError:
    det = ls.detection
    found = f"{ls.dropped[0]}; " if ls.dropped and "no stop" in ls.dropped[0] else ""
    return DataError(
        f"{ls.log.name}: no usable stop: {found}{det.static_time_s:.1f} s called static by the detector "
        f"({len(det.segments)} segments ≥ {det.config.min_duration_s:g} s, λ0 = {ls.lambda0:.3g} m/s²), "
        f"{ls.static_s:.1f} s left after the rate gate and the speed check, in {ls.log.duration_s:.0f} s of log; "
        f"calibrate needs ≥ {need_s:g} s of pooled stops for the white noise N, and stops several times "
        "longer than an averaging time to state K there; pool more logs or record stops"
    )


def calibrate(
    logs: Sequence[ImuLog | str | Path],
    *,
    detector: DetectorConfig | None = None,
    lambda0: float | None = None,
    learn_from_s: float | None = None,
    learn_s: float = LEARN_S,
    criterion: str = "wvic",
    complete: str | None = None,
    weights: str = "efficient",
    min_static_s: float = MIN_STATIC_S,
    seed: int = 0,
    progress: Callable[[Any, str], Any] | None = None,
) -> CalibrationResult:
    """Noise model of an IMU from the stops of its moving logs (module docstring).

    Parameters
    ----------
    logs : sequence of ImuLog, LogStops, str or Path
        Logs of the same IMU (paths are read with :func:`read_log`'s defaults; a :class:`LogStops`, e.g. from
        :func:`stream_stops`, is taken as detected); pooled.
    detector : DetectorConfig, optional
        Detector settings (its λ_0 is learned per log unless ``lambda0`` is given).
    lambda0 : float, optional
        Fixed λ_0 [m/s²] for every log.
    learn_from_s : float, optional
        Learn λ_0 from the first this many seconds of each log (a known stop there).
    learn_s : float
        Length of the quietest stretch λ_0 is learned from [s] (default).
    criterion : {"wvic", "gof"}
        Selection criterion (:func:`imunoise.selection.select_model`).
    complete : str, optional
        Largest structure searched (default the paper's 4*AR1+DR+WN+QN+RW).
    weights : str
        Ω of the GMWM.
    min_static_s : float
        Pooled static time needed [s].
    seed : int
        Seed of the random starts of the selection.
    progress : callable, optional
        ``progress(iterable, desc)`` wrapping the per-log and per-axis loops (e.g. a tqdm factory).

    Returns
    -------
    CalibrationResult

    Raises
    ------
    DataError
        A log without a usable stop, too little pooled static time, or logs at different rates.
    """
    from imunoise.imu_model import ImuModel

    if not logs:
        raise DataError("calibrate needs at least one log")
    wrap = progress or (lambda it, desc: it)
    found: list[LogStops] = []
    for item in wrap(list(logs), "logs"):
        if isinstance(item, LogStops):  # detected already (a streamed log, :func:`stream_stops`)
            found.append(item)
            continue
        log = item if isinstance(item, ImuLog) else read_log(item)
        found.append(detect_stops(log, detector, lambda0=lambda0, learn_from_s=learn_from_s, learn_s=learn_s))
    for ls in found:
        if not ls.stops:
            raise _no_stop_error(ls, min_static_s)
    f = found[0].log.rate_hz
    for ls in found[1:]:
        if abs(ls.log.rate_hz - f) > RATE_TOLERANCE * f:
            raise DataError(f"{ls.log.name} is at {ls.log.rate_hz:.4g} Hz, {found[0].log.name} at {f:.4g} Hz: "
                            "logs of different rates cannot be pooled (the densities are per rate); resample one")
    total = sum(ls.static_s for ls in found)
    if total < min_static_s:
        parts = ", ".join(f"{ls.log.name}: {ls.static_s:.1f} s in {len(ls.stops)} stops" for ls in found)
        raise DataError(f"only {total:.1f} s of stops pooled ({parts}); calibrate needs ≥ {min_static_s:g} s for the "
                        "white noise N, and stops several times longer than an averaging time to state K there; "
                        "pool more logs")
    _refuse_repeats(found)
    fits: dict[str, Any] = {}
    for k, axis in enumerate(wrap(list(AXES), "axes")):
        segs = [x - x.mean() for ls in found for x in ls.stop_samples(k)]  # bias removed per stop (SPEC §7)
        unit = GYRO_UNIT if k < 3 else ACCEL_UNIT
        fits[axis] = pooled_fit(segs, freq=f, unit=unit, complete=complete, criterion=criterion, weights=weights,
                                seed=seed)
    axes = {ax: _axis_calibration(ax, fit) for ax, fit in fits.items()}
    source = {
        "calibrate": [ls.log.name for ls in found],
        "freq_hz": f,
        "static_s": total,
        "n_stops": int(sum(len(ls.stops) for ls in found)),
        "horizon_s": float(max(a.horizon_s for a in axes.values())),
        **_topic_of(found),
    }
    if source.get("topic"):
        for fit in fits.values():  # a single fit exported later names the topic too
            fit.extra["topic"] = source["topic"]
    model = ImuModel.from_fits(fits, source=source)
    return CalibrationResult(found, fits, axes, model, f, criterion)
