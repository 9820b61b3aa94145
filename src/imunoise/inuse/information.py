"""The observed information of the in-motion likelihood, and Newton steps that finish its search
(docs/guide/theory.rst, 'In-use noise').

The search (:mod:`imunoise.inuse.estimate`: Nelder–Mead, a few dozen likelihood evaluations per group) stops where
its simplex is small, not where the gradient vanishes; on 30-minute drives its optimum lay a sizeable part of a
standard deviation from the likelihood's (docs/evidence/in_use_estimate.md, 'Where the search stops'), which
widens the estimates' scatter beyond their intervals. The central differences of the Hessian give the gradient
as well, g_i = (ℓ(p + h e_i) − ℓ(p − h e_i)) / 2h, from runs the Hessian makes anyway, so Newton steps
δ = −H⁻¹g finish the search at the cost of one evaluation and one Hessian per step. A step is taken only where
ℓ falls (else half of it is tried once) and the steps stop once the quadratic model's remaining decrease
½ gᵀH⁻¹g is below ``tol``. Parameters the curvature does not identify (:func:`covariance`) are not moved.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.inuse.dispersion import dispersion, score_variance

__all__ = ["WIDE_SD", "Information", "covariance", "dispersion_at", "gradient", "hessian", "newton_finish"]

WIDE_SD = math.log(10.0) / 1.96  # sd of a log parameter whose 95 % interval is ×/÷ 10: wider is not identified


def hessian(fun: Callable[[np.ndarray], float], p: np.ndarray, h: float) -> np.ndarray:
    """The Hessian of ``fun`` at ``p`` by central second differences of step ``h``."""
    n = p.size
    f0 = fun(p)
    H = np.zeros((n, n))
    e = np.eye(n) * h
    for i in range(n):
        H[i, i] = (fun(p + e[i]) - 2 * f0 + fun(p - e[i])) / (h * h)
        for j in range(i):
            H[i, j] = H[j, i] = (fun(p + e[i] + e[j]) - fun(p + e[i] - e[j]) - fun(p - e[i] + e[j])
                                 + fun(p - e[i] - e[j])) / (4 * h * h)
    return H


def gradient(fun: Callable[[np.ndarray], float], p: np.ndarray, h: float) -> np.ndarray:
    """The gradient of ``fun`` at ``p`` by central differences of step ``h`` (the points :func:`hessian`'s
    diagonal evaluates: free where ``fun`` is cached)."""
    e = np.eye(p.size) * h
    return np.array([(fun(p + e[i]) - fun(p - e[i])) / (2.0 * h) for i in range(p.size)])


def covariance(H: np.ndarray) -> np.ndarray:
    """Covariance of the log parameters from the observed information ``H``: a parameter whose curvature alone
    gives an interval wider than ×/÷ 10 (flat) is left out (variance inf) and the rest inverted; if that block is
    not positive definite either, the least curved parameter is left out too, and so on."""
    n = H.shape[0]
    keep = [i for i in range(n) if H[i, i] > 1.0 / WIDE_SD**2]
    while keep:
        sub = H[np.ix_(keep, keep)]
        try:
            np.linalg.cholesky(sub)
        except np.linalg.LinAlgError:
            keep.remove(min(keep, key=lambda i: H[i, i]))
            continue
        cov = np.full((n, n), math.inf)
        cov[np.ix_(keep, keep)] = np.linalg.inv(sub)
        return cov
    return np.full((n, n), math.inf)


@dataclass
class Information:
    """Where the Newton steps ended (``p``), the Hessian ``H`` and covariance ``cov`` (:func:`covariance`) there,
    the steps taken and the quadratic model's remaining decrease ``left`` [NLL units]."""

    p: np.ndarray
    H: np.ndarray
    cov: np.ndarray
    steps: int
    left: float


def newton_finish(fun: Callable[[np.ndarray], float], p: np.ndarray, h: float, lo: np.ndarray, hi: np.ndarray, *,
                  tol: float = 0.02, max_steps: int = 3,
                  decided: Callable[[float, float], bool] | None = None) -> Information:
    """Newton steps on ``fun`` from ``p`` inside the box [``lo``, ``hi``] (module docstring); at most ``max_steps``,
    each taken only where ``fun`` falls; none once ``decided(fun(p), left)`` (a caller that needs only to know
    whether the minimum is below a level stops when the remaining decrease cannot decide it otherwise)."""
    p = np.asarray(p, dtype=float).copy()
    steps = 0
    while True:
        H = hessian(fun, p, h)
        cov = covariance(H)
        keep = [i for i in range(p.size) if math.isfinite(cov[i, i])]
        g = gradient(fun, p, h)
        d = np.zeros(p.size)
        if keep:
            d[keep] = -cov[np.ix_(keep, keep)] @ g[keep]
        left = float(-0.5 * g @ d)
        f0 = fun(p)
        if steps >= max_steps or not left > tol or (decided is not None and decided(f0, left)):
            return Information(p, H, cov, steps, left)
        for frac in (1.0, 0.5):
            q = np.clip(p + frac * d, lo, hi)
            if fun(q) < f0:
                break
        else:
            return Information(p, H, cov, steps, left)
        p = q
        steps += 1


def dispersion_at(lik: Any, thf, p: np.ndarray, h: float, H: np.ndarray, cov: np.ndarray) -> float:
    """The dispersion c ≥ 1 (:mod:`imunoise.inuse.dispersion`) at ``p`` of the parameters ``cov`` keeps (finite
    variance): the per-fix scores by the central differences the Hessian ``H`` (step ``h``) already ran,
    ``thf(p)`` the :class:`Theta` of the log parameters ``p``. Fixes without a term in any of the runs are left
    out; 1 when a run failed."""
    keep = [i for i in range(p.size) if math.isfinite(cov[i, i])]
    if not keep:
        return 1.0
    e = np.eye(p.size) * h
    plus = [lik.terms(thf(p + e[i])) for i in keep]
    minus = [lik.terms(thf(p - e[i])) for i in keep]
    n = len(lik.drives)
    if any(len(t) != n for t in (*plus, *minus)):
        return 1.0
    scores = []
    for d in range(n):
        s = np.column_stack([(a[d] - b[d]) / (2.0 * h) for a, b in zip(plus, minus, strict=True)])
        scores.append(s[np.all(np.isfinite(s), axis=1)])
    return dispersion(H[np.ix_(keep, keep)], score_variance(scores))
