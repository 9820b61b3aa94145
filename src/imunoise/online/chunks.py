"""Replay of a whole record by the online engine in chunks (issue 25): the batch kernel between events.

:meth:`~imunoise.online.navigator.OnlineNavigator.run` feeds the streaming detector a chunk of IMU samples
(:meth:`~imunoise.detect.StaticDetector.push_chunk`: it decides the stops from the IMU alone, so it runs
ahead of the filter), then walks the chunk from event to event. An *event* is a sample that needs the
per-sample Python path (:meth:`OnlineNavigator.step_sample`):

* the first sample after the initial time (the strapdown is primed there);
* a sample at which the detector completed a segment (stop end: the stop guard, the modeller, an inline fit);
* the sample at which a scheduled model takes effect (:meth:`StopModeller.due`: a swap);
* a ZUPT/ZARU candidate (the update's speed/gate policy and the ZARU σ from the stop's own scatter);
* a non-finite increment (the step filter replaces it and logs it);
* with the in-motion noise learner (:mod:`imunoise.online.learner`): while its shadows wait to start, every
  sample that applies a fix (a start needs the live filter's speed after the fix); while they run, the sample
  its next rehearsal round is due; while the learned model has a departure step, every start from a stop;
* the change points of any extra event source (:meth:`OnlineNavigator.add_event_source`: e.g. a noise schedule).

Everything between two events runs in one :meth:`~imunoise.nav.ekf.LooselyCoupledEKF.run_span` call, which is the
step filter's propagate / GNSS update sequence through the same functions, and the per-sample bookkeeping
(raw samples for the segments, static flags, gate log and events, the stop guard's navigation rows, stored
epochs) is done on arrays. Where the next event lies is decided in one place,
:func:`~imunoise.nav.filter_loop.next_event`. The result equals the per-sample path to the bit
(``tests/test_online_chunks.py``). The shadows of the in-motion noise learner already run in the batch
kernel, one call per shadow and round (:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.rehearse`). The thread
worker (whose results arrive at wall-clock moments) keeps the per-sample path.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.filter_loop import SPAN_COLS, ImuInput, next_event
from imunoise.nav.zupt_policy import static_runs, zupt_due
from imunoise.online.stream_checks import fixes_pass

__all__ = ["chunked", "push_chunk", "replay", "run_chunk", "run_record"]

RUN_CHUNK = 4096  # IMU samples per StaticDetector.push_chunk call
_VEL = 4  # first velocity column of a run_span row (SPAN_COLS layout)


def chunked(nav: Any) -> bool:
    """Whether ``nav`` can run its record in kernel spans (the inline worker: a thread's results arrive at
    wall-clock moments, so its replay stays per sample)."""
    return nav.config.worker == "inline"


def replay(nav: Any, imu: Any, gnss: Any, progress: Any = None) -> Any:
    """:meth:`OnlineNavigator.run`: check and prepare the record (rates, sorted fixes, λ0), replay it with
    :func:`run_record`, and finish."""
    st = nav.state
    t0 = time.perf_counter()
    t = np.asarray(imu.t, dtype=float)
    dth_all, dv_all = imu.increments() if hasattr(imu, "increments") else (imu.dtheta, imu.dv)
    if t.size < 2:
        raise DataError("the IMU record needs at least 2 samples")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise DataError(f"IMU time stamps must increase strictly (sample {k}: {t[k]!r} after {t[k - 1]!r})")
    dt = np.diff(t, prepend=t[0] - nav.dt_nom)
    gyro = dth_all / dt[:, None]
    accel = dv_all / dt[:, None]
    gt = np.asarray(gnss.t, dtype=float)
    order = np.argsort(gt, kind="stable")
    gt, gllh, gsig = gt[order], np.asarray(gnss.llh)[order], np.asarray(gnss.sigma_ned)[order]
    if nav.detector is None:
        lam_mask = t < t[0] + nav.config.learn_lambda0_s
        nav.learn_lambda0(accel[lam_mask], t[0])
    st.elapsed += time.perf_counter() - t0
    run_record(nav, t, dth_all, dv_all, gyro, accel, gt, gllh, gsig, progress)
    if progress is not None:
        progress(t.size, t.size)
    return nav.finish()


def push_chunk(nav: Any, t, dtheta, dv, gnss_t=(), gnss_llh=(), gnss_sigma=()) -> None:
    """:meth:`OnlineNavigator.push_chunk`: samples checked as :meth:`push_imu` checks one, rates with the same
    Δt (the first after the last pushed sample, else the nominal one), then :func:`run_record` without
    finishing. While λ_0 is still to be learned, a chunk that ends before the learning window does goes through
    :meth:`push_imu` (held); the chunk that reaches its end learns λ_0 at once (:func:`_learn_in_chunk`)."""
    st = nav.state
    t = np.asarray(t, dtype=float).reshape(-1)
    dth = np.ascontiguousarray(dtheta, dtype=float)
    dvv = np.ascontiguousarray(dv, dtype=float)
    if dth.shape != (t.size, 3) or dvv.shape != (t.size, 3):
        raise DataError(f"push_chunk: dtheta and dv must be (n, 3) with n = len(t) = {t.size}, got {dth.shape} "
                        f"and {dvv.shape}")
    gt = np.asarray(gnss_t, dtype=float).reshape(-1)
    order = np.argsort(gt, kind="stable")
    gt = gt[order]
    gllh = np.asarray(gnss_llh, dtype=float).reshape(-1, 3)[order]
    gsig = np.asarray(gnss_sigma, dtype=float).reshape(-1, 3)[order]
    if t.size == 0:
        for k in range(gt.size):
            nav.push_gnss(gt[k], gllh[k], gsig[k])
        return
    if nav.detector is None and _learn_in_chunk(nav, t, dth, dvv, gt, gllh, gsig):
        return
    if nav.detector is None:
        gi = 0
        for k in range(t.size):
            while gi < gt.size and gt[gi] <= t[k]:
                nav.push_gnss(gt[gi], gllh[gi], gsig[gi])
                gi += 1
            nav.push_imu(t[k], dth[k], dvv[k])
        for k in range(gi, gt.size):
            nav.push_gnss(gt[k], gllh[k], gsig[k])
        return
    prev = np.concatenate([[st.t_in], t[:-1]])
    if not np.all(t > prev):
        k = int(np.flatnonzero(~(t > prev))[0])
        raise DataError(f"push_chunk: time {t[k]!r} does not follow {prev[k]!r}; stamps must increase")
    t0 = time.perf_counter()
    dt = t - prev
    if not math.isfinite(st.t_in):
        dt[0] = nav.dt_nom
    st.t_in = float(t[-1])
    st.elapsed += time.perf_counter() - t0
    run_record(nav, t, dth, dvv, dth / dt[:, None], dvv / dt[:, None], gt, gllh, gsig)


def _learn_in_chunk(nav: Any, t, dth, dvv, gt, gllh, gsig) -> bool:
    """λ_0 from the first ``learn_lambda0_s`` when this chunk reaches their end: learned at once from the held
    samples and the chunk's (the accelerations :meth:`push_imu` would hold), then everything held and the chunk
    replayed by :func:`run_record` (the same as the per-sample path, which learns at the first later sample and
    replays the held ones). False (nothing done) when the chunk ends before."""
    st = nav.state
    t0 = nav.feed.learn_t0 if nav.feed.learn_t0 is not None else float(t[0])
    k = int(np.searchsorted(t, t0 + nav.config.learn_lambda0_s, side="left"))
    if k >= t.size or not np.all(t > np.concatenate([[st.t_in], t[:-1]])):
        return False  # still learning, or bad stamps: push_imu says which
    dt = t - np.concatenate([[st.t_in], t[:-1]])
    if not math.isfinite(st.t_in):
        dt[0] = nav.dt_nom
    gyro, accel = dth / dt[:, None], dvv / dt[:, None]
    held = nav.feed.take_pending()
    nav.feed.learn_t0 = t0
    hacc = np.array([h[4] for h in held]).reshape(-1, 3)
    nav.learn_lambda0(np.concatenate([hacc, accel[:k]]), t0)
    st.t_in = float(t[-1])

    def cat(i: int, x: np.ndarray) -> np.ndarray:
        return np.concatenate([np.array([h[i] for h in held]).reshape((-1,) + x.shape[1:]), x])

    run_record(nav, cat(0, t), cat(1, dth), cat(2, dvv), cat(3, gyro), cat(4, accel), gt, gllh, gsig)
    return True


def run_record(nav: Any, t: np.ndarray, dth: np.ndarray, dv: np.ndarray, gyro: np.ndarray, accel: np.ndarray,
               gt: np.ndarray, gllh: np.ndarray, gsig: np.ndarray, progress: Any = None) -> None:
    """Replay samples and fixes (sorted) through ``nav``: detector chunks, then per chunk the events and the
    kernel spans between them (or every sample in Python when :func:`chunked` is false)."""
    st = nav.state
    n = t.size
    every = max(n // 100, 1)
    gi = 0
    base = nav.detector.n_samples
    fast = chunked(nav)
    if fixes_pass(gt, gllh, gsig):  # what push_gnss checks per fix, at once; then each fix goes in as checked

        def push_gnss(k: int) -> None:
            nav.push_checked_fix(float(gt[k]), np.asarray(gllh[k], dtype=float).reshape(-1).copy(),
                          np.asarray(gsig[k], dtype=float).reshape(-1).copy())
    else:  # push_gnss raises for the first bad fix when the replay reaches it

        def push_gnss(k: int) -> None:
            nav.push_gnss(gt[k], gllh[k], gsig[k])

    for a in range(0, n, RUN_CHUNK):
        t1 = time.perf_counter()
        b = min(a + RUN_CHUNK, n)
        det = nav.detector.push_chunk(t[a:b], accel[a:b], gyro[a:b])
        done_at: dict[int, list] = {}
        for s, k in zip(det.segments, det.completed_at, strict=True):
            done_at.setdefault(k - base, []).append(s)
        st.elapsed += time.perf_counter() - t1
        if fast:
            gi = run_chunk(nav, a, b, t, dth, dv, gyro, accel, det, done_at, gt, push_gnss, gi, progress, every, n)
            continue
        for k in range(a, b):
            t1 = time.perf_counter()
            while gi < gt.size and gt[gi] <= t[k]:
                push_gnss(gi)
                gi += 1
            nav.step_sample(t[k], dth[k], dv[k], gyro[k], accel[k], bool(det.static_raw[k - a]),
                        bool(det.gate_open[k - a]), done_at.get(k, []))
            st.elapsed += time.perf_counter() - t1
            if progress is not None and k % every == 0:
                progress(k, n)
    while gi < gt.size:
        push_gnss(gi)
        gi += 1


def run_chunk(nav: Any, a: int, b: int, t, dth, dv, gyro, accel, det, done_at: dict, gt, push_gnss: Any, gi: int,
              progress: Any, every: int, n_total: int) -> int:
    """Samples ``a``..``b−1`` (one detector chunk ``det``) from event to event; returns the next fix index
    (``push_gnss(k)`` hands fix k of the record to the navigator)."""
    st = nav.state
    t1 = time.perf_counter()
    cfg = nav.config
    static = np.asarray(det.static_raw, dtype=bool)
    gate = np.asarray(det.gate_open, dtype=bool) & bool(cfg.gate)
    runs = static_runs(static, st.static_run)
    rel = np.arange(b - a)
    py = [np.fromiter(sorted(k - a for k in done_at), dtype=np.int64)]
    bad = ~(np.all(np.isfinite(dth[a:b]), axis=1) & np.all(np.isfinite(dv[a:b]), axis=1))
    py.append(rel[bad])
    if cfg.zupt:
        py.append(rel[zupt_due(static, every=cfg.zupt_every, after=cfg.zupt_after, run0=st.static_run)])
    if not st.started:
        i = int(np.searchsorted(t[a:b], nav.init.t, side="right"))
        py.append(np.array([i], dtype=np.int64))
    for idx, _ in st.event_sources:
        py.append(idx[(idx >= st.n_samples) & (idx < st.n_samples + b - a)] - st.n_samples)
    py = [np.unique(p) for p in py if p.size]
    # starts from a stop: events while the learned model adds a departure step there
    prev_run = np.concatenate([[st.static_run], runs[:-1]])
    learner = nav.learner.motion
    departures = rel[~static & (prev_run >= learner.min_stop_n)] if learner is not None else rel[:0]
    k = 0
    m = b - a
    while k < m:
        sources = list(py)
        due = [nav.modeller.next_effect()]
        if departures.size and learner.departure_var() is not None:
            sources.append(departures)
        if learner is not None and st.started:
            if learner.waiting():
                # the shadows start at an aided moving step: every sample that applies a fix
                q = [f[0] for f in st.gnss] + gt[gi:].tolist()
                sources.append(np.unique(np.searchsorted(t[a:b], np.array(q, dtype=float), side="left")))
            else:
                due.append(learner.next_round_t())
        for d in due:
            if d is not None:
                sources.append(np.array([int(np.searchsorted(t[a:b], d, side="left"))], dtype=np.int64))
        e = next_event(k, m, sources)
        if e > k:
            while gi < gt.size and gt[gi] <= t[a + e - 1]:
                push_gnss(gi)
                gi += 1
            _span(nav, a + k, a + e, t, dth, dv, gyro, accel, static[k:e], gate[k:e], runs[k:e])
            if progress is not None:
                for j in range(a + k + (-(a + k)) % every, a + e, every):
                    progress(j, n_total)
        if e < m:
            j = a + e
            while gi < gt.size and gt[gi] <= t[j]:
                push_gnss(gi)
                gi += 1
            nav.step_sample(t[j], dth[j], dv[j], gyro[j], accel[j], bool(static[e]), bool(det.gate_open[e]),
                        done_at.get(j, []))
            if progress is not None and j % every == 0:
                progress(j, n_total)
        k = e + 1
    st.elapsed += time.perf_counter() - t1
    return gi


def _span(nav: Any, a: int, e: int, t, dth, dv, gyro, accel, static, gate, runs) -> None:
    """Samples a..e−1, none of them an event: bookkeeping on arrays, the filter in one kernel call."""
    st = nav.state
    cfg = nav.config
    ts = t[a:e]
    m = e - a
    n0 = st.n_samples
    # -- the raw-sample bookkeeping of step_sample---------------------------------------------------
    st.rows.extend(np.concatenate([gyro[a:e], accel[a:e]], axis=1))
    st.static_raw.extend(static.tolist())
    st.sample_t.extend(ts.tolist())
    st.t_last = float(ts[-1])
    st.n_samples += m
    st.static_run = int(runs[-1])
    starts = np.flatnonzero(runs == 1)
    if starts.size:
        nav.guard.new_run(n0 + int(starts[-1]))
    if not np.all(static):
        st.zupt_rejected = False
    evs = []
    if nav.detector is not None:
        for i in np.flatnonzero(runs == st.stop_start_n):
            evs.append((int(i), 0, "stop_start", {"t0": st.sample_t[n0 + i - st.stop_start_n + 1]}))
    prev = np.concatenate([[st.gate], gate[:-1]])
    for i in np.flatnonzero(gate != prev):
        evs.append((int(i), 1, "gate_open" if gate[i] else "gate_closed", {}))
    st.gate = bool(gate[-1])
    st.gate_log.extend(gate.tolist())
    for i, _, name, kw in sorted(evs, key=lambda x: (x[0], x[1])):
        st.event(name, float(ts[i]), **kw)
    rec = static.copy()
    if starts.size:
        rec[: starts[-1]] = False
    # -- the filter ------------------------------------------------------------------------------------
    if not st.started:
        fixes = st.gnss
        while fixes and fixes[0][0] <= ts[-1]:
            fixes.pop(0)
        if cfg.stop_guard == "nav":
            k = int(rec.sum())
            nav.guard.rows(np.column_stack([np.full(k, math.nan), np.full(k, math.nan), np.zeros(k),
                                           np.full(k, math.nan)]))
    else:
        _filter_span(nav, ts, dth[a:e], dv[a:e], gate, rec, static)
    # raw samples are needed only back to the start of a possible segment
    if not np.all(static) and len(st.rows) > 4096:
        last_moving = int(np.flatnonzero(~static)[-1])
        st.drop_old_rows(m - last_moving + 15)


def _filter_span(nav: Any, ts, dth, dv, gate, rec, static) -> None:
    st = nav.state
    cfg = nav.config
    ekf = nav.ekf
    ec = ekf.config
    m = ts.size
    q = st.gnss
    j = 0
    while j < len(q) and q[j][0] <= ts[-1]:
        j += 1
    fl, st.gnss = q[:j], q[j:]
    if fl:  # finite positions (one vectorised test; push_gnss keeps (3,) positions)
        finite = np.isfinite(np.array([f[1] for f in fl], dtype=float).reshape(len(fl), -1)).all(axis=1).tolist()
        fl = [f for f, ok in zip(fl, finite, strict=True) if f[0] > nav.init.t and ok]
    ft = np.array([f[0] for f in fl], dtype=float)
    sig = np.array([f[2] for f in fl], dtype=float).reshape(-1, 3)
    sig = np.where(np.isfinite(sig), sig, ec.gnss_sigma_nan)
    sig = np.maximum(sig, ec.gnss_sigma_floor)
    fixes = ekf.streams(ekf.position_stream(ft, np.array([f[1] for f in fl], dtype=float).reshape(-1, 3), sig))
    tin = np.concatenate([[ekf.t], ts])
    gin = np.concatenate([[ekf.gate_open], gate])
    imu = ImuInput(tin, np.concatenate([np.zeros((1, 3)), dth]), np.concatenate([np.zeros((1, 3)), dv]), gin,
                   np.zeros(m + 1, dtype=np.bool_))
    rows = np.empty((m, SPAN_COLS))
    guard = cfg.stop_guard == "nav" and bool(rec.any())
    pv = np.empty((m if guard else 1, 3, 3))
    if st.streams is not None:  # GNSS velocity, odometer, ...: their epochs in (filter time, span end]
        st.streams.span(fixes, ekf.t, float(ts[-1]))
    used = ekf.run_span(imu, fixes, rows, pv)  # fixes: the filter's measurement streams
    if st.streams is not None:
        st.streams.after_span(fixes, float(ts[-1]))
    # the sample each fix was applied at (the first with t ≥ the fix time)
    at = np.searchsorted(ts, ft, side="left")
    t_aided = np.full(m, st.t_aided)
    if used.any():
        ua = at[used]
        mark = np.full(m, -1)
        mark[ua] = ua
        last = np.maximum.accumulate(mark)
        t_aided = np.where(last >= 0, ts[np.maximum(last, 0)], st.t_aided)
        st.t_aided = float(ts[ua[-1]])
    if guard:
        # the rows _record_nav writes, one block per span: the same scalar operations (math.hypot, math.sqrt of
        # max(·, 0.0)) on the same values, element by element
        idx = np.flatnonzero(rec)
        speed = [math.hypot(v0, v1) for v0, v1 in zip(rows[idx, _VEL].tolist(), rows[idx, _VEL + 1].tolist())]
        sigma = [math.sqrt(max(p0 + p1, 0.0)) for p0, p1 in zip(pv[idx, 0, 0].tolist(), pv[idx, 1, 1].tolist())]
        aided = (ts[idx] - t_aided[idx] <= cfg.stop_aided_s).astype(float)
        nis = np.full(idx.size, math.nan)
        if cfg.stop_chi2 > 0:
            for n, i in enumerate(idx):
                v = rows[i, _VEL:_VEL + 3]
                try:
                    nis[n] = float(v @ np.linalg.solve(pv[i] + cfg.zupt_sigma_v**2 * np.eye(3), v))
                except np.linalg.LinAlgError:
                    nis[n] = math.inf
        nav.guard.rows(np.column_stack([speed, sigma, aided, nis]))
    if nav.learner.motion is not None:
        nav.learner.motion.observe_span(ts, dth, dv, static, [f for f, u in zip(fl, used, strict=True) if u])
    if st.store is not None:
        st.store.extend(rows)
