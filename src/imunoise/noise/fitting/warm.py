"""Warm-up of the compiled kernels of the modelling path (docs/guide/theory.rst, 'Online engine': the first
identification of the online engine).

numba compiles a kernel on its first call for each new type signature, or loads it from the on-disk
cache (``__pycache__/*.nbi``/``*.nbc`` beside the sources, every kernel has ``cache=True``). In a fresh
clone (empty cache) the fitting kernels take 8–10 s of CPU to compile (measured), and in a fresh process
with a filled cache loading them still takes a few tenths of a second; without a warm-up both land in the
first identification of the online engine, after the first stop. :func:`warm_up` pays that cost up front:
it runs the production code paths — the pooled WV accumulator (:class:`imunoise.noise.wv.WVAccumulator`), the model
selection's kernels (estimator, WVIC likelihood, quasi-likelihood step) and the refit
(:func:`imunoise.noise.fitting.estimate.refit`) — once on a tiny seeded series, so every kernel they call is
compiled (or loaded) with exactly the signatures the real calls use (float64 C-contiguous arrays, int64
kind codes, int64/float64 scalars).
:class:`imunoise.online.OnlineNavigator` calls it at construction. Precompile after an install with::

    python -c "import imunoise; imunoise.warm_up()"
"""

from __future__ import annotations

import threading
import time
from typing import Any

__all__ = ["warm_up", "modelling_dispatchers"]

# modules whose kernels the identification and refit paths call
# (the processes' numba forms are compiled as part of the fitting kernels that call them)
_MODULES = ("imunoise.noise.fitting.kernels", "imunoise.noise.fitting.ar1_levels", "imunoise.noise.ar1_math",
            "imunoise.noise.processes", "imunoise.noise.process_ma1", "imunoise.noise.wv")
# the complete model of the online engine: every kind code (AR1, WN, QN, RW, DR) and a multi-AR1 structure
_COMPLETE = "2*AR1 + DR + WN + QN + RW"

_LOCK = threading.Lock()
_DONE: dict[str, Any] | None = None


def modelling_dispatchers() -> dict[str, Any]:
    """The numba dispatchers of the modelling path, by qualified name (``module.function``).

    Returns
    -------
    dict
        ``{"imunoise.noise.fitting.kernels.levenberg_marquardt": <CPUDispatcher>, ...}`` for every compiled
        function of the fitting kernels and the wavelet variance (imports the modules).
    """
    import importlib

    from numba.core.dispatcher import Dispatcher

    out: dict[str, Any] = {}
    for name in _MODULES:
        mod = importlib.import_module(name)
        for attr, obj in vars(mod).items():
            if isinstance(obj, Dispatcher) and getattr(obj, "__module__", name) == name:
                out[f"{name}.{attr}"] = obj
    return out


def _cache_counts(dispatchers: dict[str, Any]) -> tuple[int, int]:
    hits = sum(sum(d.stats.cache_hits.values()) for d in dispatchers.values())
    misses = sum(sum(d.stats.cache_misses.values()) for d in dispatchers.values())
    return hits, misses


def _exercise() -> None:
    # imports here: ``import imunoise.noise.fitting`` stays light (the CLI's start-up imports no numpy)
    import numpy as np

    from imunoise.noise.fitting.estimate import gmwm, refit
    from imunoise.noise.fitting.problem import prepare
    from imunoise.noise.fitting.wvic import ql_estimate, wv_neg_loglik
    from imunoise.noise.wv import WVAccumulator

    rng = np.random.default_rng(0)
    freq = 100.0
    acc = WVAccumulator(freq=freq)
    for n in (1536, 1024):  # two static segments, as the online engine pools them
        x = rng.standard_normal(n) + 0.02 * np.cumsum(rng.standard_normal(n))
        acc.add(x - x.mean())
    wv = acc.result()
    # the kernels model selection runs (the estimator, its WVIC likelihood and quasi-likelihood step), called
    # here directly: the selection sits above the fitting layer
    best = gmwm(_COMPLETE, wv, freq=freq, unit="rad/s")
    wv_neg_loglik(wv, best.model)
    ql_estimate(prepare(wv, freq=freq), best.model)
    refit(best, wv, start=best, freq=freq, unit="rad/s")


def warm_up(*, force: bool = False) -> dict[str, Any]:
    """Compile (or load from numba's on-disk cache) every kernel the identification and refit use.

    Runs the WV accumulator, the model selection and a refit once on a tiny seeded series (module
    docstring), so the first real identification finds every kernel ready with the same signatures.
    Thread-safe; the work is done once per process (later calls return at once unless ``force``).

    Parameters
    ----------
    force
        Run the exercise again even if this process already did (e.g. to time it).

    Returns
    -------
    dict
        ``time_s`` (wall time of this call), ``compiled`` (kernel signatures compiled now, i.e. not
        found in the on-disk cache), ``loaded`` (signatures loaded from the cache), ``kernels`` (number of
        modelling kernels) and ``already`` (True when an earlier call of this process did the work).
    """
    global _DONE
    t0 = time.perf_counter()
    with _LOCK:
        if _DONE is not None and not force:
            return {**_DONE, "time_s": time.perf_counter() - t0, "already": True}
        disp = modelling_dispatchers()
        hits0, misses0 = _cache_counts(disp)
        _exercise()
        hits1, misses1 = _cache_counts(disp)
        result = {
            "time_s": time.perf_counter() - t0,
            "compiled": misses1 - misses0,
            "loaded": hits1 - hits0,
            "kernels": len(disp),
            "already": False,
        }
        _DONE = dict(result)
        return result
