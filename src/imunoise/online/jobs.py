"""The modelling job of the online engine (docs/guide/theory.rst, 'Online engine'): :func:`model_job` identifies the
structure or refits it
per axis on the pooled static WVs, and rejects an implausible fit (non-finite, or a GOF worse than the current
model's). A pure function of its inputs, so the navigator runs it inline (replay) or in a worker thread."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from imunoise.errors import ImunoiseError
from imunoise.noise.estimator import GMWMFit
from imunoise.online.config import OnlineConfig

__all__ = ["model_job"]


# --------------------------------------------------------------------------------------------------
# modelling job (pure function of the pooled WVs and the current fits; runs inline or in a thread)
# --------------------------------------------------------------------------------------------------
def model_job(kind: str, wvs: list, current: list[GMWMFit | None], config: OnlineConfig, freq: float) -> dict:
    from imunoise.noise.selection import refit, select_model

    fits: list[GMWMFit | None] = []
    elapsed: list[float] = []
    rankings: list[Any] = []
    rejected: list[str | None] = []
    for a in range(6):
        t0 = time.perf_counter()
        unit = "rad/s" if a < 3 else "m/s²"
        reason = None
        fit = None
        ranking = None
        try:
            if kind == "identify" or current[a] is None:
                ranking = select_model(wvs[a], freq=freq, complete=config.complete, criterion=config.criterion,
                                       top=config.top, weights=config.weights, unit=unit)
                fit = ranking.best
            else:
                fit = refit(current[a], wvs[a], start=current[a], freq=freq, weights=config.weights, unit=unit)
        except ImunoiseError as exc:
            reason = f"fit failed: {exc}"
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:  # never crash the filter
            reason = f"fit failed ({type(exc).__name__}): {exc}"
        if fit is not None:
            reason = _implausible(fit, current[a])
        elapsed.append(time.perf_counter() - t0)
        rankings.append(ranking)
        rejected.append(reason)
        fits.append(None if reason else fit)
    return {"fits": fits, "elapsed": elapsed, "rankings": rankings, "rejected": rejected}


def _implausible(fit: GMWMFit, current: GMWMFit | None) -> str | None:
    """Reason to reject a fit, or None (docs/guide/theory.rst, 'Online engine': non-finite, GOF worse than the current
    model's)."""
    v = fit.model.vector
    if not (np.all(np.isfinite(v)) and math.isfinite(fit.objective)):
        return "non-finite parameters or GOF"
    if current is not None and current.model.unknown() == fit.model.unknown():
        try:
            gof_cur = fit.objective_at(current.model)
        except (ImunoiseError, ValueError):
            gof_cur = math.inf
        if fit.objective > gof_cur * (1 + 1e-9) + 1e-12:
            return f"GOF {fit.objective:.4g} worse than the current model's {gof_cur:.4g} on the same WV"
    return None
