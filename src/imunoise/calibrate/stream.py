"""The stops of a log too large to hold, streamed block by block in two passes
(docs/guide/theory.rst, 'Static detection' and 'Online engine';
:func:`stream_stops`)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.calibrate.logs import ACCEL_UNIT, GYRO_UNIT, ImuLog, speed_of_gnss, speed_of_reference
from imunoise.calibrate.stops import (
    LEARN_S,
    STREAM_END_TRIM_S,
    LogStops,
    Stop,
    choose_lambda0,
    cut_segment,
    end_trimmed,
)
from imunoise.detect import DetectorConfig, StaticSegment
from imunoise.errors import DataError
from imunoise.imu import AXES
from imunoise.io.imu_source import UNSET, ImuSource


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
    path: str | Path | ImuSource,
    config: DetectorConfig | None = None,
    *,
    lambda0: float | None = None,
    learn_from_s: float | None = None,
    learn_s: float = LEARN_S,
    topic: str | None = UNSET,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = UNSET,
    units: str | Mapping[str, str] | None = UNSET,
    time_column: str | int | None = UNSET,
    time_unit: str | None = UNSET,
    freq: float | None = UNSET,
    ref: str | Path | None = None,
    gnss: str | Path | None = None,
    progress: Callable[[str, int, str], Any] | None = None,
) -> LogStops:
    """:func:`read_log` + :func:`detect_stops` of a bag or table too large to hold, in two passes over
    :func:`imunoise.io.imu_stream.open_imu_blocks`: the same stops and stop samples as
    ``detect_stops(read_log(path), both_ways=False)`` — a stream cannot look back at a stop from its
    departure, so the forward pass alone, each stop's end cut by :data:`STREAM_END_TRIM_S` (the lag of the
    detector's window measured at departures) instead of the whole-log path's time-reversed pass.

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
    path : str, Path or ImuSource
        A ROS bag or a table (CSV/TXT, .npy, .npz) whose columns map to ``gyro_x`` .. ``accel_z``, or an
        :class:`~imunoise.io.imu_source.ImuSource` of one.
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
    source = ImuSource.of(path, topic=topic, columns=columns, units=units, time_column=time_column,
                          time_unit=time_unit, freq=freq)
    path, freq = source.path, source.freq
    need_g = lambda0 is None and learn_from_s is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        blocks = open_imu_blocks(source)
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
        lam, src, why = choose_lambda0(t_all, accel_xy, lambda: np.concatenate(gs), base.window, f, lambda0,
                                        learn_from_s, learn_s)
        span = (float(t_all[0]), float(t_all[-1]))
        del t_all, accel_xy
        gs.clear()
        speed = None
        if ref is not None:
            speed = speed_of_reference(ref)
            meta["speed_from"] = f"reference {ref}"
        elif gnss is not None:
            speed = speed_of_gnss(gnss)
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
                lo, hi = seg.i0 - buf0, seg.i1 - buf0
                # forward only: the end cut by the measured lag of the window at a departure (STREAM_END_TRIM_S)
                short = end_trimmed(seg, bt[lo:hi], STREAM_END_TRIM_S, cfg.min_duration_s)
                if short is None:
                    continue
                segments.append(short)
                if why is not None:
                    continue  # no usable stop (λ0 from a stretch that is not still): the detection only
                hi = short.i1 - buf0
                kept, cut = cut_segment(short, bt[lo:hi], bg[lo:hi], speed, f, cfg)
                stops.extend(kept)
                dropped.extend(cut)
                samples.extend(bx[s.i0 - buf0 : s.i1 - buf0].copy() for s in kept)

        blocks = open_imu_blocks(source)
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
