"""Dense outage protocol with paired statistics (issue "Evidence with power" §1; docs/guide/theory.rst, 'Experiments').

Windows. Outage windows of length L (default 60 s) open every S s (default 20 s) wherever GNSS was
available for the preceding ``lead`` s (default 60 s; no gap between aiding fixes longer than
:data:`MAX_GAP_S`); availability is judged on the recorded fixes, so every GNSS regime and noise seed
uses the same windows (``--outages dense:L:S[:LEAD]``).

One run per window from the same aided state, at the cost of L s per window. Each method runs once through
the drive with GNSS everywhere, in streaming mode: :meth:`OnlineNavigator.push_chunk` from one window start
to the next (the filter in kernel spans between events; equal to ``push_imu``/``push_gnss`` sample by sample
to the bit, which a method with a per-sample policy, the stop refits and the adaptive noise, still uses). When
the stream reaches a window's start the navigator is copied (:meth:`OnlineNavigator.fork`; inline worker, so
there is no thread to copy; the modelling-job cache and the IMU arrays are shared, not copied) and the copy
continues with the window's IMU and no GNSS inside the window, in one chunk, to the sample of the window's
last reference epoch (the per-sample path, to L + 1 s). The copy *is* a full run with that window's GNSS
removed, up to the window end: tests/experiments/test_experiments_dense.py checks it to 1e-9 m. Per window
(read from the branch's stored epochs; no result over the whole drive is built): the end drift (horizontal
error at the last reference epoch inside the window, as :func:`imunoise.nav.metrics.outage_drift`), the
horizontal RMS inside the window, and the aided run's horizontal RMS over the same span (``aided_rms``: the
GNSS-available metric of the paper's Table 5, per window, so it can be paired too).

Methods (:data:`EVIDENCE_METHODS`; every other name of :func:`imunoise.experiments.online_exp.method_config`
works too): ``plain``; ``static_var`` — the model-free baseline: for each axis the variance of the
bias-removed static samples of the stops detected so far (online protocol), as white noise σ² per
sample, nothing else; it goes through the same fit → filter mapping as every model, so the filter keeps the
plain default's bias states (random walk and the 3600 s Gauss–Markov bias) and its white noise is
max(static variance, plain white); ``static_var_hindsight`` the same on all static data of the record;
``av``/``em`` (all static data, hindsight, the paper's baselines); ``av_online``/``em_online`` — AV/EM fitted
on the stops detected so far (refit after every stop once ``min_static_s`` of static data exist, like the
online engine, and swapped into the filter at the stop's completion, keeping every state whose structure
is unchanged); ``gmwm`` (the online engine, the paper's GOF); ``gmwm_hindsight`` (GMWM, GOF, on all static
data); ``oracle`` on the simulator; ``adaptive`` — the plain filter with its bias process noise scaled
online by covariance matching of the GNSS innovations (:mod:`imunoise.nav.adaptive`; not in the default list);
``gmwm_dyn`` — the online engine with in-motion gyro noise learned while driving by shadow filters that rehearse
GNSS outages on the data seen (:mod:`imunoise.online.motion_noise`; not in the default list); ``gmwm_lik`` —
the same learner deciding by likelihood-ratio tests on the GNSS innovations (EXPERIMENTAL research code);
``gmwm_dyn_warm`` (simulator only) — ``gmwm_dyn`` starting with what it learned on an earlier drive of the
same vehicle: the drive of seed + :data:`PRIOR_SEED_OFFSET` (same IMU models and motion law, another
trajectory, other IMU and GNSS noise), GNSS-aided throughout, in the same GNSS regime (:func:`learn_prior`);
``gmwm_dyn_warm3`` — the same after three earlier drives (seed + 3, 2, 1 × :data:`PRIOR_SEED_OFFSET`, in that
order, each starting with what the drives before it learned; the last is ``gmwm_dyn_warm``'s).
``gmwm_warm`` / ``gmwm_warm3`` (simulator only) — their baselines with the same earlier data: ``gmwm`` pooling
the stops the online engine kept on the same one / three earlier drives with this drive's stops
(``OnlineNavigator(earlier_static=...)``; :func:`earlier_stops`), so the model of the earlier stops runs from the
first sample and every stop of this drive refits on the pool; ``gmwm_dyn_warm3_stops`` — ``gmwm_dyn_warm3`` with
the stops of ``gmwm_warm3`` pooled too (the learner's carried evidence as ``gmwm_dyn_warm3``'s).
Any method with the suffix ``+sf`` (e.g. ``gmwm+sf``) is the same
method in the filter with the six scale-factor states (``EkfConfig.scale_factors``, the 21-state filter of
KF-GINS), so ``--pairs gmwm+sf/gmwm`` pairs scale factors on against off window by window. The suffix ``+nhc``
(e.g. ``gmwm+nhc``) adds the non-holonomic constraints (:mod:`imunoise.nav.measurements.nhc`) to the method's
filter; :func:`with_nhc` (``--nhc``) runs every method with and without them and pairs each with its twin and
with ``plain+nhc``.

Noise seeds. The GNSS regimes with noise (:mod:`imunoise.experiments.gnss_regimes`) are run for several
noise seeds. The seeds are realisations of the aiding on the *same* IMU data, not independent drives, so
the per-window log-ratios are averaged over the seeds before the bootstrap: the seeds sharpen each
window's value, they add no windows.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from imunoise.errors import ModelError
from imunoise.experiments.dense_branches import evaluate_method, run_windows
from imunoise.experiments.dense_methods import (
    EVIDENCE_METHODS,
    LABELS,
    LEARNED_ROWS,
    NHC_SUFFIX,
    ONLINE_BASELINES,
    SF_SUFFIX,
    SIM_EXTRA,
    STATIC_WARM_METHODS,
    WARM_METHODS,
    base_method,
    hindsight_fits,
    method_setup,
    static_var_models,
    with_nhc,
)
from imunoise.experiments.dense_paired import METRICS, assemble, paired_list, parse_pairs, significance_text
from imunoise.experiments.dense_spec import BRANCH_MARGIN_S, MAX_GAP_S, DenseSpec, dense_windows, parse_outages
from imunoise.experiments.dense_warm import PRIOR_SEED_OFFSET, earlier_prior, earlier_stops, gmwm_on_drives, learn_prior
from imunoise.experiments.gnss_regimes import GnssRegime
from imunoise.experiments.runner import tick
from imunoise.experiments.window_errors import branch_errors, window_metrics
from imunoise.online import OnlineConfig

log = logging.getLogger(__name__)
_DEFAULT_SPEC = DenseSpec()

__all__ = ["DenseSpec", "parse_outages", "dense_windows", "EVIDENCE_METHODS", "SF_SUFFIX", "NHC_SUFFIX",
           "base_method", "with_nhc", "method_setup",
           "run_windows", "learn_prior", "earlier_prior", "earlier_stops", "WARM_METHODS", "STATIC_WARM_METHODS",
           "PRIOR_SEED_OFFSET",
           "run_real", "run_sim", "n_units", "paired_list", "METRICS", "branch_errors", "window_metrics",
           # the protocol's parts, importable from here as before: dense_spec (windows), dense_methods (names →
           # configurations), dense_branches (one aided run with a branch per window), dense_warm (earlier
           # drives), dense_paired (statistics)
           "SIM_EXTRA", "ONLINE_BASELINES", "LABELS", "MAX_GAP_S", "BRANCH_MARGIN_S", "static_var_models",
           "hindsight_fits", "evaluate_method", "assemble", "significance_text", "parse_pairs"]


# --------------------------------------------------------------------------------------------------
# real drive
# --------------------------------------------------------------------------------------------------
_REAL: dict[str, Any] = {}


def _real_job(job: tuple[str, int, int]) -> tuple[str, int, int, dict]:
    name, ri, seed = job
    sc = _REAL["sc"]
    regime: GnssRegime = _REAL["regimes"][ri]
    gnss = regime.apply(sc.gnss, seed)
    res = evaluate_method(sc, name, gnss, _REAL["windows"], base=_REAL["base"], cache=_REAL["cache"], nees=True,
                          in_use=_REAL["in_use"].get((ri, seed)) if name in LEARNED_ROWS else None)
    return name, ri, seed, res


def run_real(data_dir: str | Path, *, spec: DenseSpec = _DEFAULT_SPEC, regimes: Sequence[GnssRegime] = (GnssRegime(),),
             noise_seeds: Sequence[int] = (1,), methods: Sequence[str] = EVIDENCE_METHODS,
             pairs: Sequence[tuple[str, str]] = (), workers: int = 2, start: float | None = None,
             base: OnlineConfig | None = None, n_boot: int = 2000, boot_seed: int = 0,
             paper_windows: bool = True, progress: Callable[[str], None] | None = None,
             streams: Sequence[str] = (), learn_from: Sequence[str | Path] = (),
             learn_half: str | None = None) -> dict:
    """Dense-window evidence on a real drive: every method × regime × noise seed (``rtk`` once); ``streams``: the
    manifest's measurement sources every run applies (:func:`~imunoise.experiments.common.load_real`).
    ``learn_from``: the dataset folders of the same vehicle's other drives that ``in_use`` learns on
    (``--learn-from-logs``), each in the run's GNSS regime and noise seed. ``learn_half`` ("first" or "second",
    ``--learn-half``): ``in_use`` learns on that half of this drive and only the other half is scored, its windows
    and NEES epochs (:mod:`imunoise.experiments.drive_halves`).

    Returns the results dict (``paired`` list, per-window values, per-regime summaries)."""
    from imunoise.experiments.common import load_real

    logging.getLogger("imunoise").setLevel(logging.WARNING)
    sc = load_real(data_dir, start=start, streams=streams)
    dense = dense_windows(sc, spec)
    paper = list(sc.windows) if paper_windows else []
    halves = None
    if learn_half is not None:  # only the other half is scored: its windows and NEES epochs
        from imunoise.experiments import drive_halves as dh

        if learn_from:
            raise ModelError("--learn-half learns in_use on a half of the --data drive itself; drop --learn-from-logs")
        halves = {"learn": dh.check_half(learn_half), "spans_s": dh.half_spans(sc)}
        span = halves["spans_s"][dh.other_half(learn_half)]
        dense, paper = dh.windows_in(dense, span), dh.windows_in(paper, span)
        if not dense:
            raise ModelError(f"--learn-half {learn_half}: no dense window ({spec.label}) lies in the scored half "
                             f"[{span[0]:.1f}, {span[1]:.1f}) s; use shorter windows or a shorter lead")
    _REAL.update(sc=sc if halves is None else dh.scored_half(sc, learn_half), regimes=list(regimes),
                 windows=dense + paper, base=base, cache={}, in_use={})
    if set(LEARNED_ROWS) & set(methods):  # learned once per GNSS realisation, before forking
        from imunoise.experiments.in_use_method import learn_in_use

        if not (learn_from or halves):
            raise ModelError("in_use on real data learns on other drives of the same vehicle: give them with "
                             "--learn-from-logs DATASET..., or on one half of this drive with --learn-half")
        others = [load_real(p) for p in learn_from]
        for ri, rg in enumerate(regimes):
            for s in (noise_seeds if rg.random else [0]):
                if halves is None:
                    d = [(o, rg.apply(o.gnss, s)) for o in others]
                    run = gmwm_on_drives(d, base)
                    _REAL["in_use"][(ri, s)] = learn_in_use(d, run.fits, base, run.static_pieces)
                else:
                    _REAL["in_use"][(ri, s)] = dh.learn_on_half(sc, rg.apply(sc.gnss, s), learn_half, base,
                                                                _REAL["cache"])
    for m in methods:  # fixed fits once, before forking: the workers inherit them
        if base_method(m) in ("av", "em", "gmwm_hindsight", "static_var_hindsight"):
            hindsight_fits(sc, base_method(m), _REAL["cache"])
    jobs = [(m, ri, s) for ri, rg in enumerate(regimes) for s in (noise_seeds if rg.random else [0])
            for m in methods]
    jobs.sort(key=lambda j: not j[0].startswith(("gmwm", "em")))  # long jobs first
    raw: list[tuple[str, int, int, dict]] = []
    if workers > 1 and len(jobs) > 1:
        with mp.get_context("fork").Pool(workers) as pool:
            for r in pool.imap_unordered(_real_job, jobs):
                raw.append(r)
                if progress:
                    progress(r[0])
    else:
        for j in jobs:
            raw.append(_real_job(j))
            if progress:
                progress(j[0])
    drives = [{"name": sc.name, "windows": dense, "runs": raw}]
    res = assemble(drives, methods, regimes, spec, pairs, n_paper=len(paper), n_boot=n_boot, boot_seed=boot_seed)
    res["data"] = str(data_dir)
    res["noise_seeds"] = [int(s) for s in noise_seeds] if any(r.random for r in regimes) else []  # the seed label
    res["paper_windows"] = [list(w) for w in paper]
    res["learn_from_logs"] = [str(p) for p in learn_from]
    res["in_use_models"] = _in_use_models(drives, regimes)
    if halves is not None:
        res["halves"] = halves
    return res


# --------------------------------------------------------------------------------------------------
# simulator
# --------------------------------------------------------------------------------------------------
def _sim_job(args: tuple) -> dict:
    seed, methods, regimes, noise_seeds, spec, kw, base, vehicle_drives = args
    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives, vehicle_seeds
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.in_use_method import learn_in_use

    logging.getLogger("imunoise").setLevel(logging.WARNING)
    # the scored drive: the last of the vehicle's (imunoise.experiments.carry_over), the drive of the seed itself
    sc = simulate_scenario(seed, n_outages=0, **kw)
    windows = dense_windows(sc, spec)
    # the earlier drives of the same vehicle (same IMU, same motion law, another trajectory and noise) that the
    # warm methods learn from
    n_warm, n_stops = _warm_needs(methods)
    earlier = earlier_scenarios(seed, max((*n_warm.values(), *n_stops.values(), vehicle_drives - 1), default=0), **kw)
    cache: dict = {}
    runs = []
    for ri, rg in enumerate(regimes):
        for ns in (noise_seeds if rg.random else [0]):
            # the noise seed is offset by the drive seed so different drives get different GNSS noise
            gnss = rg.apply(sc.gnss, 1_000_003 * seed + ns)
            priors = {n: earlier_prior(seed, rg, ns, n_drives=n, base=base, earlier=earlier)
                      for n in sorted(set(n_warm.values()))}
            stops = {n: earlier_stops(seed, rg, ns, n_drives=n, base=base, earlier=earlier)
                     for n in sorted(set(n_stops.values()))}
            learned = None
            if set(LEARNED_ROWS) & set(methods):  # the static part: the gmwm row's fits on the earlier drives
                d = learning_drives(seed, vehicle_drives, earlier, rg, ns)
                run = gmwm_on_drives(d, base)
                learned = learn_in_use(d, run.fits, base, run.static_pieces)
            for m in methods:
                prior = priors[n_warm[m]] if m in n_warm else None
                pooled = stops[n_stops[m]] if m in n_stops else None
                runs.append((m, ri, ns, evaluate_method(sc, m, gnss, windows, base=base, cache=cache, prior=prior,
                                                        earlier_static=pooled, nees=True,
                                                        in_use=learned if m in LEARNED_ROWS else None)))
                tick()
    return {"seed": seed, "name": sc.name, "windows": windows, "runs": runs,
            "vehicle_drives": vehicle_seeds(seed, vehicle_drives)}


def _warm_needs(methods: Sequence[str]) -> tuple[dict[str, int], dict[str, int]]:
    """Earlier drives per warm method: those whose prior is learned, those whose stops are pooled."""
    n_warm = {m: WARM_METHODS[base_method(m)] for m in methods if base_method(m) in WARM_METHODS}
    n_stops = {m: STATIC_WARM_METHODS[base_method(m)][1] for m in methods if base_method(m) in STATIC_WARM_METHODS}
    return n_warm, n_stops


def _check_replay(seeds: Sequence[int], methods: Sequence[str], k: int, scen_kw: dict) -> None:
    """With a replayed recording: every earlier drive a method learns on needs its own stretch (one of the
    vehicle's K), and every vehicle must fit in the recording; refused here, before any drive is simulated."""
    from imunoise.sim.replay import check_vehicles

    n_warm, n_stops = _warm_needs(methods)
    need = {**n_warm, **n_stops}
    over = {m: n for m, n in need.items() if n > k - 1}
    if over:
        m, n = max(over.items(), key=lambda x: x[1])
        raise ModelError(f"--methods {m} learns on {n} earlier drive(s) of the vehicle; with --imu-noise each earlier "
                         f"drive replays one of the vehicle's --vehicle-drives {k} stretches: give --vehicle-drives "
                         f"{n + 1} or more, or leave {m} out")
    check_vehicles(scen_kw["imu_noise"], int(scen_kw.get("imu_noise_first", 0)), list(seeds), k,
                   float(scen_kw.get("duration_s", 600.0)), float(scen_kw.get("imu_rate_hz", 100.0)),
                   float(scen_kw.get("imu_noise_reserve_s", 0.0)))


def n_units(methods: Sequence[str], regimes: Sequence[GnssRegime], noise_seeds: Sequence[int]) -> int:
    """Runs per drive: methods × GNSS realisations (a regime with noise once per noise seed)."""
    return len(methods) * sum(len(noise_seeds) if rg.random else 1 for rg in regimes)


def run_sim(seeds: Sequence[int], *, spec: DenseSpec = _DEFAULT_SPEC, regimes: Sequence[GnssRegime] = (GnssRegime(),),
            noise_seeds: Sequence[int] = (1,), methods: Sequence[str] = (*EVIDENCE_METHODS, *SIM_EXTRA),
            pairs: Sequence[tuple[str, str]] = (), workers: int = 2, base: OnlineConfig | None = None,
            n_boot: int = 2000, boot_seed: int = 0, progress: Callable[[int], None] | None = None,
            scheduler: str | None = None, vehicle_drives: int = 1, **scen_kw: Any) -> dict:
    """Dense-window evidence over simulated drives (``seeds``; drives are the bootstrap's clusters).
    ``vehicle_drives``: drives per vehicle (:mod:`imunoise.experiments.carry_over`), scored on the last.

    One job per drive (its scenario, GNSS draws and earlier drives made once for all methods), run by
    :func:`imunoise.experiments.runner.run_jobs` in ``workers`` processes or on the Dask ``scheduler``;
    ``progress(n)`` after every ``n`` runs of one method on one realisation of a drive
    (:func:`n_units` per drive). The results do not depend on ``workers`` or ``scheduler``."""
    from imunoise.experiments.carry_over import check_vehicle_drives
    from imunoise.experiments.runner import run_jobs

    k = check_vehicle_drives(vehicle_drives)
    if set(LEARNED_ROWS) & set(methods) and k < 2:
        raise ModelError("the in_use method learns on a vehicle's earlier drives: vehicle_drives must be 2 or more")
    if scen_kw.get("imu_noise"):
        if int(scen_kw.get("imu_noise_drives", 1)) != k:
            raise ModelError(f"--imu-noise: the scenario lays out {scen_kw.get('imu_noise_drives', 1)} stretch(es) per "
                             f"vehicle but vehicle_drives is {k}: build it with imu_noise_kwargs(..., "
                             f"vehicle_drives={k})")
        _check_replay(seeds, methods, k, scen_kw)
    jobs = [(int(s), tuple(methods), tuple(regimes), tuple(noise_seeds), spec, dict(scen_kw), base, k) for s in seeds]
    drives = run_jobs(_sim_job, jobs, workers=workers, scheduler=scheduler,
                      units=n_units(methods, regimes, noise_seeds), progress=progress)
    drives.sort(key=lambda d: d["seed"])
    res = assemble(drives, methods, regimes, spec, pairs, n_paper=0, n_boot=n_boot, boot_seed=boot_seed)
    res["data"] = "sim"
    res["seeds"] = [d["seed"] for d in drives]
    res["noise_seeds"] = [int(s) for s in noise_seeds] if any(r.random for r in regimes) else []
    res["scenario"] = dict(scen_kw)
    res["vehicle_drives"] = k
    res["vehicles"] = {str(d["seed"]): d["vehicle_drives"] for d in drives}
    res["in_use_models"] = _in_use_models(drives, regimes)
    return res


def _in_use_models(drives: Sequence[dict], regimes: Sequence[GnssRegime]) -> dict:
    """What ``in_use`` learned per drive and GNSS realisation (the in-motion part, the estimate's CPU time)."""
    return {f"{d.get('seed', d.get('name'))}/{regimes[r[1]].label}/{r[2]}": r[3]["in_use"]
            for d in drives for r in d["runs"] if r[0] in LEARNED_ROWS and "in_use" in r[3]}
