"""The methods of the dense-window evidence (the vocabulary of :mod:`imunoise.experiments.dense`'s docstring):
their names and suffixes (``+sf``, ``+nhc``), the warm methods' earlier drives, and :func:`method_setup`, which
turns a name into the online configuration, the initial models and the updater that acts between samples (the
stop refits of the online baselines, the adaptive bias noise)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario, baseline_fits, filter_models, static_segments
from imunoise.online import MotionNoisePrior, OnlineConfig, OnlineNavigator

__all__ = ["EVIDENCE_METHODS", "SIM_EXTRA", "ONLINE_BASELINES", "SF_SUFFIX", "NHC_SUFFIX", "LABELS", "WARM_METHODS",
           "STATIC_WARM_METHODS", "base_method", "with_nhc", "StopRefit", "AdaptiveUpdater", "Updater",
           "static_var_models", "hindsight_fits", "method_setup", "LEARNED_ROWS"]

EVIDENCE_METHODS = ("plain", "static_var", "av", "em", "av_online", "em_online", "gmwm", "gmwm_hindsight")
SIM_EXTRA = ("oracle_law", "oracle")
ONLINE_BASELINES = {"static_var": "static_var", "av_online": "av", "em_online": "em"}
SF_SUFFIX = "+sf"  # a method with the scale-factor states in the filter
NHC_SUFFIX = "+nhc"  # a method with the non-holonomic constraints in the filter
LABELS = {
    "static_var": "static variance as white noise (stops so far)",
    "static_var_hindsight": "static variance as white noise (all static data)",
    "av_online": "AV-based (stops so far)",
    "em_online": "EM-based (stops so far)",
    "gmwm_hindsight": "GMWM, GOF (all static data)",
    "adaptive": "plain + innovation-based adaptive bias noise (covariance matching)",
    "gmwm_dyn": "GMWM + in-motion gyro noise learned by rehearsed outages",
    "gmwm_lik": "gmwm_dyn deciding by the GNSS innovation likelihood (EXPERIMENTAL research code)",
    "gmwm_dyn_warm": "gmwm_dyn carrying what it learned on an earlier drive of the same vehicle",
    "gmwm_dyn_warm3": "gmwm_dyn carrying what it learned on three earlier drives of the same vehicle",
    "gmwm_warm": "GMWM pooling the stops of an earlier drive of the same vehicle",
    "gmwm_warm3": "GMWM pooling the stops of three earlier drives of the same vehicle",
    "gmwm_dyn_warm3_stops": "gmwm_dyn_warm3 also pooling the stops of its three earlier drives",
    "in_use": "static + in-motion model learned on the vehicle's earlier drives, from the first sample",
    "in_use_stops": "in_use in the online engine, refitting its static part at the stops (as online --imu-model)",
    "oracle_const": "true static model + the law's constant in-motion average (in_use's family; simulator only)",
    "oracle_const_gmwm": "in_use's static part + the law's constant in-motion average (simulator only)",
}
# the rows that navigate with what in_use learned on the vehicle's earlier drives (in_use itself, in the batch
# filter and in the online engine; the constant-model
# ceiling on in_use's static part: imunoise.experiments.oracle_const)
LEARNED_ROWS = ("in_use", "in_use_stops", "oracle_const_gmwm")
# method → earlier drives whose learner evidence it carries
WARM_METHODS: dict[str, int] = {"gmwm_dyn_warm": 1, "gmwm_dyn_warm3": 3, "gmwm_dyn_warm3_stops": 3}
# method → (the method it is, earlier drives whose stops it pools)
STATIC_WARM_METHODS: dict[str, tuple[str, int]] = {"gmwm_warm": ("gmwm", 1), "gmwm_warm3": ("gmwm", 3),
                                                   "gmwm_dyn_warm3_stops": ("gmwm_dyn_warm3", 3)}


def base_method(name: str) -> str:
    """The method without its filter suffixes (``gmwm+sf+nhc`` → ``gmwm``)."""
    while name.endswith((SF_SUFFIX, NHC_SUFFIX)):
        name = name.removesuffix(SF_SUFFIX).removesuffix(NHC_SUFFIX)
    return name


def with_nhc(methods: Sequence[str]) -> tuple[tuple[str, ...], list[tuple[str, str]]]:
    """Every method and its ``+nhc`` twin, with the pairs twin/method and twin/``plain+nhc``,
    twin/``static_var+nhc`` where run (the ranking of the noise methods with the constraints on, as
    :func:`~imunoise.experiments.dense_paired.paired_list` ranks them without)."""
    twins = tuple(m + NHC_SUFFIX for m in methods if not m.endswith(NHC_SUFFIX))
    all_ = tuple(dict.fromkeys((*methods, *twins)))
    pairs = [(t, t.removesuffix(NHC_SUFFIX)) for t in twins]
    for b in ("plain" + NHC_SUFFIX, "static_var" + NHC_SUFFIX):
        if b in all_:
            pairs += [(t, b) for t in twins if t != b and (t, b) != ("plain+nhc", "static_var+nhc")]
    return all_, pairs


class StopRefit:
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


class AdaptiveUpdater:
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


Updater = StopRefit | AdaptiveUpdater  # what acts on the navigator between samples


def static_var_models(segments: Sequence[np.ndarray]) -> list:
    """Per axis ``WN(σ²)`` with σ² the variance of the pooled bias-removed static samples (the model-free
    baseline; the filter mapping adds the plain floor)."""
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN

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
        from imunoise.noise.selection import select_model
        from imunoise.online import COMPLETE

        cache[name] = [select_model([s[:, a] for s in segs], freq=sc.rate, complete=COMPLETE, criterion="gof",
                                    top=1, unit="rad/s" if a < 3 else "m/s²").best for a in range(6)]
    else:
        raise ModelError(f"no hindsight fit for {name!r}")
    return cache[name]


def method_setup(name: str, sc: Scenario, base: OnlineConfig | None = None, cache: dict | None = None, *,
                 prior: MotionNoisePrior | None = None) -> tuple[OnlineConfig, Any, Updater | None]:
    """(OnlineConfig, initial models, stop-refit updater or None) of a method (module docstring); ``prior``:
    the evidence an earlier drive gives ``gmwm_dyn_warm`` (:func:`~imunoise.experiments.dense_warm.learn_prior`)."""
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
    if name == "gmwm_lik":  # gmwm_dyn deciding by likelihood-ratio tests (MotionNoiseConfig.statistic)
        cfg, models, upd = method_setup("gmwm_dyn", sc, base, cache)
        from imunoise.online.learner.candidates import LIKELIHOOD_FAMILIES

        mn = replace(cfg.motion_noise, statistic="likelihood", families=LIKELIHOOD_FAMILIES)
        return cfg.with_(motion_noise=mn), models, upd
    plain_cfg, _ = method_config("plain", sc, base)
    if name in ONLINE_BASELINES:
        gyro, accel = sc.imu.rates()
        if "rates" not in cache:
            cache["rates"] = np.column_stack([gyro, accel])
        upd = StopRefit(ONLINE_BASELINES[name], cache["rates"], sc.rate, plain_cfg, cache.setdefault("stop_fits", {}))
        return plain_cfg, None, upd
    if name == "adaptive":
        return plain_cfg, None, AdaptiveUpdater()
    if name in ("av", "em", "gmwm_hindsight", "static_var_hindsight"):
        return plain_cfg, filter_models(hindsight_fits(sc, name, cache), sc.rate, plain_cfg), None
    cfg, models = method_config(name, sc, base, fits_cache=cache)
    return cfg, models, None


# --------------------------------------------------------------------------------------------------
