"""Dense outage protocol with paired statistics (issue "Evidence with power" §1; SPEC §11).

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
continues with the window's IMU and no GNSS inside the window, to L + 1 s, in one chunk. The copy *is* a full
run with that window's GNSS removed, up to the window end: tests/test_experiments_dense.py checks it to 1e-9 m. Per
window: the end drift (horizontal error at the last reference epoch inside the window, as
:func:`imunoise.nav.metrics.outage_drift`), the horizontal RMS inside the window, and the aided run's
horizontal RMS over the same span (``aided_rms``: the GNSS-available metric of the paper's Table 5, per
window, so it can be paired too).

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
GNSS outages on the data seen (:mod:`imunoise.online.motion_noise`; not in the default list);
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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, ModelError
from imunoise.experiments.common import Scenario, baseline_fits, filter_models, static_segments
from imunoise.experiments.gnss_regimes import GnssRegime
from imunoise.experiments.runner import tick
from imunoise.experiments.stats import default_block, n_independent, paired_entry
from imunoise.experiments.window_errors import branch_errors, window_metrics
from imunoise.nav.metrics import nav_errors
from imunoise.online import MotionNoisePrior, OnlineConfig, OnlineNavigator

log = logging.getLogger(__name__)

__all__ = ["DenseSpec", "parse_outages", "dense_windows", "EVIDENCE_METHODS", "SF_SUFFIX", "NHC_SUFFIX",
           "base_method", "with_nhc", "method_setup",
           "run_windows", "learn_prior", "earlier_prior", "earlier_stops", "WARM_METHODS", "STATIC_WARM_METHODS",
           "PRIOR_SEED_OFFSET",
           "run_real", "run_sim", "n_units", "paired_list", "METRICS", "branch_errors", "window_metrics"]

EVIDENCE_METHODS = ("plain", "static_var", "av", "em", "av_online", "em_online", "gmwm", "gmwm_hindsight")
SIM_EXTRA = ("oracle_law", "oracle")
ONLINE_BASELINES = {"static_var": "static_var", "av_online": "av", "em_online": "em"}
SF_SUFFIX = "+sf"  # a method with the scale-factor states in the filter
NHC_SUFFIX = "+nhc"  # a method with the non-holonomic constraints in the filter
METRICS = ("drift", "rms", "aided_rms")
MAX_GAP_S = 2.0
BRANCH_MARGIN_S = 1.0
LABELS = {
    "static_var": "static variance as white noise (stops so far)",
    "static_var_hindsight": "static variance as white noise (all static data)",
    "av_online": "AV-based (stops so far)",
    "em_online": "EM-based (stops so far)",
    "gmwm_hindsight": "GMWM, GOF (all static data)",
    "adaptive": "plain + innovation-based adaptive bias noise (covariance matching)",
    "gmwm_dyn": "GMWM + in-motion gyro noise learned by rehearsed outages",
    "gmwm_dyn_warm": "gmwm_dyn carrying what it learned on an earlier drive of the same vehicle",
    "gmwm_dyn_warm3": "gmwm_dyn carrying what it learned on three earlier drives of the same vehicle",
    "gmwm_warm": "GMWM pooling the stops of an earlier drive of the same vehicle",
    "gmwm_warm3": "GMWM pooling the stops of three earlier drives of the same vehicle",
    "gmwm_dyn_warm3_stops": "gmwm_dyn_warm3 also pooling the stops of its three earlier drives",
}
# method → earlier drives whose learner evidence it carries
WARM_METHODS: dict[str, int] = {"gmwm_dyn_warm": 1, "gmwm_dyn_warm3": 3, "gmwm_dyn_warm3_stops": 3}
# method → (the method it is, earlier drives whose stops it pools)
STATIC_WARM_METHODS: dict[str, tuple[str, int]] = {"gmwm_warm": ("gmwm", 1), "gmwm_warm3": ("gmwm", 3),
                                                   "gmwm_dyn_warm3_stops": ("gmwm_dyn_warm3", 3)}
PRIOR_SEED_OFFSET = 7_000_000  # the k-th drive before drive seed on the simulator: seed + k · this


def base_method(name: str) -> str:
    """The method without its filter suffixes (``gmwm+sf+nhc`` → ``gmwm``)."""
    while name.endswith((SF_SUFFIX, NHC_SUFFIX)):
        name = name.removesuffix(SF_SUFFIX).removesuffix(NHC_SUFFIX)
    return name


def with_nhc(methods: Sequence[str]) -> tuple[tuple[str, ...], list[tuple[str, str]]]:
    """Every method and its ``+nhc`` twin, with the pairs twin/method and twin/``plain+nhc``,
    twin/``static_var+nhc`` where run (the ranking of the noise methods with the constraints on, as
    :func:`paired_list` ranks them without)."""
    twins = tuple(m + NHC_SUFFIX for m in methods if not m.endswith(NHC_SUFFIX))
    all_ = tuple(dict.fromkeys((*methods, *twins)))
    pairs = [(t, t.removesuffix(NHC_SUFFIX)) for t in twins]
    for b in ("plain" + NHC_SUFFIX, "static_var" + NHC_SUFFIX):
        if b in all_:
            pairs += [(t, b) for t in twins if t != b and (t, b) != ("plain+nhc", "static_var+nhc")]
    return all_, pairs


@dataclass(frozen=True)
class DenseSpec:
    """Dense windows: ``length_s`` long, opened every ``step_s`` after ``lead_s`` of aided driving."""

    length_s: float = 60.0
    step_s: float = 20.0
    lead_s: float = 60.0

    @property
    def label(self) -> str:
        return f"dense:{self.length_s:g}:{self.step_s:g}:{self.lead_s:g}"


def parse_outages(text: str | int | None) -> tuple[str, Any]:
    """``--outages``: ``"dense:L:S[:LEAD]"`` → ("dense", DenseSpec); an integer → ("count", n) (simulator:
    windows per drive); anything else → ("file", Path) (an outage file, SPEC §8)."""
    if text is None:
        return "none", None
    if isinstance(text, int):
        return "count", text
    s = str(text).strip()
    if s.lower().startswith("dense"):
        parts = s.split(":")[1:]
        try:
            vals = [float(p) for p in parts if p.strip()]
        except ValueError as exc:
            raise ModelError(f"--outages {text!r}: dense:L:S[:LEAD] takes numbers (s)") from exc
        if len(vals) > 3:
            raise ModelError(f"--outages {text!r}: dense:L:S[:LEAD], at most three numbers (s)")
        spec = DenseSpec(*vals)
        if not (spec.length_s > 0 and spec.step_s > 0 and spec.lead_s >= 0):
            raise ModelError(f"--outages {text!r}: L and S must be > 0 s and LEAD ≥ 0 s")
        return "dense", spec
    try:
        return "count", int(s)
    except ValueError:
        pass
    p = Path(s)
    if not p.exists():
        raise ModelError(f"--outages {text!r}: not dense:L:S[:LEAD], a number of windows or an existing "
                            "outage file")
    return "file", p


def dense_windows(sc: Scenario, spec: DenseSpec) -> list[tuple[float, float]]:
    """Window (start, L) every ``step_s`` from ``init.t + lead_s`` while the window ends before the IMU
    and the reference do, kept where the recorded fixes cover the preceding ``lead_s`` with no gap over
    :data:`MAX_GAP_S`."""
    gt = np.asarray(sc.gnss.t, dtype=float)
    gt = gt[gt > sc.init.t]
    t_end = min(float(sc.imu.t[-1]), float(sc.ref.t[-1])) - BRANCH_MARGIN_S
    out = []
    s = sc.init.t + spec.lead_s
    while s + spec.length_s <= t_end + 1e-9:
        a = s - spec.lead_s
        inside = gt[(gt >= a) & (gt < s)]
        if inside.size:
            edges = np.concatenate([[a], inside, [s]])
            if float(np.max(np.diff(edges))) <= MAX_GAP_S:
                out.append((float(s), float(spec.length_s)))
        s += spec.step_s
    if not out:
        raise DataError(f"no dense window fits ({spec.label}): the drive is shorter than lead + L or GNSS has gaps")
    return out


# --------------------------------------------------------------------------------------------------
# methods
# --------------------------------------------------------------------------------------------------
class _StopRefit:
    """AV/EM/static-variance models refitted on the stops detected so far and swapped into the filter at
    each stop's completion (the online data protocol of the baselines)."""

    def __init__(self, which: str, rates: np.ndarray, freq: float, base: OnlineConfig, cache: dict):
        self.which = which
        self.rates = rates
        self.freq = freq
        self.base = base
        self.cache = cache
        self.n_seen = 0

    def models(self, segs) -> list:
        key = (self.which, tuple((s.i0, s.i1) for s in segs))
        if key not in self.cache:
            data = [self.rates[s.i0:s.i1] for s in segs if s.i1 - s.i0 >= 16]
            data = [d - d.mean(axis=0) for d in data]  # bias removal, as the online engine
            if self.which == "static_var":
                self.cache[key] = filter_models(static_var_models(data), self.freq, self.base)
            else:
                self.cache[key] = filter_models(baseline_fits(data, self.freq, self.which), self.freq, self.base)
        return self.cache[key]

    def shared(self) -> tuple:
        """Large read-only objects a fork shares instead of copying."""
        return (self.rates, self.cache, self.base)

    def step(self, nav: OnlineNavigator) -> None:
        segs = nav.segments
        if len(segs) == self.n_seen:
            return
        self.n_seen = len(segs)
        if sum(s.duration for s in segs) < self.base.min_static_s:
            return
        models = self.models(segs)
        nav.ekf.swap_model(models, preserve=self.base.swap == "preserve", imu_rate_hz=nav.rate)
        nav.current_models = models


class _Adaptive:
    """The plain filter with its bias process noise adapted online from the GNSS innovations
    (:class:`imunoise.nav.adaptive.AdaptiveNoise`; the ``adaptive`` method)."""

    def __init__(self, config=None):
        self.config = config
        self.core = None

    def shared(self) -> tuple:
        return ()

    def step(self, nav: OnlineNavigator) -> None:
        if self.core is None:
            from imunoise.nav.adaptive import AdaptiveNoise

            self.core = AdaptiveNoise(nav.current_models, self.config)
        if self.core.observe(nav.ekf):
            nav.current_models = self.core.models()


def static_var_models(segments: Sequence[np.ndarray]) -> list:
    """Per axis ``WN(σ²)`` with σ² the variance of the pooled bias-removed static samples (the model-free
    baseline; the filter mapping adds the plain floor)."""
    from imunoise.model import Model
    from imunoise.processes import WN

    x = np.concatenate([np.asarray(s) - np.asarray(s).mean(axis=0) for s in segments])
    return [Model([WN(sigma2=float(max(np.var(x[:, a]), 1e-30)))]) for a in range(6)]


def hindsight_fits(sc: Scenario, name: str, cache: dict) -> list:
    """Fixed fits on all static data of the record (``av``/``em``/``gmwm_hindsight``/``static_var_hindsight``),
    cached in ``cache``."""
    if name in cache:
        return cache[name]
    if "segments" not in cache:
        cache["segments"], _ = static_segments(sc)
    segs = cache["segments"]
    if name in ("av", "em"):
        cache[name] = baseline_fits(segs, sc.rate, name)
    elif name == "static_var_hindsight":
        cache[name] = static_var_models(segs)
    elif name == "gmwm_hindsight":
        from imunoise.online import COMPLETE
        from imunoise.selection import select_model

        cache[name] = [select_model([s[:, a] for s in segs], freq=sc.rate, complete=COMPLETE, criterion="gof",
                                    top=1, unit="rad/s" if a < 3 else "m/s²").best for a in range(6)]
    else:
        raise ModelError(f"no hindsight fit for {name!r}")
    return cache[name]


def method_setup(name: str, sc: Scenario, base: OnlineConfig | None = None, cache: dict | None = None, *,
                 prior: MotionNoisePrior | None = None) -> tuple[OnlineConfig, Any, _StopRefit | _Adaptive | None]:
    """(OnlineConfig, initial models, stop-refit updater or None) of a method (module docstring); ``prior``:
    the evidence an earlier drive gives ``gmwm_dyn_warm`` (:func:`learn_prior`)."""
    from imunoise.experiments.online_exp import method_config

    cache = cache if cache is not None else {}
    if name.endswith(NHC_SUFFIX):
        from imunoise.nav.measurements.nhc import NhcConfig

        cfg, models, upd = method_setup(name[: -len(NHC_SUFFIX)], sc, base, cache, prior=prior)
        return cfg.with_(ekf=cfg.ekf.with_(aiding=(*cfg.ekf.aiding, NhcConfig()))), models, upd
    if name.endswith(SF_SUFFIX):
        # the noise model is the method's own; only the filter's state vector gains the scale factors
        cfg, models, upd = method_setup(name[: -len(SF_SUFFIX)], sc, base, cache, prior=prior)
        return cfg.with_(ekf=cfg.ekf.with_(scale_factors=True)), models, upd
    if name in STATIC_WARM_METHODS:  # the earlier stops go to the navigator (run_windows)
        return method_setup(STATIC_WARM_METHODS[name][0], sc, base, cache, prior=prior)
    if name in WARM_METHODS:
        if prior is None:
            raise ModelError(f"{name} needs what the learner learned on an earlier drive of the same vehicle: the "
                             "simulator makes one (run_sim); for a real vehicle use `imunoise online "
                             "--motion-noise-prior METRICS.json` of an earlier drive")
        cfg, models, upd = method_setup("gmwm_dyn", sc, base, cache)
        return cfg.with_(motion_noise=replace(cfg.motion_noise, prior=prior)), models, upd
    plain_cfg, _ = method_config("plain", sc, base)
    if name in ONLINE_BASELINES:
        gyro, accel = sc.imu.rates()
        if "rates" not in cache:
            cache["rates"] = np.column_stack([gyro, accel])
        upd = _StopRefit(ONLINE_BASELINES[name], cache["rates"], sc.rate, plain_cfg, cache.setdefault("stop_fits", {}))
        return plain_cfg, None, upd
    if name == "adaptive":
        return plain_cfg, None, _Adaptive()
    if name in ("av", "em", "gmwm_hindsight", "static_var_hindsight"):
        return plain_cfg, filter_models(hindsight_fits(sc, name, cache), sc.rate, plain_cfg), None
    cfg, models = method_config(name, sc, base, fits_cache=cache)
    return cfg, models, None


# --------------------------------------------------------------------------------------------------
# one aided run with a branch per window
# --------------------------------------------------------------------------------------------------
def _fork(nav: OnlineNavigator, upd: _StopRefit | _Adaptive | None, shared: Sequence[Any]):
    # the branch keeps only its own epochs: the result converts every stored epoch to Euler angles; the aided
    # run's store is shared rather than copied, since the fork replaces it with an empty one. The finished
    # modelling jobs (ModelUpdate, never changed once made; their fits and rankings are most of what a fork
    # would copy) are shared too: the branch gets its own list of them.
    store = getattr(nav, "_store", None)
    done = tuple(nav.updates)
    nav2, upd2 = nav.fork(upd, share=(*shared, *((store,) if store is not None else ()), *done))
    return nav2, upd2


def _aided_chunks(nav: OnlineNavigator, sc: Scenario, windows, order_w, data, shared, out: list) -> None:
    """The aided run and its branches in kernel spans (:meth:`OnlineNavigator.push_chunk`): the aided run is
    pushed from one window start to the next and each branch in one chunk, with the fixes :func:`_aided_samples`
    pushes in the same places (push_chunk equals push_imu/push_gnss in time order to the bit)."""
    t, dth, dv, gt, gllh, gsig = data
    n = t.size
    if nav.detector is None and n:
        # λ_0 from the first learn_lambda0_s of the record at once, as OnlineNavigator.run does (push_imu holds
        # those samples, learns from the same accelerations at the first later sample, then replays them one by
        # one): the detector exists before the first chunk, so no sample takes the per-sample path for it
        dt = np.diff(t, prepend=t[0] - nav.dt_nom)
        nav._learn_from((dv / dt[:, None])[t < t[0] + nav.config.learn_lambda0_s], t[0])
    i0 = k = 0
    for j in order_w:
        s, length = windows[j]
        i = int(np.searchsorted(t, s, side="left"))  # the first sample with t ≥ s: the branch starts there
        if i >= n:
            break
        ks = max(int(np.searchsorted(gt, s, side="left")), k)  # the fixes before the window start
        nav.push_chunk(t[i0:i], dth[i0:i], dv[i0:i], gt[k:ks], gllh[k:ks], gsig[k:ks])
        i0, k = i, ks
        br, _ = _fork(nav, None, shared)
        ie = max(int(np.searchsorted(t, s + length + BRANCH_MARGIN_S, side="left")), i)
        # inside the window no fix; after its end those up to the branch's last sample
        kb = int(np.searchsorted(gt, s + length, side="left"))
        ke = max(int(np.searchsorted(gt, t[ie - 1], side="right")), kb) if ie > i else kb
        br.push_chunk(t[i:ie], dth[i:ie], dv[i:ie], gt[kb:ke], gllh[kb:ke], gsig[kb:ke])
        out[j] = window_metrics(branch_errors(br.finish(), sc, s), s, length)
    ke = max(int(np.searchsorted(gt, t[-1], side="right")), k)  # fixes after the last sample are never pushed
    nav.push_chunk(t[i0:], dth[i0:], dv[i0:], gt[k:ke], gllh[k:ke], gsig[k:ke])


def _aided_samples(nav: OnlineNavigator, updater: _StopRefit | _Adaptive, sc: Scenario, windows, order_w, data,
                   shared, out: list) -> None:
    """The aided run and its branches sample by sample, the ``updater`` after every sample (its policy acts
    between samples)."""
    t, dth, dv, gt, gllh, gsig = data
    n, ng = t.size, gt.size
    k = 0
    wi = 0
    for i in range(n):
        ti = t[i]
        while wi < len(order_w) and windows[order_w[wi]][0] <= ti:
            j = order_w[wi]
            s, length = windows[j]
            while k < ng and gt[k] < s:
                nav.push_gnss(gt[k], gllh[k], gsig[k])
                k += 1
            br, bu = _fork(nav, updater, shared)
            kb = int(np.searchsorted(gt, s + length, side="left"))
            ib = i
            while ib < n and t[ib] < s + length + BRANCH_MARGIN_S:
                while kb < ng and gt[kb] <= t[ib]:
                    br.push_gnss(gt[kb], gllh[kb], gsig[kb])
                    kb += 1
                br.push_imu(t[ib], dth[ib], dv[ib])
                bu.step(br)
                ib += 1
            out[j] = window_metrics(branch_errors(br.finish(), sc, s), s, length)
            wi += 1
        while k < ng and gt[k] <= ti:
            nav.push_gnss(gt[k], gllh[k], gsig[k])
            k += 1
        nav.push_imu(ti, dth[i], dv[i])
        updater.step(nav)


def run_windows(sc: Scenario, config: OnlineConfig, gnss, windows: Sequence[tuple[float, float]], *,
                initial_models=None, updater: _StopRefit | _Adaptive | None = None, keep: bool = False,
                earlier_static: Sequence[np.ndarray] | None = None) -> dict:
    """One aided run (``gnss`` everywhere) with a GNSS-free branch per window (module docstring);
    ``earlier_static``: the navigator's (static pieces of earlier drives of the same IMU).

    Returns ``windows`` (per window ``drift``, ``rms``, ``drift_v``, ``aided_rms``) and the aided run's
    ``horizontal_rms_m``/``vertical_rms_m``; ``_full`` (the aided OnlineResult) when ``keep``."""
    t = np.asarray(sc.imu.t, dtype=float)
    dth, dv = sc.imu.increments()
    gt = np.asarray(gnss.t, dtype=float)
    order = np.argsort(gt, kind="stable")
    gt, gllh, gsig = gt[order], np.asarray(gnss.llh)[order], np.asarray(gnss.sigma_ned)[order]
    cache = sc.extra.setdefault("job_cache", {})
    nav = OnlineNavigator(config, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models, job_cache=cache,
                          earlier_static=earlier_static)
    shared = [cache, sc, t, dth, dv, gt, gllh, gsig, sc.imu, sc.ref, config]
    if updater is not None:
        shared += list(updater.shared())
    order_w = sorted(range(len(windows)), key=lambda j: windows[j][0])
    out: list[dict | None] = [None] * len(windows)
    data = (t, dth, dv, gt, gllh, gsig)
    if updater is None:
        _aided_chunks(nav, sc, windows, order_w, data, shared, out)
    else:
        _aided_samples(nav, updater, sc, windows, order_w, data, shared, out)
    full = nav.finish()
    err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
    for j, (s, length) in enumerate(windows):
        m = (err.t >= s) & (err.t < s + length)
        h = err.horizontal[m]
        if out[j] is None:
            out[j] = {"drift": None, "rms": None, "drift_v": None}
        out[j]["aided_rms"] = float(np.sqrt(np.mean(h * h))) if h.size else None
    res: dict[str, Any] = {"windows": out,
                           "horizontal_rms_m": float(np.sqrt(np.mean(err.horizontal ** 2))),
                           "vertical_rms_m": float(np.sqrt(np.mean(err.vertical ** 2)))}
    if keep:
        res["_full"] = full
    return res


def evaluate_method(sc: Scenario, name: str, gnss, windows, *, base: OnlineConfig | None = None,
                    cache: dict | None = None, prior: MotionNoisePrior | None = None,
                    earlier_static: Sequence[np.ndarray] | None = None) -> dict:
    """:func:`run_windows` for one method (:func:`method_setup`); ``earlier_static`` the earlier drives' stops
    a ``gmwm_warm`` method pools (:func:`earlier_stops`)."""
    if (base_method(name) in STATIC_WARM_METHODS) != (earlier_static is not None):
        raise ModelError(f"{name}: earlier drives' stops are for {', '.join(STATIC_WARM_METHODS)} only, and those "
                         "need them (the simulator makes them: run_sim)")
    if name == "oracle_law":  # the batch filter told the law's schedule (imunoise.experiments.oracle_law)
        from imunoise.experiments.oracle_law import run_windows_law

        return run_windows_law(sc, gnss, windows, base=base)
    cfg, models, upd = method_setup(name, sc, base, cache, prior=prior)
    return run_windows(sc, cfg, gnss, windows, initial_models=models, updater=upd, earlier_static=earlier_static)


def learn_prior(sc: Scenario, gnss, base: OnlineConfig | None = None,
                prior: MotionNoisePrior | None = None) -> MotionNoisePrior:
    """What ``gmwm_dyn`` learns on the whole GNSS-aided drive ``sc`` (no outage), starting from ``prior`` (what
    the drives before it learned) if given: the prior of the next drive of the same vehicle
    (:class:`~imunoise.online.motion_noise.MotionNoisePrior`; its rounds are the carried ones and this drive's)."""
    cfg, models, upd = method_setup("gmwm_dyn" if prior is None else "gmwm_dyn_warm", sc, base, {}, prior=prior)
    full = run_windows(sc, cfg, gnss, [], initial_models=models, updater=upd, keep=True)["_full"]
    end = [e for e in full.events if e["event"] == "motion_noise_end"]
    return MotionNoisePrior.from_dict(end[-1]["evidence"])


# --------------------------------------------------------------------------------------------------
# real drive
# --------------------------------------------------------------------------------------------------
_REAL: dict[str, Any] = {}


def _real_job(job: tuple[str, int, int]) -> tuple[str, int, int, dict]:
    name, ri, seed = job
    sc = _REAL["sc"]
    regime: GnssRegime = _REAL["regimes"][ri]
    gnss = regime.apply(sc.gnss, seed)
    res = evaluate_method(sc, name, gnss, _REAL["windows"], base=_REAL["base"], cache=_REAL["cache"])
    return name, ri, seed, res


def run_real(data_dir: str | Path, *, spec: DenseSpec = DenseSpec(), regimes: Sequence[GnssRegime] = (GnssRegime(),),
             noise_seeds: Sequence[int] = (1,), methods: Sequence[str] = EVIDENCE_METHODS,
             pairs: Sequence[tuple[str, str]] = (), workers: int = 2, start: float | None = None,
             base: OnlineConfig | None = None, n_boot: int = 2000, boot_seed: int = 0,
             paper_windows: bool = True, progress: Callable[[str], None] | None = None) -> dict:
    """Dense-window evidence on a real drive: every method × regime × noise seed (``rtk`` once).

    Returns the results dict (``paired`` list, per-window values, per-regime summaries)."""
    from imunoise.experiments.common import load_real

    logging.getLogger("imunoise").setLevel(logging.WARNING)
    sc = load_real(data_dir, start=start)
    dense = dense_windows(sc, spec)
    paper = list(sc.windows) if paper_windows else []
    _REAL.update(sc=sc, regimes=list(regimes), windows=dense + paper, base=base, cache={})
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
    res["paper_windows"] = [list(w) for w in paper]
    return res


# --------------------------------------------------------------------------------------------------
# simulator
# --------------------------------------------------------------------------------------------------
def _earlier_drives(seed: int, n_drives: int, earlier: Sequence[Scenario] | None, scen_kw: dict):
    """(seed, scenario) of the ``n_drives`` earlier drives of simulated drive ``seed``, oldest first: seed + k ·
    :data:`PRIOR_SEED_OFFSET`, k = ``n_drives`` … 1; ``earlier[k - 1]`` is drive k if given, else simulated."""
    from imunoise.experiments.common import simulate_scenario

    if n_drives < 1:
        raise ModelError(f"a warm method needs at least one earlier drive, not {n_drives}")
    for k in range(n_drives, 0, -1):
        s = int(seed) + k * PRIOR_SEED_OFFSET
        yield s, (earlier[k - 1] if earlier is not None and len(earlier) >= k
                  else simulate_scenario(s, n_outages=0, **scen_kw))


def earlier_prior(seed: int, regime: GnssRegime, noise_seed: int, *, n_drives: int = 1,
                  base: OnlineConfig | None = None, earlier: Sequence[Scenario] | None = None,
                  **scen_kw: Any) -> MotionNoisePrior:
    """The prior of a warm method on simulated drive ``seed`` after ``n_drives`` earlier drives of the same
    vehicle: :func:`learn_prior` on the drives of seed + k · :data:`PRIOR_SEED_OFFSET`, k = ``n_drives`` … 1 in
    that order, each starting with what the ones before it learned. ``earlier[k - 1]`` is drive k if given (else
    it is simulated with ``scen_kw``); each in GNSS ``regime``, its noise seeded like a drive's own
    (``1_000_003 · drive seed + noise_seed``)."""
    prior = None
    for s, sc in _earlier_drives(seed, n_drives, earlier, scen_kw):
        prior = learn_prior(sc, regime.apply(sc.gnss, 1_000_003 * s + noise_seed), base, prior)
    assert prior is not None
    return prior


def earlier_stops(seed: int, regime: GnssRegime, noise_seed: int, *, n_drives: int = 1,
                  base: OnlineConfig | None = None, earlier: Sequence[Scenario] | None = None,
                  **scen_kw: Any) -> list[np.ndarray]:
    """The static pieces ``gmwm`` pooled on ``n_drives`` earlier drives of the same vehicle (the drives of
    :func:`earlier_prior`, in the same order and GNSS), each run online GNSS-aided starting with the pieces
    of the drives before it (:attr:`OnlineResult.static_pieces`): the ``earlier_static`` of drive ``seed``."""
    pieces: list[np.ndarray] | None = None
    for s, sc in _earlier_drives(seed, n_drives, earlier, scen_kw):
        cfg, models, upd = method_setup("gmwm", sc, base, {})
        full = run_windows(sc, cfg, regime.apply(sc.gnss, 1_000_003 * s + noise_seed), [], initial_models=models,
                           updater=upd, keep=True, earlier_static=pieces)["_full"]
        pieces = full.static_pieces
    assert pieces is not None
    return pieces


def _sim_job(args: tuple) -> dict:
    seed, methods, regimes, noise_seeds, spec, kw, base = args
    from imunoise.experiments.common import simulate_scenario

    logging.getLogger("imunoise").setLevel(logging.WARNING)
    sc = simulate_scenario(seed, n_outages=0, **kw)
    windows = dense_windows(sc, spec)
    # the earlier drive of the same vehicle (same IMU, same motion law, another trajectory and noise) that the
    # warm methods learn from
    n_warm = {m: WARM_METHODS[base_method(m)] for m in methods if base_method(m) in WARM_METHODS}
    n_stops = {m: STATIC_WARM_METHODS[base_method(m)][1] for m in methods if base_method(m) in STATIC_WARM_METHODS}
    earlier = [simulate_scenario(seed + k * PRIOR_SEED_OFFSET, n_outages=0, **kw)
               for k in range(1, max((*n_warm.values(), *n_stops.values()), default=0) + 1)]
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
            for m in methods:
                prior = priors[n_warm[m]] if m in n_warm else None
                pooled = stops[n_stops[m]] if m in n_stops else None
                runs.append((m, ri, ns, evaluate_method(sc, m, gnss, windows, base=base, cache=cache, prior=prior,
                                                        earlier_static=pooled)))
                tick()
    return {"seed": seed, "name": sc.name, "windows": windows, "runs": runs}


def n_units(methods: Sequence[str], regimes: Sequence[GnssRegime], noise_seeds: Sequence[int]) -> int:
    """Runs per drive: methods × GNSS realisations (a regime with noise once per noise seed)."""
    return len(methods) * sum(len(noise_seeds) if rg.random else 1 for rg in regimes)


def run_sim(seeds: Sequence[int], *, spec: DenseSpec = DenseSpec(), regimes: Sequence[GnssRegime] = (GnssRegime(),),
            noise_seeds: Sequence[int] = (1,), methods: Sequence[str] = (*EVIDENCE_METHODS, *SIM_EXTRA),
            pairs: Sequence[tuple[str, str]] = (), workers: int = 2, base: OnlineConfig | None = None,
            n_boot: int = 2000, boot_seed: int = 0, progress: Callable[[int], None] | None = None,
            scheduler: str | None = None, **scen_kw: Any) -> dict:
    """Dense-window evidence over simulated drives (``seeds``; drives are the bootstrap's clusters).

    One job per drive (its scenario, GNSS draws and earlier drives made once for all methods), run by
    :func:`imunoise.experiments.runner.run_jobs` in ``workers`` processes or on the Dask ``scheduler``;
    ``progress(n)`` after every ``n`` runs of one method on one realisation of a drive
    (:func:`n_units` per drive). The results do not depend on ``workers`` or ``scheduler``."""
    from imunoise.experiments.runner import run_jobs

    jobs = [(int(s), tuple(methods), tuple(regimes), tuple(noise_seeds), spec, dict(scen_kw), base) for s in seeds]
    drives = run_jobs(_sim_job, jobs, workers=workers, scheduler=scheduler,
                      units=n_units(methods, regimes, noise_seeds), progress=progress)
    drives.sort(key=lambda d: d["seed"])
    res = assemble(drives, methods, regimes, spec, pairs, n_paper=0, n_boot=n_boot, boot_seed=boot_seed)
    res["data"] = "sim"
    res["seeds"] = [d["seed"] for d in drives]
    res["scenario"] = dict(scen_kw)
    return res


# --------------------------------------------------------------------------------------------------
# assembly and statistics
# --------------------------------------------------------------------------------------------------
def assemble(drives: list[dict], methods: Sequence[str], regimes: Sequence[GnssRegime], spec: DenseSpec,
             pairs: Sequence[tuple[str, str]], *, n_paper: int = 0, n_boot: int = 2000, boot_seed: int = 0) -> dict:
    """Per-window values (drives × realisations × windows), per-regime summaries and the ``paired`` list."""
    block = default_block(spec.length_s, spec.step_s)
    n_ind = sum(n_independent([w[0] for w in d["windows"]], spec.length_s) for d in drives)
    per: dict[str, dict] = {}
    summary: dict[str, dict] = {}
    for ri, rg in enumerate(regimes):
        vals = {met: {m: [] for m in methods} for met in METRICS}
        paper: dict[str, list] = {m: [] for m in methods}
        scal: dict[str, dict[str, list]] = {m: {"horizontal_rms_m": [], "vertical_rms_m": []} for m in methods}
        for d in drives:
            nd = len(d["windows"])
            runs = sorted([r for r in d["runs"] if r[1] == ri], key=lambda r: r[2])
            for m in methods:
                rr = [r[3] for r in runs if r[0] == m]
                for met in METRICS:
                    vals[met][m].append([[w[met] for w in r["windows"][:nd]] for r in rr])
                paper[m].extend([[w["drift"] for w in r["windows"][nd:nd + n_paper]] for r in rr])
                for key in scal[m]:
                    scal[m][key].extend(r[key] for r in rr)
        s: dict[str, Any] = {}
        for m in methods:
            def _mean(x):
                a = np.array([np.nan if v is None else v for v in np.ravel(np.array(x, dtype=object))], dtype=float)
                return float(np.nanmean(a)) if np.any(np.isfinite(a)) else None

            s[m] = {"horizontal_rms_m": _mean(scal[m]["horizontal_rms_m"]),
                    "vertical_rms_m": _mean(scal[m]["vertical_rms_m"]),
                    "mean_end_drift_m": _mean([v for dd in vals["drift"][m] for v in dd]),
                    "mean_window_rms_m": _mean([v for dd in vals["rms"][m] for v in dd]),
                    "mean_aided_rms_m": _mean([v for dd in vals["aided_rms"][m] for v in dd])}
            if n_paper:
                arr = np.array([[np.nan if v is None else v for v in row] for row in paper[m]], dtype=float)
                s[m]["paper_windows_drift_m"] = np.nanmean(arr, axis=0).tolist()
                s[m]["paper_mean_drift_m"] = float(np.nanmean(arr))
        per[rg.label] = vals
        summary[rg.label] = s
    paired = paired_list(per, methods, pairs, block=block, n_indep=n_ind, n_boot=n_boot, boot_seed=boot_seed)
    return {"experiment": "online", "protocol": {"outages": spec.label, "length_s": spec.length_s,
                                                  "step_s": spec.step_s, "lead_s": spec.lead_s, "block": block,
                                                  "n_boot": n_boot, "boot_seed": boot_seed},
            "methods": list(methods), "gnss": [rg.label for rg in regimes],
            "windows": {d["name"]: [list(w) for w in d["windows"]] for d in drives},
            "n_windows": sum(len(d["windows"]) for d in drives), "n_independent": n_ind, "n_drives": len(drives),
            "summary": summary, "per_window": per, "paired": paired}


def paired_list(per: dict, methods: Sequence[str], pairs: Sequence[tuple[str, str]], *, block: int, n_indep: int,
                n_boot: int = 2000, boot_seed: int = 0) -> list[dict]:
    """Every method against ``plain`` and ``static_var`` (when run; plain/static_var only as static_var/plain)
    and every pair of ``pairs``, for each GNSS regime and metric (``drift``, ``rms``, ``aided_rms``)."""
    want: list[tuple[str, str]] = []
    for b in ("plain", "static_var"):
        if b in methods:
            # plain vs static_var is the inverse of static_var vs plain: listed once
            want += [(m, b) for m in methods if m != b and (m, b) != ("plain", "static_var")]
    for a, b in pairs:
        if a not in methods or b not in methods:
            raise ModelError(f"--pairs {a}/{b}: both methods must be among the methods run ({', '.join(methods)})")
        if (a, b) not in want:
            want.append((a, b))
    out = []
    for label, vals in per.items():
        for met in METRICS:
            for a, b in want:
                e = paired_entry(a, b, met, vals[met], block, n_independent_total=n_indep, n_boot=n_boot,
                                 seed=boot_seed)
                e["gnss"] = label
                out.append(e)
    return out


def significance_text(e: dict) -> str:
    """"significant" when the CI excludes 1, else "not significant"."""
    return "significant" if e.get("significant") else "not significant"


def parse_pairs(text: str | None) -> list[tuple[str, str]]:
    """``"a/b,c/d"`` → [(a, b), (c, d)]."""
    if not text:
        return []
    out = []
    for p in text.split(","):
        p = p.strip()
        if not p:
            continue
        if p.count("/") != 1:
            raise ModelError(f"--pairs: {p!r} is not method/baseline (e.g. gmwm/av)")
        a, b = (x.strip() for x in p.split("/"))
        out.append((a, b))
    return out
