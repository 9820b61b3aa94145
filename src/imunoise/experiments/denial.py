"""GNSS-denial experiment (paper §3.1, Table 1; docs/guide/theory.rst, 'Experiments'): static recording → models → 60 s
outages.

The IMU is modelled from static data: on the simulator a separate 2 h static recording of the same IMU
model (the paper's set-up; with a replayed real recording, ``imu_noise``, its last part that no drive
uses), on the real drive all static segments of the drive itself (it has no
separate static recording; 66 s of stops). Models: the top 3 by GOF (paper Eq. 8) of the selection over
the complete model (``gmwm`` = the best, ``gmwm_top2``, ``gmwm_top3``), the best by WVIC (``gmwm_wvic``), the AV
model (``av``); ``plain`` is the default model. Each drives the EKF (fixed model, same fit → filter
mapping) through the outage windows; the table is the horizontal drift at each window's end and the %
improvement of the mean over plain.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from imunoise.experiments.common import (
    KFGINS_DRIVE0708,
    SIM_IMU,
    Scenario,
    baseline_fits,
    evaluate,
    filter_models,
    load_real,
    map_seeds,
    simulate_scenario,
    static_segments,
)
from imunoise.experiments.online_exp import summarize_seeds
from imunoise.online import OnlineConfig

log = logging.getLogger(__name__)

__all__ = ["METHODS", "static_models", "run_real", "run_sim"]

METHODS = ("plain", "av", "gmwm_top3", "gmwm_top2", "gmwm", "gmwm_wvic")
LABELS = {"plain": "plain LC (default model)", "av": "AV model", "gmwm_top3": "GMWM 3rd by GOF",
          "gmwm_top2": "GMWM 2nd by GOF", "gmwm": "GMWM best by GOF", "gmwm_wvic": "GMWM best by WVIC"}


def static_models(segments: list[np.ndarray], freq: float, *, complete: str | None = None) -> dict[str, Any]:
    """Per method the six fits (gyro x..accel z) from static data: AV, GMWM top-3 by GOF, best by WVIC.
    Also ``rankings`` (six ModelRanking) and ``timing_s`` (selection time per axis)."""
    from imunoise.noise.selection import select_model

    out: dict[str, Any] = {"av": baseline_fits(segments, freq, "av"), "gmwm": [], "gmwm_top2": [],
                           "gmwm_top3": [], "gmwm_wvic": [], "rankings": [], "timing_s": []}
    for a in range(6):
        unit = "rad/s" if a < 3 else "m/s²"
        kw = {"complete": complete} if complete else {}
        r = select_model([s[:, a] for s in segments], freq=freq, criterion="gof", top=3, unit=unit, **kw)
        fits = r.fits
        out["gmwm"].append(fits[0])
        out["gmwm_top2"].append(fits[min(1, len(fits) - 1)])
        out["gmwm_top3"].append(fits[min(2, len(fits) - 1)])
        out["gmwm_wvic"].append(min(fits, key=lambda f: (f.extra.get("wvic", np.inf), f.n_params)))
        out["rankings"].append(r)
        out["timing_s"].append(r.elapsed_s)
    return out


def _evaluate_all(sc: Scenario, models: dict, methods: Sequence[str], keep: bool) -> dict[str, dict]:
    base = OnlineConfig(ekf=sc.ekf_config(), modelling=False)
    out = {}
    for name in methods:
        init = None if name == "plain" else filter_models(models[name], sc.rate, base)
        out[name] = evaluate(sc, base, initial_models=init, keep=keep)
    return out


def run_real(data_dir: str, *, methods: Sequence[str] = METHODS, start: float | None = None,
             progress: Callable[[str], None] | None = None, complete: str | None = None,
             streams: Sequence[str] = ()) -> tuple[dict, Scenario]:
    """Denial experiment on a real drive: models from the drive's own static segments; ``streams``: the manifest's
    measurement sources every run applies (:func:`~imunoise.experiments.common.load_real`)."""
    sc = load_real(data_dir, start=start, streams=streams)
    segs, det = static_segments(sc)
    models = static_models(segs, sc.rate, complete=complete)
    raw = {}
    base = OnlineConfig(ekf=sc.ekf_config(), modelling=False)
    for name in methods:
        init = None if name == "plain" else filter_models(models[name], sc.rate, base)
        raw[name] = evaluate(sc, base, initial_models=init, keep=True)
        if progress:
            progress(name)
    objects = {n: {k: r.pop(k) for k in list(r) if k.startswith("_")} for n, r in raw.items()}
    res: dict[str, Any] = {
        "experiment": "denial", "data": str(data_dir), "methods": raw, "windows": [list(w) for w in sc.windows],
        "static_s": float(sum(s.shape[0] for s in segs) / sc.rate),
        "models": {n: [str(f.model) for f in models[n]] for n in methods if n != "plain"},
        "timing": {"identification_s": float(sum(models["timing_s"])), "identification_per_axis_s": models["timing_s"],
                   "refit_s": []},
        "kfgins_outage_end_horizontal_m": KFGINS_DRIVE0708 if len(sc.windows) == 5 else None,
    }
    res["improvement_vs_plain_pct"] = {
        n: 100.0 * (1 - raw[n]["mean_outage_end_horizontal_m"] / raw["plain"]["mean_outage_end_horizontal_m"])
        for n in methods if n != "plain" and "plain" in raw
    }
    res["_objects"] = {"runs": objects, "models": models, "detection": det}
    return res, sc


_REPLAY_MODELS: dict[tuple, dict] = {}


def _replay_models(path: str, static_s: float, rate: float, complete: str | None) -> dict:
    """:func:`static_models` of a replayed recording's static part (:func:`imunoise.sim.replay.static_part`), fitted
    once per process: every seed of a run shares that part, so the fits are the same for all."""
    key = (path, float(static_s), float(rate), complete)
    if key not in _REPLAY_MODELS:
        from imunoise.sim.replay import load_recording, static_part

        errors = static_part(load_recording(path), static_s, rate)
        _REPLAY_MODELS[key] = static_models([errors - errors.mean(axis=0)], 100.0, complete=complete)
    return _REPLAY_MODELS[key]


def _sim_job(args: tuple) -> dict:
    seed, methods, static_s, scen_kw = args
    scen_kw = dict(scen_kw)
    complete = scen_kw.pop("_complete", None)
    logging.getLogger("imunoise").setLevel(logging.WARNING)
    from imunoise.sim import simulate_static

    imu_models = scen_kw.get("imu_models", SIM_IMU)
    rate = float(scen_kw.get("imu_rate_hz", 100.0))
    if scen_kw.get("imu_noise"):  # real noise: the end of the recording, which no drive uses (same for every seed)
        models = _replay_models(scen_kw["imu_noise"], static_s, rate, complete)
    else:
        errors = simulate_static(imu_models, duration_s=static_s, rate_hz=rate, seed=10_000 + seed).errors
        models = static_models([errors - errors.mean(axis=0)], 100.0, complete=complete)
    sc = simulate_scenario(seed, **scen_kw)
    res = _evaluate_all(sc, models, methods, keep=False)
    out = {"seed": seed, "methods": res,
           "models": {n: [str(f.model) for f in models[n]] for n in methods if n != "plain"},
           "selection_s": models["timing_s"]}
    for r in out["methods"].values():
        for k in [k for k in r if k.startswith("_")]:
            r.pop(k)
        r.setdefault("timing", {"identification_s": None, "identification_per_axis_s": [], "refit_s": [],
                                "refit_max_axis_s": []})
    if seed == scen_kw.get("seed0", seed):
        out["_example"] = {"fits": models["gmwm"], "av": models["av"]}
    return out


def run_sim(seeds: Sequence[int], *, methods: Sequence[str] = METHODS, workers: int = 2,
            static_recording_s: float = 7200.0,
            progress: Callable[[int], None] | None = None, complete: str | None = None, **scen_kw: Any) -> dict:
    """Monte Carlo of the denial experiment over simulator seeds (a ``static_recording_s`` recording of the same
    IMU model per seed; ``complete`` the selection's complete model, default the paper's)."""
    jobs = [(int(s), tuple(methods), float(static_recording_s), {**scen_kw, "_complete": complete}) for s in seeds]
    if scen_kw.get("imu_noise"):  # fit the shared static part here, before the workers fork, not once per seed
        _replay_models(scen_kw["imu_noise"], float(static_recording_s), float(scen_kw.get("imu_rate_hz", 100.0)),
                       complete)
    per_seed = map_seeds(_sim_job, jobs, workers, progress)
    for r in per_seed:
        r["methods"].setdefault("gmwm", r["methods"].get("gmwm"))
    res = summarize_seeds(per_seed, list(methods))
    res["experiment"] = "denial"
    res["data"] = "sim"
    res["scenario"] = dict(scen_kw)
    res["static_s"] = static_recording_s
    res["models_per_seed"] = [r["models"] for r in per_seed]
    sel = [x for r in per_seed for x in r["selection_s"]]
    res["timing"] = {"identification_s": float(np.mean(sel)) * 6 if sel else None,
                     "identification_max_axis_s": float(max(sel)) if sel else None, "refit_s": []}
    ex = per_seed[0].get("_example") if per_seed else None
    if ex is not None:
        res["_objects"] = {"example": ex}
    return res
