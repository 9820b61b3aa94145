"""GNSS-available online experiment (paper §3.2, Tables 5–6; docs/guide/theory.rst, 'Experiments'), on the real drive or
the simulator.

Methods (``METHODS``): ``plain`` (default model), ``av`` and ``em`` (fixed models from all static data of
the record, in hindsight, as the paper's Table 5 baselines), ``gmwm`` (online, the paper's GOF criterion), ``gmwm_wvic``
(online, WVIC), ``gmwm_raw`` (online without the plain-default floor), ``gmwm_qndrop`` (QN not
used as filter noise, see :mod:`imunoise.online`), ``gmwm_zupt`` and
``plain_zupt`` (with ZUPT/ZARU while static), and on the simulator ``oracle`` (the true IMU model in the
filter: the ceiling of what any error model can gain against ``plain``) and ``oracle_law`` (the true model and
the motion law per sample, :mod:`imunoise.experiments.oracle_law`: the ceiling under any law).
Each method gets a full-GNSS run
(position RMS, ECEF and horizontal/vertical; the real drive's RTK reference is the aiding GNSS itself, so
those are residuals) and the outage runs (end-of-outage drift). Monte Carlo over simulator seeds runs seeds in parallel
processes; the differences to ``plain`` and ``av`` get paired 95 % CIs.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import (
    KFGINS_DRIVE0708,
    Scenario,
    baseline_fits,
    combine,
    evaluate,
    evaluate_full,
    evaluate_outages,
    filter_models,
    load_real,
    map_seeds,
    paired_ci,
    simulate_scenario,
    static_segments,
)
from imunoise.online import OnlineConfig

log = logging.getLogger(__name__)

__all__ = ["METHODS", "MC_METHODS", "DEMO_METHODS", "method_config", "run_real", "run_sim", "summarize_seeds",
           "window_paired"]

METHODS = ("plain", "av", "em", "gmwm", "gmwm_wvic", "gmwm_raw", "gmwm_qndrop", "gmwm_zupt", "plain_zupt")
MC_METHODS = ("plain", "av", "em", "gmwm", "gmwm_wvic", "gmwm_zupt", "plain_zupt", "oracle_law", "oracle")
DEMO_METHODS = ("plain", "av", "em", "gmwm", "gmwm_zupt")
METRIC_KEYS = ("horizontal_rms_m", "vertical_rms_m", "mean_outage_end_horizontal_m")


def method_config(name: str, sc: Scenario, base: OnlineConfig | None = None,
                  fits_cache: dict | None = None) -> tuple[OnlineConfig, Any]:
    """(OnlineConfig, initial models) of a method on a scenario.

    The ``gmwm`` family ranks candidates by GOF (paper Eq. 8), as the paper does; ``gmwm_wvic`` by WVIC,
    the library's default elsewhere.
    """
    base = (base or OnlineConfig()).with_(ekf=sc.ekf_config(), store=True, criterion="gof")
    if name == "plain":
        return base.with_(modelling=False), None
    if name == "plain_zupt":
        return base.with_(modelling=False, zupt=True), None
    if name == "gmwm":
        return base, None
    if name == "gmwm_dyn":
        from imunoise.online.motion_noise import MotionNoiseConfig

        return base.with_(motion_noise=MotionNoiseConfig()), None
    if name == "gmwm_wvic":
        return base.with_(criterion="wvic"), None
    if name == "gmwm_raw":
        return base.with_(floor="none"), None
    if name == "gmwm_qndrop":
        return base.with_(qn="drop"), None
    if name == "gmwm_zupt":
        return base.with_(zupt=True), None
    if name == "oracle":
        # the simulator's true per-axis models through the same fit → filter mapping, without the floor: the
        # moving-regime models of the motion law (the outages are driven), the ceiling of every method here
        if not sc.truth_models:
            raise ModelError("the oracle method needs a simulated scenario (true IMU models)")
        from imunoise.imu import AXES
        from imunoise.noise.model import Model
        from imunoise.noise.processes import WN

        none = Model([WN(sigma2=1e-30)])  # an axis the simulator left without errors
        truth = [sc.truth_models.get(ax, none) for ax in AXES]
        return base.with_(modelling=False), filter_models(truth, sc.rate, base.with_(floor="none"))
    if name in ("av", "em"):
        cache = fits_cache if fits_cache is not None else {}
        if "segments" not in cache:
            cache["segments"], _ = static_segments(sc)
        if name not in cache:
            cache[name] = baseline_fits(cache["segments"], sc.rate, name)
        return base.with_(modelling=False), filter_models(cache[name], sc.rate, base)
    raise ModelError(f"unknown method {name!r}; choose from {METHODS}")


# --------------------------------------------------------------------------------------------------
# real drive
# --------------------------------------------------------------------------------------------------
_SC: dict[str, Any] = {}


def _init_real(data_dir: str, start: float | None, base: OnlineConfig | None = None,
               windows: list | None = None, streams: Sequence[str] = ()) -> None:
    logging.getLogger("imunoise").setLevel(logging.WARNING)
    _SC["sc"] = load_real(data_dir, start=start, streams=streams)
    if windows is not None:
        _SC["sc"].windows = [tuple(w) for w in windows]
    _SC["cache"] = {}
    _SC["base"] = base


def _real_job(job: tuple[str, int]) -> tuple[str, int, dict]:
    """One run of a method: ``k = -1`` the full-GNSS run, else outage window k (README protocol)."""
    name, k = job
    sc = _SC["sc"]
    cfg, models = method_config(name, sc, _SC.get("base"), fits_cache=_SC["cache"])
    if k < 0:
        res = evaluate_full(sc, cfg, initial_models=models, keep=True)
        if name in ("av", "em"):
            res["_fits"] = _SC["cache"][name]
    else:
        res = evaluate_outages(sc, cfg, [sc.windows[k]], initial_models=models, keep=True)
    return name, k, res


def run_real(data_dir: str, *, methods: Sequence[str] = METHODS, workers: int = 2, start: float | None = None,
             progress: Callable[[str], None] | None = None,
             base: OnlineConfig | None = None, windows: list | None = None,
             streams: Sequence[str] = ()) -> tuple[dict, Scenario]:
    """The online experiment on a real dataset folder: ``results`` (docs/guide/theory.rst, 'Experiments' keys;
    per-method objects
    under ``_objects``) and the scenario. Runs (method × {full, window k}) are spread over ``workers``
    processes; ``progress(name)`` is called after every run. ``base``: the online settings the methods
    start from (default :class:`OnlineConfig`); ``windows``: outage windows (start, length) instead of the
    dataset's outage file."""
    _init_real(str(data_dir), start, base, windows, streams)
    sc = _SC["sc"]
    jobs = [(m, k) for m in methods for k in range(-1, len(sc.windows))]
    # baselines first (their fits are cached per worker), long online runs early for load balance
    jobs.sort(key=lambda j: (j[0] not in ("av", "em"), not j[0].startswith("gmwm")))
    parts: dict[str, dict[int, dict]] = {m: {} for m in methods}
    if workers > 1 and len(jobs) > 1:
        ctx = mp.get_context("fork")
        with ctx.Pool(workers, initializer=_init_real, initargs=(str(data_dir), start, base, windows, streams)) as pool:
            for name, k, res in pool.imap_unordered(_real_job, jobs):
                parts[name][k] = res
                if progress:
                    progress(name)
    else:
        for j in jobs:
            name, k, res = _real_job(j)
            parts[name][k] = res
            if progress:
                progress(name)
    raw = {m: combine(parts[m][-1], [parts[m][k] for k in range(len(sc.windows))]) for m in methods}
    results = _assemble(raw, methods, sc)
    results["data"] = str(data_dir)
    results["kfgins_outage_end_horizontal_m"] = KFGINS_DRIVE0708 if len(sc.windows) == 5 else None
    return results, sc


def _sections(res: dict) -> list[tuple[float, float]]:
    full = res["_full"]
    bounds = [s.t1 for s in full.segments if s.duration >= 5.0]
    t_end = float(full.t[-1]) if full.t.size else 0.0
    edges = sorted(set(bounds))
    return [(a, b) for a, b in zip(edges, edges[1:] + [t_end + 1e-6]) if b > a]


def _assemble(raw: dict[str, dict], methods: Sequence[str], sc: Scenario) -> dict:
    from imunoise.nav.metrics import section_rms

    results: dict[str, Any] = {"experiment": "online", "methods": {}, "windows": [list(w) for w in sc.windows]}
    objects: dict[str, Any] = {}
    for name in methods:
        r = raw[name]
        objects[name] = {k: r.pop(k) for k in list(r) if k.startswith("_")}
        results["methods"][name] = r
    g = next((m for m in ("gmwm", "gmwm_wvic", "gmwm_zupt") if m in objects), None)
    if g:
        full = objects[g]["_full"]
        results["timing"] = {"identification_s": full.timing["identification_s"],
                             "identification_per_axis_s": full.timing["identification_per_axis_s"],
                             "refit_s": full.timing["refit_s"], "refit_max_axis_s": full.timing["refit_max_axis_s"],
                             "method": g}
        secs = _sections(objects[g])
        table = []
        for name in ("plain", g):
            if name in objects:
                e = objects[name]["_err"]
                table.append({"method": name, "sections": section_rms(e, secs)})
        results["sections"] = {"bounds": secs, "rows": table,
                               "updates": [{"kind": u.kind, "t_stop": u.t_stop, "t_effect": u.t_effect,
                                            "static_s": u.static_s, "elapsed_s": float(sum(u.elapsed_s))}
                                           for u in full.updates]}
    results["_objects"] = objects
    results["paired"] = window_paired({m: [results["methods"][m].get("outage_end_horizontal_m") or []]
                                       for m in methods}, [list(sc.windows)])
    if "plain" in results["methods"]:
        results["improvement_vs_plain_pct"] = {
            n: {k: _pct(results["methods"][n].get(k), results["methods"]["plain"].get(k)) for k in METRIC_KEYS}
            for n in methods if n != "plain"
        }
    return results


def window_paired(ends: dict[str, list[list]], windows: list[list], *, n_boot: int = 2000, seed: int = 0) -> list[dict]:
    """The ``paired`` list of the per-window protocols (official windows): end-drift log-ratios of every method
    against ``plain`` (and ``static_var`` when run), bootstrap over drives and windows (:mod:`.stats`);
    ``ends[m]`` per drive the drift per window, ``windows`` per drive the (start, length) list."""
    from imunoise.experiments.stats import default_block, n_independent, paired_entry

    lengths = [w[1] for ws in windows for w in ws]
    if lengths:
        starts = sorted(w[0] for ws in windows for w in ws)
        step = min((b - a for a, b in zip(starts, starts[1:]) if b > a), default=max(lengths))
        block = default_block(max(lengths), step)
        n_ind: int | None = sum(n_independent([w[0] for w in ws], max(lengths)) for ws in windows)
    else:  # windows not given: taken as disjoint (every window independent)
        block, n_ind = 1, None
    out = []
    for base in ("plain", "static_var"):
        if base not in ends:
            continue
        for m in ends:
            if m == base or (m, base) == ("plain", "static_var"):
                continue
            out.append(paired_entry(m, base, "drift", ends, block, n_independent_total=n_ind, n_boot=n_boot,
                                    seed=seed))
    return out


def _pct(a, b) -> float | None:
    if a is None or b is None or not b:
        return None
    return float(100.0 * (1.0 - a / b))


# --------------------------------------------------------------------------------------------------
# simulator Monte Carlo
# --------------------------------------------------------------------------------------------------
def run_sim(seeds: Sequence[int], *, methods: Sequence[str] = MC_METHODS, workers: int = 2,
            progress: Callable[[int], None] | None = None, base: OnlineConfig | None = None,
            **scen_kw: Any) -> dict:
    """Monte Carlo of the online experiment over simulator ``seeds`` (``scen_kw`` → ``simulate_scenario``;
    ``base`` the online settings the methods start from)."""
    kw = dict(scen_kw)
    kw["_keep_seed"] = seeds[0] if len(seeds) else -1
    kw["_base"] = base
    per_seed = map_seeds(_sim_job_kw, [(int(s), tuple(methods), kw) for s in seeds], workers, progress)
    res = summarize_seeds(per_seed, methods)
    res["experiment"] = "online"
    res["data"] = "sim"
    res["scenario"] = dict(scen_kw)
    return res


def _sim_job_kw(args: tuple) -> dict:
    seed, methods, kw = args
    kw = dict(kw)
    keep = kw.pop("_keep_seed", -1)
    base = kw.pop("_base", None)
    return _sim_job_clean(seed, methods, kw, keep, base)


def _sim_job_clean(seed: int, methods: Sequence[str], kw: dict, keep_seed: int, base: OnlineConfig | None) -> dict:
    logging.getLogger("imunoise").setLevel(logging.WARNING)
    sc = simulate_scenario(seed, **kw)
    cache: dict = {}
    out: dict[str, Any] = {"seed": seed, "methods": {}, "windows": [list(w) for w in sc.windows]}
    for name in methods:
        if name == "oracle_law":  # the batch filter told the law's schedule (imunoise.experiments.oracle_law)
            from imunoise.experiments.oracle_law import evaluate_law

            out["methods"][name] = evaluate_law(sc, base=base)
            continue
        cfg, models = method_config(name, sc, base, fits_cache=cache)
        res = evaluate(sc, cfg, initial_models=models, keep=(seed == keep_seed and name == "gmwm"))
        if "_full" in res:
            full = res["_full"]
            out["_example"] = {"fits": full.fits, "events": full.events}
        for k in [k for k in res if k.startswith("_")]:
            res.pop(k)
        out["methods"][name] = res
    return out


def summarize_seeds(per_seed: list[dict], methods: Sequence[str]) -> dict:
    """Means over seeds (``methods``), paired CIs vs plain and AV (``differences``), per-seed values."""
    res: dict[str, Any] = {"seeds": [r["seed"] for r in per_seed], "methods": {}, "per_seed": {},
                           "differences": {}}
    for name in methods:
        rows = [r["methods"][name] for r in per_seed]
        res["per_seed"][name] = [{k: r.get(k) for k in (*METRIC_KEYS, "ecef_rms_m", "outage_end_horizontal_m")}
                                 for r in rows]
        m: dict[str, Any] = {}
        for k in METRIC_KEYS:
            v = np.array([np.nan if r.get(k) is None else r[k] for r in rows], dtype=float)
            m[k] = float(np.nanmean(v)) if np.any(np.isfinite(v)) else None
        m["ecef_rms_m"] = np.nanmean(np.array([r["ecef_rms_m"] for r in rows], dtype=float), axis=0).tolist()
        ends = [r["outage_end_horizontal_m"] for r in rows]
        width = max((len(e) for e in ends), default=0)
        arr = np.full((len(ends), width), np.nan)
        for i, e in enumerate(ends):
            arr[i, :len(e)] = [np.nan if x is None else x for x in e]
        m["outage_end_horizontal_m"] = np.nanmean(arr, axis=0).tolist() if width else []
        m["realtime_factor"] = float(np.mean([r["realtime_factor"] for r in rows]))
        res["methods"][name] = m
    for name in methods:
        d = {}
        for ref in ("plain", "av"):
            if ref == name or ref not in methods:
                continue
            d[f"vs_{ref}"] = {
                k: paired_ci([r["methods"][name][k] for r in per_seed], [r["methods"][ref][k] for r in per_seed])
                for k in METRIC_KEYS
            }
        res["differences"][name] = d
    res["paired"] = window_paired({m: [r["methods"][m].get("outage_end_horizontal_m") or [] for r in per_seed]
                                   for m in methods}, [r.get("windows") or [] for r in per_seed])
    timing = [r["methods"]["gmwm"]["timing"] for r in per_seed if "gmwm" in r["methods"]]
    if timing:
        ident = [t["identification_s"] for t in timing if t["identification_s"] is not None]
        per_axis = [x for t in timing for x in t["identification_per_axis_s"]]
        refits = [x for t in timing for x in t["refit_max_axis_s"]]
        res["timing"] = {"identification_s": float(np.mean(ident)) if ident else None,
                         "identification_max_axis_s": float(max(per_axis)) if per_axis else None,
                         "refit_s": [x for t in timing for x in t["refit_s"]],
                         "refit_max_axis_s": float(max(refits)) if refits else None}
    ex = next((r["_example"] for r in per_seed if "_example" in r), None)
    if ex is not None:
        res["_objects"] = {"example": ex}
    return res
