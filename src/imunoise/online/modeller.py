"""The modelling half of the online engine: pooled stops → online GMWM fits → scheduled model updates.

:class:`StopModeller` holds what the online engine learns from the stops (paper §2.2–2.3; the rules are in
:mod:`imunoise.online.navigator`'s docstring): the static pieces pooled so far (bias removed, one
:class:`~imunoise.noise.wv.WVAccumulator` per axis, no wavelet coefficient across two pieces:
docs/guide/theory.rst, 'Static detection'), the current
fit of each axis, the modelling jobs (inline, or on one background thread that the filter never waits for)
and the updates whose effect time has not come yet. The navigator hands it the samples of every kept stop and
asks it at every sample which updates are due; it never touches the filter.
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from imunoise.detect import StaticSegment
from imunoise.errors import DataError, ImunoiseError
from imunoise.nav.ekf import AXES
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.wv import WVAccumulator
from imunoise.online.config import OnlineConfig
from imunoise.online.jobs import model_job
from imunoise.online.result import ModelUpdate, log_event

log = logging.getLogger(__name__)

__all__ = ["StopModeller"]


class StopModeller:
    """Pooled static data, the per-axis GMWM fits and the model updates of one online run.

    Parameters
    ----------
    config : OnlineConfig
        Modelling settings (``modelling``, ``min_static_s``, ``criterion``, ``complete``, ``worker``,
        ``latency``, …).
    rate : float
        IMU rate [Hz].
    events : list of dict
        The run's event log; the modeller appends its events (``stop_end``, ``waiting``, ``identified``,
        ``refit``, ``rejected``, ``warm_up``, ``earlier_static``) to it in the order they happen.
    job_cache : dict, optional
        Shared by replays of the same IMU record (:class:`~imunoise.online.navigator.OnlineNavigator`).

    Attributes
    ----------
    fits : list of GMWMFit or None
        The current fit of each axis (gyro x, y, z, accel x, y, z); None before the first identification.
    updates : list of ModelUpdate
        Every modelling job's outcome, accepted or not.
    segments : list of StaticSegment
        The stops whose samples were pooled.
    static_s : float
        Static data pooled [s], the earlier drives' included.
    job_cache : dict or None
        The ``job_cache`` given (a copy of the run shares it: :meth:`OnlineNavigator.fork`).
    """

    def __init__(self, config: OnlineConfig, rate: float, events: list[dict], job_cache: dict | None = None):
        self.config = config
        self.rate = float(rate)
        self.events = events
        self.fits: list[GMWMFit | None] = [None] * 6
        self.updates: list[ModelUpdate] = []
        self.segments: list[StaticSegment] = []
        self.static_s = 0.0
        self._acc = [WVAccumulator(freq=self.rate) for _ in range(6)]
        self._pieces: list[np.ndarray] = []  # every pooled static piece (static_pieces)
        self._earlier_key: tuple = ()  # what the job cache must tell apart: the earlier drives' static data
        self.job_cache = job_cache
        self._scheduled: list[tuple[float, ModelUpdate]] = []
        self._executor: ThreadPoolExecutor | None = None
        self._future: Future | None = None
        self._future_meta: tuple[str, float] | None = None  # (kind, stop time) of the running job
        self._dirty = False  # new static data arrived while a thread job runs
        self._warm: Future | None = None

    def _event(self, event: str, t: float, **kw: Any) -> None:
        log_event(self.events, event, t, **kw)

    @property
    def busy(self) -> bool:
        """A modelling job is running on the background thread."""
        return self._future is not None

    # -- warm-up ----------------------------------------------------------------------------------------
    def start_warm_up(self, t0: float) -> None:
        """Compile or load the modelling kernels before the first stop (:func:`imunoise.noise.fitting.warm.warm_up`):
        inline here, or as the worker thread's first job (the identification queues behind it, so its
        measured compute time never includes the warm-up)."""
        from imunoise.noise.fitting.warm import warm_up

        if self.config.worker == "thread":
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imunoise-gmwm")
            self._warm = self._executor.submit(warm_up)
            return
        try:
            info = warm_up()
        except Exception as exc:  # noqa: BLE001 - a failed warm-up only means compiling later, in the first fit
            info = {"error": f"{type(exc).__name__}: {exc}"}
        self._event("warm_up", t0, worker="inline", **info)

    def _collect_warm_up(self, t: float) -> None:
        fut, self._warm = self._warm, None
        try:
            info = fut.result()
        except Exception as exc:  # noqa: BLE001 - see start_warm_up
            info = {"error": f"{type(exc).__name__}: {exc}"}
        self._event("warm_up", t, worker="thread", **info)

    # -- static data ------------------------------------------------------------------------------------
    def add_stop(self, seg: StaticSegment, data: np.ndarray, t_now: float) -> None:
        """Pool the samples of one kept stop, (n, 6) rad/s and m/s² (bias removed, split at non-finite samples)
        and log its ``stop_end``."""
        ok = np.all(np.isfinite(data), axis=1)
        # a non-finite sample splits the segment (no wavelet coefficient may span it)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        pieces = [data[p:q] for p, q in zip(edges[::2], edges[1::2]) if q - p >= 16]
        if not ok.all():
            self._event("rejected", t_now, reason=f"{int((~ok).sum())} non-finite samples in the stop "
                        f"{seg.t0:.2f}–{seg.t1:.2f} s; used the {len(pieces)} finite pieces")
        for piece in pieces:
            self._pool_piece(piece)
        self.static_s += seg.duration
        self.segments.append(seg)
        self._event("stop_end", t_now, t0=seg.t0, t1=seg.t1, duration_s=seg.duration, static_total_s=self.static_s)

    def add_earlier(self, earlier: Sequence[np.ndarray], t0: float) -> None:
        """Pool the static pieces of earlier drives (``earlier_static`` of the navigator) and identify on them
        if there are enough; such a model is in effect from ``t0``."""
        n_before = len(self._pieces)
        for k, x in enumerate(earlier):
            x = np.asarray(x, dtype=float)
            if x.ndim != 2 or x.shape[1] != 6:
                raise DataError(f"earlier_static[{k}]: expected an (N, 6) array of static samples (gyro x, y, z "
                                f"rad/s, accel x, y, z m/s²), got shape {x.shape}")
            if not np.all(np.isfinite(x)):
                raise DataError(f"earlier_static[{k}]: {int((~np.isfinite(x)).sum())} non-finite values; pass "
                                "only finite static samples")
            if x.shape[0] >= 16:
                self._pool_piece(x, keep_as_given=True)
        n = sum(p.shape[0] for p in self._pieces[n_before:])
        self.static_s += n / self.rate
        digest = hashlib.sha1()
        for p in self._pieces[n_before:]:
            digest.update(p.tobytes())
        self._earlier_key = (n, digest.hexdigest())
        self._event("earlier_static", t0, pieces=len(self._pieces) - n_before, static_s=n / self.rate)
        if self.config.modelling and self.static_s >= self.config.min_static_s:
            wvs = self._wvs(t0)
            if wvs is not None:
                out = model_job("identify", wvs, self.fits, self.config, self.rate)
                self._accept("identify", t0, out, t0)  # computed before the drive: in effect from its start

    def _pool_piece(self, piece: np.ndarray, *, keep_as_given: bool = False) -> None:
        """Pool one static piece, its bias removed (docs/guide/theory.rst, 'Static detection'). ``keep_as_given``: an
        earlier drive's piece is
        stored with its exact values, so a chain of drives hands on the same bytes and a repeated piece is
        recognised (:func:`imunoise.io.static_npz.load_static_pieces`)."""
        centred = piece - piece.mean(axis=0)
        self._pieces.append(piece if keep_as_given else centred)
        for ax in range(6):
            self._acc[ax].add(centred[:, ax])

    def static_pieces(self, *, copy: bool = True) -> list[np.ndarray]:
        """Every static piece pooled so far, (N, 6) each: the earlier drives' as given, then this drive's stops
        with their bias removed; the ``earlier_static`` of the next drive of the same IMU. ``copy=False``: the
        pooled arrays themselves (read only; for a result object)."""
        return [p.copy() for p in self._pieces] if copy else list(self._pieces)

    def _wvs(self, t_now: float) -> list | None:
        """The per-axis WVs of the static data so far, or None after a 'rejected' event when one fails."""
        try:
            return [acc.result() for acc in self._acc]
        except ImunoiseError as exc:
            self._event("rejected", t_now, reason=f"wavelet variance: {exc}")
            return None

    # -- jobs -------------------------------------------------------------------------------------------
    def stop_done(self, t_now: float) -> None:
        """After a kept stop: identify (first time) or refit on all static data, once ``min_static_s`` exist;
        with the thread worker a stop that ends while a job runs is picked up by the next job."""
        if not self.config.modelling:
            return
        if self.static_s < self.config.min_static_s:
            self._event("waiting", t_now, static_total_s=self.static_s, need_s=self.config.min_static_s)
            return
        kind = "identify" if all(f is None for f in self.fits) else "refit"
        if self.config.worker == "thread":
            if self._future is not None:
                self._dirty = True
                return
            self._submit(kind, t_now)
            return
        self._run_inline(kind, t_now)

    def _run_inline(self, kind: str, t_now: float) -> None:
        wvs = self._wvs(t_now)
        if wvs is None:
            return
        key = None
        if self.job_cache is not None:
            c = self.config
            key = (kind, self._earlier_key, tuple((sg.i0, sg.i1) for sg in self.segments), c.criterion, c.complete,
                   c.weights, c.top,
                   tuple(None if f is None else (str(f.model), tuple(f.model.vector)) for f in self.fits))
        out = self.job_cache.get(key) if key is not None else None
        if out is None:
            out = model_job(kind, wvs, self.fits, self.config, self.rate)
            if key is not None:
                self.job_cache[key] = out
        delay = self.config.latency if self.config.latency is not None else float(sum(out["elapsed"]))
        self._accept(kind, t_now, out, t_now + delay)

    def _submit(self, kind: str, t_now: float) -> None:
        wvs = self._wvs(t_now)
        if wvs is None:
            return
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imunoise-gmwm")
        self._future = self._executor.submit(model_job, kind, wvs, list(self.fits), self.config, self.rate)
        self._future_meta = (kind, t_now)
        self._dirty = False

    def _collect_thread(self, t_now: float) -> None:
        fut, (kind, t_stop) = self._future, self._future_meta
        self._future = None
        try:
            out = fut.result()
        except Exception as exc:  # noqa: BLE001 - a worker failure must never stop the filter
            self._event("rejected", t_now, reason=f"worker failed: {type(exc).__name__}: {exc}")
            return
        self._accept(kind, t_stop, out, t_now)
        if self._dirty:
            self._submit("refit" if any(f is not None for f in self.fits) else "identify", t_now)

    def _accept(self, kind: str, t_stop: float, out: dict, t_effect: float) -> None:
        fits = out["fits"]
        for a, reason in enumerate(out["rejected"]):
            if reason:
                self._event("rejected", t_stop, axis=AXES[a], job=kind, reason=reason)
                log.info("%s fit of %s rejected: %s", kind, AXES[a], reason)
        ok = any(f is not None for f in fits)
        upd = ModelUpdate(kind, t_stop, t_effect if ok else None, self.static_s, fits, out["elapsed"],
                          out["rankings"], out["rejected"])
        self.updates.append(upd)
        per_axis = {
            AXES[a]: {"structure": str(f.model), "gof": f.objective, "time_s": out["elapsed"][a],
                      "wvic": f.extra.get("wvic")}
            for a, f in enumerate(fits) if f is not None
        }
        self._event("identified" if kind == "identify" else "refit", t_stop, static_total_s=self.static_s,
                    axes=per_axis, elapsed_s=float(sum(out["elapsed"])), t_effect=upd.t_effect)
        if ok:
            for a, f in enumerate(fits):
                if f is not None:
                    self.fits[a] = f
            self._scheduled.append((upd.t_effect, upd))
            self._scheduled.sort(key=lambda x: x[0])

    # -- the navigator's clock ----------------------------------------------------------------------------
    def due(self, t: float) -> list[ModelUpdate]:
        """At filter time ``t``: collect a finished warm-up or thread job, and return the accepted updates whose
        effect time has come (in effect-time order; the caller swaps each into the filter)."""
        if self._warm is not None and self._warm.done():
            self._collect_warm_up(t)
        if self._future is not None and self._future.done():
            self._collect_thread(t)
        out = []
        while self._scheduled and self._scheduled[0][0] <= t:
            out.append(self._scheduled.pop(0)[1])
        return out

    def next_effect(self) -> float | None:
        """Effect time of the next scheduled update (None: none): where a chunked replay must stop to swap."""
        return self._scheduled[0][0] if self._scheduled else None

    def finish(self, t_last: float) -> None:
        """Wait for the warm-up and a running job (logged at ``t_last``) and stop the worker thread."""
        if self._warm is not None:
            self._warm.exception()  # wait; _collect_warm_up logs the outcome
            self._collect_warm_up(t_last)
        if self._future is not None:
            self._future.result()
            self._collect_thread(t_last)
        if self._executor is not None:
            self._executor.shutdown(wait=True)

