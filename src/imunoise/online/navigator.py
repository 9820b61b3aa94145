"""Online engine: static detection → online GMWM → model hot-swap in the EKF
(docs/guide/theory.rst, 'System overview' and 'Online engine'; paper Fig. 1).

Per IMU sample the navigator (1) feeds the static detector (docs/guide/theory.rst, 'Static detection'), (2) sets the
angular-rate gate, (3) propagates the loosely coupled EKF (docs/guide/theory.rst, 'Navigation filter') and applies
queued GNSS fixes and the due epochs of the other measurement streams (:meth:`OnlineNavigator.add_streams`), (4)
optionally applies ZUPT/ZARU while the detector says "static", (5) applies a new error model whose effect time has come.

Modelling (paper §2.2–2.3; held by :class:`~imunoise.online.modeller.StopModeller`, which the navigator feeds
the kept stops and asks at every sample which model updates are due). Every completed static segment (trimmed,
bias removed = segment mean, all six axes) is added to one :class:`~imunoise.noise.wv.WVAccumulator` per axis (pooled
WV, no junction crosses two stops). Once ``min_static_s`` of static data exist, the structure is identified per
axis over every sub-model of ``complete`` (:func:`imunoise.noise.selection.select_model`, criterion ``"wvic"``, the
library's default, or ``"gof"`` as the paper); after every later stop the fixed structure is re-estimated on all
static data so far, warm-started from the previous fit (:func:`imunoise.noise.estimator.refit`). A fit is rejected
(the current model is kept and the reason logged) when it has non-finite parameters or when its GOF on the new
WV is worse than the current parameters' GOF on the same WV and Ω.

From a GMWM fit to filter noise (``ekf_axis_model``). The static fit describes the sensor at rest; the
EKF needs a model of the error that drives the navigation states while driving. Everything that does not
become a Gauss–Markov state goes through :func:`imunoise.noise.equivalent_noise.equivalent_noise`, the one
model → (white, random walk) mapping the export uses too (with ``white_below_s = fold_tau_s``). The mapping:

* WN → white noise of δv/φ (density N² = σ²/f);
* AR1 with T_c ≥ ``fold_tau_s`` → an augmented Gauss–Markov state; faster AR1 → white noise with the
  same low-frequency density (per sample σ²/(1 − φ)², the AR1 spectrum at f = 0): a state that decorrelates
  between two covariance steps carries no information the filter can use, and folding keeps the state vector small;
* QN → white noise with the per-sample variance 2Q² (as ``Model.white_variance``), by default
  (``qn="white"``). True quantisation noise has zero density at f = 0 (its integral is bounded), which
  ``qn="drop"`` models; but on a car standing with its engine running the τ⁻² part of the WV is engine
  vibration (2.4 °/s per sample on gyro y of the shared drive), and while driving the vibration is larger
  still. Measured on the shared drive (five 60 s outages): mean end drift 338 m plain, 337 m with QN
  dropped, 226 m with QN as white; the simulator (no QN in the truth) is indifferent.
* AR1 with T_c·f beyond the longest Haar scale of the static data → the random walk matched to its WV over
  [1/f, horizon] (≈ the AR1's innovation variance: the same WV at every scale the data has). Kept as a
  state, such a fit (T_c = 3·10⁵ s, σ_GM = 1 °/s on a simulated gyro) entered the filter with its
  extrapolated stationary σ as initial uncertainty; two GNSS fixes before an outage moved that bias and the
  outage ended 3 km off;
* DR → the random walk with the same Haar WV at the longest scale of the static data (``dr="rw"``, the
  default; :func:`dr_equivalent_rw`). On seconds-long stops a rate random walk and a ramp are two readings
  of the same rising WV (GOF often picks DR where the truth is RW); a ramp state would extrapolate one
  fitted slope, and dropping it (``dr="drop"``, the earlier behaviour) throws away the evidence that the
  bias wanders. RW → bias random walk.
* ``floor="default"`` (the default): white density, RW and the slow Gauss–Markov bias of the plain
  default model (``EkfConfig.fallback``) are lower bounds. The static model never makes the filter more
  confident than the plain filter about the low-frequency error it cannot see in seconds-long stops,
  nor about the white noise of a moving car (vibration grows with speed). ``floor="none"`` uses the
  static model as is (measured in the experiments: overconfident on the real drive).

Swap: the kept stops go to the modeller and its due updates into the filter in :mod:`imunoise.online.model_swaps`
(``swap="preserve"``, the default, keeps the augmented states of a refit; ``"reset"`` restarts them).

Criterion. GOF always prefers the biggest nested model; WVIC (the WV's −2 log-likelihood + p·ln n, see
docs/guide/theory.rst, 'Model selection') penalises size. Measured (20 simulated drives, real drive): GOF 88 m vs
WVIC 96 m vs plain 92 m mean outage drift on the simulator (before the collapse rule below, excluding one GOF
divergence), 209 m vs 216 m vs 338 m on the real drive. With GOF, components that collapsed to the parameter bound
(σ² ~ 1e-57, kept by the nesting guarantee of the selection) are dropped from the filter model (``NEGLIGIBLE``):
kept, they made P ill-conditioned and the filter diverged on one simulated drive (4 km drift). Default: ``"wvic"``.

Worker. ``worker="inline"`` (replay, deterministic): a model is computed at the stop's completion and takes
effect at that time plus ``latency`` (a fixed delay; ``None`` = the measured compute time, as the paper's
Table 6 time-taken). ``worker="thread"`` (live use): the fit runs in a background thread and the filter
never waits; the model takes effect at the first sample after the thread finished.

``run(imu, gnss)`` (batch) and ``push_imu``/``push_gnss``/``solution`` (streaming) run the same code: both feed the one
streaming :class:`~imunoise.detect.StaticDetector`, batch in chunks (:meth:`StaticDetector.push_chunk`, which also says
at which sample each segment was completed; identical to per-sample pushes, checked in tests/test_detect_paths.py), and
batch interleaves the GNSS fixes by time (a fix at t_g is applied after the first IMU sample with t ≥ t_g, as in
:func:`imunoise.nav.ekf.run_ekf`). Batch runs the filter between events (stop ends, swaps, ZUPT candidates, the first
sample) in one kernel call (:mod:`imunoise.online.chunks`), identical to the per-sample path to the bit.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.detect import StaticDetector, StaticSegment
from imunoise.errors import DataError
from imunoise.nav.defaults import default_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF, normalize_axis_models
from imunoise.nav.streams import Epochs
from imunoise.noise.model import Model
from imunoise.online.chunks import push_chunk, replay
from imunoise.online.config import OnlineConfig, config_summary
from imunoise.online.engine_state import EngineState
from imunoise.online.lambda0 import DetectorFeed
from imunoise.online.learner.host import LearnerHost
from imunoise.online.measurement_feed import MeasurementFeed
from imunoise.online.model_swaps import apply_due_models, stop_completed
from imunoise.online.modeller import StopModeller
from imunoise.online.nav_output import build_result, fork_navigator, store_epoch
from imunoise.online.nav_parts import ModellerViews, Zupt
from imunoise.online.result import EpochStore, OnlineResult
from imunoise.online.stops import StopGuard
from imunoise.online.stream_checks import check_fix, check_increment
from imunoise.online.to_filter import filter_axis_models

__all__ = ["OnlineNavigator", "run_online"]


class OnlineNavigator(ModellerViews):
    """Online GMWM INS/GNSS navigator (docs/guide/theory.rst, 'Online engine'). See the module docstring.

    The engine's per-sample state is one :class:`~imunoise.online.engine_state.EngineState` (``state``) handed to
    named collaborators: ``feed`` (:class:`~imunoise.online.lambda0.DetectorFeed`: the static detector and
    λ_0), ``guard`` (:class:`~imunoise.online.stops.StopGuard`: which detected stops are modelled), ``modeller``
    (:class:`~imunoise.online.modeller.StopModeller`), ``zupt`` (:class:`~imunoise.online.nav_parts.Zupt`) and
    ``learner`` (:class:`~imunoise.online.learner.host.LearnerHost`: the in-motion noise learner).

    Parameters
    ----------
    config : OnlineConfig
        Detection, modelling, swap and filter settings.
    init : InitialState
        Initial state at ``init.t`` (samples at or before it only feed the detector and the modeller).
    imu_rate_hz : float
        Nominal IMU rate [Hz].
    initial_models : optional
        The filter's models until the first identification (default: the plain default,
        ``EkfConfig.fallback``), e.g. an AV or EM model for the baselines with ``modelling=False``.
    job_cache : dict, optional
        Shared by replays of the *same IMU record* (e.g. the per-window outage runs of an experiment): a
        modelling job on the same static segments with the same settings is computed once, and its
        measured compute time is reused so the model takes effect at the same time in every replay
        (inline worker only).
    earlier_static : sequence of numpy.ndarray, optional
        Static IMU samples of earlier drives of the same IMU, one array of shape (n, 6) per stop (rad/s, m/s²;
        columns gyro x, y, z, accel x, y, z; e.g. :attr:`OnlineResult.static_pieces` of an earlier run, or
        ``static.npz`` of ``imunoise online``). They are pooled with this drive's stops (each piece's
        bias removed, no wavelet coefficient across pieces: docs/guide/theory.rst, 'Static detection'). With modelling
        on and at least ``min_static_s`` of them, the model is identified on them at construction (computed here, before
        the first sample, with either worker) and the filter runs it from the first sample; every stop of
        this drive then refits on the pool. ``static_s`` counts them.
    """

    def __init__(self, config: OnlineConfig, init: InitialState, *, imu_rate_hz: float = 100.0,
                 initial_models=None, job_cache: dict | None = None,
                 earlier_static: Sequence[np.ndarray] | None = None):
        if not (math.isfinite(imu_rate_hz) and imu_rate_hz > 0):
            raise DataError(f"imu_rate_hz must be a positive rate in Hz, got {imu_rate_hz!r}")
        self.config = config
        self.rate = float(imu_rate_hz)
        self.dt_nom = 1.0 / self.rate
        self.init = init
        self.state = EngineState(init.t, store=EpochStore() if config.store else None)
        models = initial_models if initial_models is not None else default_axis_models(self.rate,
                                                                                        config.ekf.fallback)
        # the models without the learned in-motion part (the stops' model; what the learner adds to)
        self.static_models = normalize_axis_models(models, self.rate)
        self.learner = LearnerHost(config, self.state, self.rate)
        models = self.learner.first_models(self.static_models, self.static_models)  # a carried prior's from the start
        self.ekf = LooselyCoupledEKF(config.ekf, models, init, imu_rate_hz=self.rate)
        self.floor = default_axis_models(self.rate, config.ekf.fallback)
        self.feed = DetectorFeed(self.state, self.rate, config.learn_lambda0_s, config.detector)
        self.guard = StopGuard(config, self.state, self.rate)
        self.zupt = Zupt(config, self.state)
        self.detected_segments: list[StaticSegment] = []  # every completed detector segment, before the guard
        self.modeller = StopModeller(config, self.rate, self.state.events, job_cache)
        self.current_models = models
        self.in_motion: Any = None  # a model file's in-motion part: imunoise.online.in_motion (with its swaps)
        self.state.event("start", init.t, lambda0=self.lambda0, config=config_summary(config))
        if earlier_static is not None:
            self.modeller.add_earlier(earlier_static, init.t)
        if config.modelling and config.warm_up and all(f is None for f in self.fits):
            self.modeller.start_warm_up(init.t)

    @property
    def events(self) -> list[dict]:
        """The event log so far."""
        return self.state.events

    @property
    def store(self) -> EpochStore | None:
        """The stored epochs so far (None with ``OnlineConfig(store=False)``); read, e.g., by the experiments'
        errors of a running navigator (:func:`imunoise.experiments.window_errors.stored_errors`)."""
        return self.state.store

    @property
    def detector(self) -> StaticDetector | None:
        """The static detector (None while λ_0 is still to be learned)."""
        return self.feed.detector

    @property
    def lambda0(self) -> float | None:
        """The detector's λ_0 [m/s²] (None while still to be learned)."""
        return self.feed.lambda0

    @property
    def rejected_segments(self) -> list[StaticSegment]:
        """The parts of the detected segments the stop guard dropped."""
        return self.guard.rejected_segments

    def learn_lambda0(self, accel_static: np.ndarray, t0: float) -> None:
        """Learn λ_0 now from the specific forces ``accel_static`` (n, 3) [m/s²] of the first ``learn_lambda0_s``
        of the record, starting at ``t0`` [s] (:meth:`DetectorFeed.learn_from`): what :meth:`push_imu` does at
        the first sample after them, done at once by a replay that has the whole record."""
        self.feed.learn_from(accel_static, t0)

    def add_event_source(self, indices: np.ndarray, hook: Any) -> None:
        """Call ``hook(navigator, i)`` just before IMU sample ``i`` (0-based, in push order) for every ``i`` of the
        sorted ``indices``: a source of events beside the stops, swaps and fixes (e.g. the change points of a
        per-sample noise schedule). :meth:`run` makes each such sample an event of its chunked replay
        (:mod:`imunoise.online.chunks`), so the kernel stops there and the sample takes the per-sample path,
        which calls the hook (as for :meth:`push_imu`)."""
        self.state.event_sources.append((np.asarray(indices, dtype=np.int64), hook))

    def add_streams(self, *epochs: Epochs) -> None:
        """Measurement streams besides GNSS position over the whole record (:class:`~imunoise.nav.streams.Epochs`, one
        per kind), applied as the filter reaches them (:mod:`imunoise.online.measurement_feed`: ``state.streams``)."""
        self.state.streams = MeasurementFeed(self.ekf, epochs, self.init.t)

    # -- streaming API ----------------------------------------------------------------------------
    def push_gnss(self, t: float, llh_rad: np.ndarray, sigma_ned_m: np.ndarray) -> None:
        """A GNSS antenna fix, applied after the first IMU sample with time ≥ t (immediately, referred back
        with the velocity, if that sample was already pushed).

        Parameters
        ----------
        t
            Fix time (s), same time base as the IMU samples.
        llh_rad
            (latitude rad, longitude rad, height m) of the antenna (docs/guide/theory.rst, 'Conventions': SI inside).
            Degrees are refused: a latitude beyond ±π/2 or a longitude beyond ±π raises :class:`DataError` (convert
            with ``np.radians``); so do non-finite values (skip fixes without a position).
        sigma_ned_m
            1σ of the fix along north, east, down (m), ≥ 0. A NaN σ is handled by the filter (replaced by
            ``EkfConfig.gnss_sigma_nan``, logged), as in the batch EKF.
        """
        self.push_checked_fix(*check_fix(t, llh_rad, sigma_ned_m))

    def push_checked_fix(self, t: float, llh: np.ndarray, sig: np.ndarray) -> None:
        """:meth:`push_gnss` of a fix :func:`~imunoise.online.stream_checks.check_fix` already passed (the replay
        checks a record's fixes at once: :func:`imunoise.online.chunks.run_record`)."""
        st = self.state
        fix = (t, llh, sig)
        if t <= st.t_last:
            if st.started and t > self.init.t and self.ekf.update_gnss(*fix):
                st.t_aided = st.t_last
                self.learner.fix_used(fix)
            return
        st.gnss.append(fix)

    def push_imu(self, t: float, dtheta: np.ndarray, dv: np.ndarray) -> None:
        """One IMU increment (Δθ rad, Δv m/s over (t_prev, t], body FRD): ``dtheta`` and ``dv`` three
        values each (else :class:`DataError`). Non-finite values are logged and handled by the filter.

        Parameters
        ----------
        t : float
            End of the increment [s]; stamps must increase strictly.
        dtheta, dv : numpy.ndarray
            Angle [rad] and velocity [m/s] increments, shape (3,).
        """
        t0 = time.perf_counter()
        st = self.state
        t, dth, dvv = check_increment(t, dtheta, dv, st.t_in)
        dt = t - st.t_in if math.isfinite(st.t_in) else self.dt_nom
        st.t_in = t
        self.feed.push(t, dth, dvv, dth / dt, dvv / dt, self.step_sample)
        st.elapsed += time.perf_counter() - t0

    def push_chunk(self, t, dtheta, dv, gnss_t=(), gnss_llh=(), gnss_sigma=()) -> None:
        """Many IMU increments (n,), (n, 3), (n, 3) and the fixes up to them at once: the same as :meth:`push_gnss`
        and :meth:`push_imu` in time order (fixes after ``t[-1]`` are queued), the filter run in kernel spans
        between events (:func:`imunoise.online.chunks.push_chunk`)."""
        push_chunk(self, t, dtheta, dv, gnss_t, gnss_llh, gnss_sigma)

    def solution(self) -> dict:
        """Current filter solution (IMU point): see :meth:`LooselyCoupledEKF.state`."""
        return self.ekf.state()

    def fork(self, *others: Any, share: tuple = ()) -> tuple:
        """A branch of the running navigator: an independent copy that continues from the same state, e.g. one GNSS
        outage per window from the same aided state (the dense-window protocol of :mod:`imunoise.experiments.dense`).
        Needs ``worker="inline"``: a thread cannot be copied. ``others`` are copied together with the navigator
        (references between them stay consistent); ``share`` are shared instead of copied (large read-only arrays;
        the modelling-job cache always). Returns ``(navigator, *others)``; the branch's stored epochs start empty,
        so its result holds only the epochs after the fork."""
        return fork_navigator(self, others, share)

    def finish(self) -> OnlineResult:
        """Close the stream: flush samples held for λ_0 learning, wait for a running thread job, and
        return the result.

        Returns
        -------
        OnlineResult
        """
        st = self.state
        t0 = time.perf_counter()
        if self.detector is None and self.feed.pending:
            self.feed.finish_learning(self.step_sample)
        self.modeller.finish(st.t_last)
        self.learner.finish(self)
        if self.detector is not None:
            self.detector.finish()
        st.elapsed += time.perf_counter() - t0
        st.event("end", st.t_last, static_s=self.static_s, n_updates=len(self.updates))
        return build_result(self)

    def run(self, imu, gnss, *, progress: Any = None) -> OnlineResult:
        """Replay a whole record (ImuData increments, GnssData); same result as pushing every sample and fix in
        time order through the streaming API.

        Parameters
        ----------
        imu : ImuData
            IMU increments (:func:`imunoise.io.kfgins.read_imu`).
        gnss : GnssData
            GNSS antenna fixes (:func:`imunoise.io.kfgins.read_gnss`).
        progress : callable, optional
            ``progress(n_done, n_total)``.

        Returns
        -------
        OnlineResult
        """
        return replay(self, imu, gnss, progress)

    # -- one sample -----------------------------------------------------------------------------------
    def step_sample(self, t, dth, dvv, gyro, accel, is_static: bool, gate_open: bool, segs) -> None:
        """The per-sample path of one increment whose detector verdict is known (``is_static``, ``gate_open``, the
        segments it completed): the bookkeeping, the filter step with its fixes, the stop guard's row, ZUPT, the
        learner, the stops and the model swaps. :meth:`push_imu` and the chunked replay's events take it."""
        cfg = self.config
        st = self.state
        for idx, hook in st.event_sources:
            if np.any(idx == st.n_samples):
                hook(self, st.n_samples)
        st.rows.append(np.concatenate([gyro, accel]))
        st.static_raw.append(is_static)
        st.sample_t.append(t)
        st.t_last = t
        st.n_samples += 1
        prev_run = st.static_run
        st.static_run = st.static_run + 1 if is_static else 0
        if st.static_run == 1:
            # a new raw static run: the previous run's segments were completed at its first non-static sample
            self.guard.new_run(st.n_samples - 1)
        if not is_static:
            st.zupt_rejected = False
        if st.static_run == st.stop_start_n and self.detector is not None:
            # the raw static run is now long enough to become a segment: a stop has started
            st.event("stop_start", t, t0=st.sample_t[-st.static_run])
        gate = bool(gate_open) and cfg.gate
        if gate != st.gate:
            st.gate = gate
            st.event("gate_open" if gate else "gate_closed", t)
        st.gate_log.append(gate)
        if t > self.init.t:
            if not st.started:
                st.started = True
                # previous increment for the coning/sculling terms, as run_ekf does
                self.ekf.prime(dth, dvv)
            self.ekf.set_gate(gate)
            self.ekf.propagate(dth, dvv, t)
            while st.gnss and st.gnss[0][0] <= t:
                fix = st.gnss.pop(0)
                if fix[0] > self.init.t and self.ekf.update_gnss(*fix):
                    st.t_aided = t
                    self.learner.fix_used(fix)
            if st.streams is not None:
                st.streams.step(self.ekf)
            if is_static and cfg.stop_guard == "nav":
                self.guard.record(t, self.ekf)
            if cfg.zupt:
                self.zupt.step(t, gate, self.ekf, self.current_models)
            if self.learner.motion is not None:
                self.learner.step(self, t, dth, dvv, is_static, prev_run)
        else:
            while st.gnss and st.gnss[0][0] <= t:
                st.gnss.pop(0)
            if is_static and cfg.stop_guard == "nav":
                self.guard.row(math.nan, math.nan, 0.0, math.nan)
        for s in segs:
            stop_completed(self, s, t)
        apply_due_models(self, t)
        if st.store is not None and st.started:
            store_epoch(st.store, self.ekf, t)
        # raw samples are needed only back to the start of a possible segment
        if not is_static and len(st.rows) > 4096:
            st.drop_old_rows(16)

    # -- modelling ------------------------------------------------------------------------------------
    def filter_models(self) -> list[Model]:
        """The six models (with their rate) the filter gets from the current fits (plain default where none)."""
        return filter_axis_models(self.fits, self.rate, self.config, floor=self.floor)


def run_online(imu, gnss, init: InitialState, config: OnlineConfig | None = None, *, initial_models=None,
               progress: Any = None, earlier_static: Sequence[np.ndarray] | None = None,
               streams: Sequence[Epochs] = ()) -> OnlineResult:
    """Batch convenience: ``OnlineNavigator(config, init).run(imu, gnss)`` at the rate ``imu.rate_hz``.

    Parameters
    ----------
    imu, gnss, init, config, initial_models, progress, earlier_static, streams
        As for :class:`OnlineNavigator` (``config`` default ``OnlineConfig()``), :meth:`OnlineNavigator.run` and
        :meth:`OnlineNavigator.add_streams` (``streams``).
    """
    config = config or OnlineConfig()
    nav = OnlineNavigator(config, init, imu_rate_hz=float(imu.rate_hz), initial_models=initial_models,
                          earlier_static=earlier_static)
    if streams:
        nav.add_streams(*streams)
    return nav.run(imu, gnss, progress=progress)
