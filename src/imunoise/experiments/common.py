"""Shared pieces of the paper's experiments (docs/guide/theory.rst, 'Experiments'): scenarios, baselines, filter runs,
metrics, CIs.

A :class:`Scenario` is one drive with a reference: the real drive (a dataset folder with a manifest,
docs/guide/theory.rst, 'Interfaces') or a simulated one (docs/guide/theory.rst, 'Simulator'). Every method is run
through :class:`imunoise.online.OnlineNavigator`
(fixed-model baselines with ``modelling=False``), so methods differ only in their error models.
All static-derived models (AV, EM, GMWM) pass through the same fit → filter mapping
(:func:`imunoise.online.filter_axis_models`, floor = the plain default), so the comparison is about the
models, not about the mapping.
"""

from __future__ import annotations

import logging
import math
import multiprocessing as mp
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from imunoise.detect import DetectorConfig, detect_static, learn_lambda0, segment_data
from imunoise.errors import DataError, ImunoiseError, ModelError
from imunoise.imu import AXES
from imunoise.nav.defaults import EkfConfig
from imunoise.nav.ekf import InitialState
from imunoise.nav.metrics import nav_errors, summarize
from imunoise.online import OnlineConfig, OnlineNavigator, OnlineResult, filter_axis_models

log = logging.getLogger(__name__)

__all__ = [
    "Scenario", "load_real", "simulate_scenario", "static_segments", "baseline_fits", "filter_models",
    "run_filter", "evaluate", "evaluate_full", "evaluate_outages", "combine",
    "paired_ci", "map_seeds", "METHOD_LABELS", "SIM_IMU", "SIM_MOTION", "repo_data_dir", "imu_noise_kwargs",
    "replay_methods",
]

SIM_IMU = "paper"  # gyros of paper Table 4 (3*AR1+WN+RW per axis), accelerometers of the "mems" preset
# motion law of the simulated errors: imunoise.sim.motion.DEFAULT_MOTION (calibrated on the real drive; named
# here so that importing the experiments does not import the simulator)
SIM_MOTION = "drive0708"
KFGINS_DRIVE0708 = [335.5, 520.9, 42.7, 398.6, 310.8]  # m, README of the shared drive

METHOD_LABELS = {
    "plain": "plain LC (default model)",
    "plain_zupt": "plain LC + ZUPT/ZARU",
    "av": "AV-based (all static data)",
    "em": "EM-based (all static data, AV start)",
    "gmwm": "online GMWM (GOF, paper)",
    "gmwm_wvic": "online GMWM (WVIC)",
    "gmwm_raw": "online GMWM (no floor)",
    "gmwm_qndrop": "online GMWM (QN not in the filter)",
    "gmwm_zupt": "online GMWM + ZUPT/ZARU",
    "gmwm_top3": "GMWM 3rd by GOF",
    "gmwm_top2": "GMWM 2nd by GOF",
    "oracle": "true IMU model (simulator only)",
    "oracle_law": "true IMU model and motion law, per sample (simulator only)",
}


def repo_data_dir() -> Path:
    """``data/drive_0708`` of the source tree (the demo's data), found relative to this file."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "data" / "drive_0708"
        if (cand / "dataset.json").exists():
            return cand
    raise DataError("data/drive_0708 not found next to the source tree; pass --data DIR")


@dataclass(eq=False)
class Scenario:
    """One drive: IMU (increments), GNSS, reference, lever arm, initial state, outage windows.

    ``outage_runs``: run every window separately from the same start (the real drive's protocol) or all
    windows in one run (simulator: windows are far apart). ``static_truth`` (per IMU sample) when known.
    """

    name: str
    imu: Any
    gnss: Any
    ref: Any
    lever: np.ndarray
    init: InitialState
    windows: list[tuple[float, float]]
    outage_runs: bool
    static_truth: np.ndarray | None = None
    truth_models: dict | None = None
    extra: dict = field(default_factory=dict)

    @property
    def rate(self) -> float:
        return float(self.imu.rate_hz)

    @property
    def duration(self) -> float:
        return float(self.imu.t[-1] - self.init.t)

    def ekf_config(self) -> EkfConfig:
        """The filter settings of this drive: its lever arm, plus ``extra["ekf"]`` (e.g. the simulator's
        turn-on bias σ as the initial bias σ, as a datasheet would give it)."""
        return EkfConfig(lever_arm=tuple(float(x) for x in self.lever)).with_(**self.extra.get("ekf", {}))


def load_real(data_dir: str | Path, *, start: float | None = None, static_duration: float = 30.0,
              streams: Sequence[str] = ()) -> Scenario:
    """The real drive in a dataset folder (docs/guide/theory.rst, 'Interfaces'). Start time: ``start``, else the
    manifest's ``start_sow``, else the first GNSS epoch; alignment from the first ``static_duration`` s (a stop).
    ``streams``: keys of measurement sources (:mod:`imunoise.nav.aiding_sources`, e.g. ``gnss_vel``) read from the
    files the manifest names under them, into ``extra["streams"]`` (every online run of the drive applies them)."""
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_gnss, read_imu, read_outages, read_reference
    from imunoise.nav.align import coarse_align

    ds = read_dataset(data_dir)
    imu = read_imu(ds.imu, time_offset=ds.imu_time_offset_s)
    gnss = read_gnss(ds.gnss)
    if ds.ref is None:
        raise DataError(f"{ds.root}: the experiments need a reference ('ref' in dataset.json)")
    ref = read_reference(ds.ref)
    windows = read_outages(ds.outages) if ds.outages else []
    t0 = start if start is not None else ds.extra.get("start_sow")
    if t0 is None:
        t0 = max(float(imu.t[0]), float(gnss.t[0]))
    lever = np.asarray(ds.lever_arm_m, dtype=float)
    init = coarse_align(imu, gnss, float(t0), static_duration=static_duration, lever_arm=lever)
    extra_streams = []
    for key in streams:
        from imunoise.nav.aiding_sources import source

        if not ds.extra.get(key):
            raise DataError(f"{ds.root}/dataset.json names no '{key}' file; add it or drop the option")
        extra_streams.append(source(key).read(ds.root / ds.extra[key], imu_t=imu.t, gnss=gnss, option=key))
    static_truth = None
    try:
        from imunoise.detect import static_truth_from_speed

        static_truth = static_truth_from_speed(imu.t, ref.t, ref.vel_ned, 0.2)
    except ImunoiseError:
        pass
    return Scenario(ds.name, imu, gnss, ref, lever, init, windows, outage_runs=True, static_truth=static_truth,
                    extra={"root": str(ds.root), "license": ds.license, "streams": extra_streams})


def simulate_scenario(seed: int, *, duration_s: float = 600.0, n_stops: int = 4, n_outages: int = 4,
                      imu_models: Any = SIM_IMU, outage_s: float = 60.0, outage_lead_s: float = 60.0,
                      match_bias_prior: bool = True, motion_noise: Any = SIM_MOTION, streams: Sequence[str] = (),
                      **drive_kw: Any) -> Scenario:
    """A simulated urban drive (docs/guide/theory.rst, 'Simulator') with ``n_outages`` windows of ``outage_s`` (all in
    one run), the first
    no earlier than ``outage_lead_s`` of GNSS-aided driving after the static start. ``match_bias_prior``: the
    filter's initial bias σ is set to the simulated turn-on bias σ (else the :class:`EkfConfig` defaults).
    ``motion_noise``: the motion law of the IMU errors (:mod:`imunoise.sim.motion`; default the preset
    calibrated on the real drive, ``"none"``: moving = static); ``truth_models`` are the moving-regime models
    (what the ``oracle`` method filters with), ``extra["static_models"]`` the static ones.

    Why the lead (default 60 s): the online model exists only after the first stop (the static start, 60 s),
    and a window that opens seconds after the car starts moving tests the alignment, not the error model:
    every method enters it with the same state. Measured on 20 seeds (paper preset), a window 3 s after the
    start dominated the mean drift (248 m for plain and online GMWM alike on seed 2). ``streams``: keys of
    measurement sources simulated from the drive's truth (:func:`imunoise.nav.aiding_sources.simulate_all`, seeded
    by ``seed``) into ``extra["streams"]`` (every online run of the drive applies them)."""
    from imunoise.nav.aiding_sources import simulate_all
    from imunoise.nav.align import coarse_align
    from imunoise.sim import DriveConfig, simulate_drive

    cfg = DriveConfig(duration_s=duration_s, n_stops=n_stops, seed=seed, motion_noise=motion_noise, **drive_kw)
    drive = simulate_drive(cfg, imu_models, seed=seed)
    windows = drive.outage_windows(n_outages, outage_s, lead_s=outage_lead_s) if n_outages else []
    # the filter's initial bias σ = the simulated turn-on σ (what a datasheet tells the user), where there is one
    ekf = {k: v for k, v in (("sigma_gyro_bias0", cfg.gyro_bias_sigma), ("sigma_accel_bias0", cfg.accel_bias_sigma))
           if v > 0} if match_bias_prior else {}
    a, b = drive.truth["static_intervals"][0]
    t_start = float(drive.imu.t[0]) + 1.0
    init = coarse_align(drive.imu, drive.gnss, t_start, static_window=(a, b), lever_arm=cfg.lever_arm_m)
    return Scenario(f"simulated drive (seed {seed})", drive.imu, drive.gnss, drive.reference,
                    np.asarray(cfg.lever_arm_m, dtype=float), init, windows, outage_runs=False,
                    static_truth=drive.static_mask, truth_models=drive.moving_models,
                    extra={"stops": drive.truth["stops"], "seed": seed, "ekf": ekf, "static_models": drive.imu_models,
                           "motion_noise": drive.truth["motion_noise"], "law_schedule": drive.law_schedule,
                           "streams": list(simulate_all(drive, seed, streams).values()) if streams else []})


def imu_noise_kwargs(path: str | None, seed0: int, *, imu: Any = None, reserve_s: float = 0.0,
                     vehicle_drives: int = 1) -> dict:
    """Scenario keywords that replay the static recording ``path`` as the drives' IMU errors
    (:mod:`imunoise.sim.replay`; ``--imu-noise``): drive d = seed − ``seed0`` gets the d-th stretch, the last
    ``reserve_s`` s stay for the denial experiment's static recording. With ``vehicle_drives`` K > 1 vehicle d
    gets stretches d·K … d·K + K − 1, its scored drive the last (:func:`imunoise.sim.replay.stretch_index`). The
    file is read and checked now.

    Raises
    ------
    ModelError, DataError
        With ``--imu`` also given (the recording is the IMU's errors), or for an unreadable recording.
    """
    if path is None:
        return {}
    if imu:
        raise ModelError("--imu and --imu-noise exclude each other: the replayed recording is the IMU's errors")
    from imunoise.sim.replay import load_recording

    rec = load_recording(str(Path(path).resolve()))
    kw = {"imu_noise": rec.path, "imu_noise_first": int(seed0), "imu_noise_reserve_s": float(reserve_s),
          "imu_models": None}
    if int(vehicle_drives) > 1:  # only then: a single-drive run's scenario record stays as it was
        kw["imu_noise_drives"] = int(vehicle_drives)
    return kw


def replay_methods(methods: Sequence[str], explicit: bool) -> tuple[str, ...]:
    """The methods of a replayed-noise run: ``oracle`` and ``oracle_law`` need true models, which a real
    recording has not; they are dropped from a default list and refused when asked for."""
    for m in ("oracle", "oracle_law", "oracle_const"):
        if m in methods and explicit:
            raise ModelError(f"--methods {m} needs the simulator's true IMU models; with --imu-noise the errors are "
                             f"a real recording (no true model): leave {m} out")
    return tuple(m for m in methods if m not in ("oracle", "oracle_law", "oracle_const"))


# --------------------------------------------------------------------------------------------------
# static data and baselines
# --------------------------------------------------------------------------------------------------
def static_segments(sc: Scenario, learn_s: float = 10.0) -> tuple[list[np.ndarray], Any]:
    """All static segments of the whole record (hindsight; the AV/EM baselines' data), bias removed,
    columns gyro x,y,z, accel x,y,z (SI), with the online detector's settings (λ_0 learned from the
    first ``learn_s`` seconds)."""
    gyro, accel = sc.imu.rates()
    t = sc.imu.t
    lam = learn_lambda0(accel[t < t[0] + learn_s])
    det = detect_static(t, accel, gyro, DetectorConfig(lambda0=lam))
    if not det.segments:
        raise DataError("no static segment detected; the AV/EM baselines need static data")
    return segment_data(det, np.column_stack([gyro, accel])), det


def baseline_fits(segments: list[np.ndarray], freq: float, which: str) -> list:
    """Six fits (gyro x..accel z) of the AV (``"av"``) or EM (``"em"``) baseline on static segments."""
    from imunoise.noise.allan import allan_fit

    out = []
    for a in range(6):
        unit = "rad/s" if a < 3 else "m/s²"
        data = [s[:, a] for s in segments]
        av = allan_fit(data, freq=freq, unit=unit)
        if which == "av":
            out.append(av)
            continue
        from imunoise.noise.em import em_fit
        from imunoise.noise.model import Model

        start = av.model
        if start.has("QN") or start.has("DR"):
            # EM has no QN state (docs/guide/theory.rst, 'Baselines'); start from the rest, or from white noise of the
            # data's variance
            from imunoise.noise.processes import RW, WN

            rest = [c for c in start.components if c.kind not in ("QN", "DR")]
            v = float(np.var(np.concatenate(data)))
            if not any(c.kind == "WN" for c in rest):  # EM's observation noise
                rest.append(WN(sigma2=0.5 * v))
            if len(rest) == 1:
                rest.append(RW(gamma2=1e-6 * v))
            start = Model(rest)
        try:
            out.append(em_fit(start.unknown(), data, freq=freq, init=start, unit=unit, max_iter=200))
        except ImunoiseError as exc:
            log.warning("EM baseline failed on %s (%s): using the AV model", AXES[a], exc)
            out.append(av)
    return out


def filter_models(fits: list, freq: float, config: OnlineConfig | None = None) -> list:
    """The six filter models of fixed fits (or bare models), through the online engine's own mapping
    (:func:`imunoise.online.filter_axis_models`)."""
    return filter_axis_models(fits, freq, config)


# --------------------------------------------------------------------------------------------------
# runs and metrics
# --------------------------------------------------------------------------------------------------
def run_filter(sc: Scenario, config: OnlineConfig, *, initial_models=None, windows=None) -> OnlineResult:
    """One online run with GNSS removed inside ``windows`` (default none). Modelling jobs are shared between
    the runs of one scenario (``sc.extra["job_cache"]``): the static data do not depend on GNSS."""
    gnss = sc.gnss.without(windows) if windows else sc.gnss
    cache = sc.extra.setdefault("job_cache", {})
    nav = OnlineNavigator(config, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models, job_cache=cache)
    if sc.extra.get("streams"):  # GNSS velocity, odometer, ...: through the outages too
        nav.add_streams(*sc.extra["streams"])
    return nav.run(sc.imu, gnss)


def evaluate_full(sc: Scenario, config: OnlineConfig, *, initial_models=None, keep: bool = False) -> dict:
    """The full-GNSS run of one method: position RMS (m), timing; ``_full``/``_err`` when ``keep``."""
    full = run_filter(sc, config, initial_models=initial_models)
    err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
    m = summarize(err, elapsed_s=full.elapsed_s, duration_s=sc.duration)
    out: dict[str, Any] = {
        "horizontal_rms_m": m["horizontal_rms_m"],
        "vertical_rms_m": m["vertical_rms_m"],
        "ecef_rms_m": m["ecef_rms_m"],
        "horizontal_max_m": m["horizontal_max_m"],
        "elapsed_s": full.elapsed_s,
        "realtime_factor": m["realtime_factor"],
        "timing": full.timing,
        "n_updates": len(full.updates),
    }
    if keep:
        out["_full"] = full
        out["_err"] = err
    return out


def evaluate_outages(sc: Scenario, config: OnlineConfig, windows, *, initial_models=None,
                     keep: bool = False) -> dict:
    """One run without GNSS in ``windows``: horizontal/vertical error at each window's end (m)."""
    r = run_filter(sc, config, initial_models=initial_models, windows=windows)
    e = nav_errors(r.t, r.antenna_llh(sc.lever), r.vel_ned, r.euler, sc.ref)
    outs = summarize(e, outages=windows)["outages"]
    out: dict[str, Any] = {"ends": [o["end_horizontal_m"] for o in outs], "ends_v": [o["end_vertical_m"] for o in outs]}
    if keep:
        out["_run"] = (windows[0] if len(windows) == 1 and sc.outage_runs else None, r, e)
    return out


def combine(full: dict, outage_parts: list[dict]) -> dict:
    """Merge a full-run result and the outage runs (in window order) into the docs/guide/theory.rst, 'Experiments'
    method entry."""
    out = dict(full)
    ends = [x for p in outage_parts for x in p["ends"]]
    out["outage_end_horizontal_m"] = ends
    out["outage_end_vertical_m"] = [x for p in outage_parts for x in p["ends_v"]]
    good = [x for x in ends if x is not None]
    out["mean_outage_end_horizontal_m"] = float(np.mean(good)) if good else None
    runs = [p["_run"] for p in outage_parts if "_run" in p]
    if runs:
        out["_runs"] = runs
    return out


def evaluate(sc: Scenario, config: OnlineConfig, *, initial_models=None, keep: bool = False) -> dict:
    """Full-GNSS run + outage run(s) of one method (one per window when ``sc.outage_runs``)."""
    full = evaluate_full(sc, config, initial_models=initial_models, keep=keep)
    parts = []
    if sc.windows:
        groups = [[w] for w in sc.windows] if sc.outage_runs else [list(sc.windows)]
        parts = [evaluate_outages(sc, config, g, initial_models=initial_models, keep=keep) for g in groups]
    return combine(full, parts)


def map_seeds(job: Callable[[tuple], dict], jobs: Sequence[tuple], workers: int,
              progress: Callable[[int], None] | None = None) -> list[dict]:
    """Run one Monte Carlo ``job`` per entry of ``jobs`` (its first item is the seed) in ``workers`` forked
    processes (inline when 1), calling ``progress(seed)`` after each; results sorted by their ``"seed"``."""
    out: list[dict] = []
    if workers > 1 and len(jobs) > 1:
        with mp.get_context("fork").Pool(workers) as pool:
            for r in pool.imap_unordered(job, jobs):
                out.append(r)
                if progress:
                    progress(r["seed"])
    else:
        for j in jobs:
            out.append(job(j))
            if progress:
                progress(j[0])
    out.sort(key=lambda r: r["seed"])
    return out


def paired_ci(a: np.ndarray, b: np.ndarray, level: float = 0.95) -> dict:
    """Mean of the paired differences a − b with a Student-t CI, and the relative change of the means
    100·(mean a / mean b − 1) % with a CI from the delta method on the paired means."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    n = a.size
    if n < 2:
        return {"n": int(n), "mean_diff": math.nan, "ci": [math.nan, math.nan], "rel_pct": math.nan,
                "rel_ci_pct": [math.nan, math.nan], "excludes_zero": False}
    d = a - b
    tq = float(stats.t.ppf(0.5 + level / 2, n - 1))
    se = float(np.std(d, ddof=1) / math.sqrt(n))
    md = float(d.mean())
    ma, mb = float(a.mean()), float(b.mean())
    # ratio of means R = ma/mb; Var(R) ≈ Var(a − R b)/(n mb²)
    r = ma / mb
    se_r = float(np.std(a - r * b, ddof=1) / (math.sqrt(n) * abs(mb)))
    return {
        "n": int(n), "mean_diff": md, "ci": [md - tq * se, md + tq * se],
        "rel_pct": 100 * (r - 1), "rel_ci_pct": [100 * (r - tq * se_r - 1), 100 * (r + tq * se_r - 1)],
        "excludes_zero": bool(md - tq * se > 0 or md + tq * se < 0),
    }
