"""The in-motion estimate's search on a synthetic likelihood: the real :class:`DriveLikelihood` (cache, run count)
with the filter run replaced by a smooth function of θ, so the estimator's rules can be checked in milliseconds
and every θ it evaluates, in order, compared between two versions of the code (:func:`every_number`)::

    PYTHONPATH=<src of one version> python -c "import sys; sys.path.insert(0, 'tests/inuse'); \\
        import test_estimate_synthetic as t; t.dump('out.json')"
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np

import imunoise.inuse.likelihood as lik_mod
from imunoise.inuse import estimate_in_motion
from imunoise.nav.defaults import default_axis_models

TRUE_K = {"wander": (3e-5, 2e-4), "none": (0.0, 0.0)}  # driving density [unit/√s] of the optimum: gyro, accel
GROUP_ORDERS = (("gyro", "accel"), ("accel", "gyro"), ("gyro",), ("accel",))


def synthetic_nll(kind: str, th: tuple) -> float:
    """A smooth NLL of (white, σ, τ) per axis with its optimum at white factor e^0.3 (gyros) / e^−0.2 (accels) and
    driving density ``TRUE_K[kind]``, the two groups coupled (the best values of one depend on the other's)."""
    kg, ka = TRUE_K[kind]
    white, sigma, tau = th
    v = 0.0
    for i in range(6):
        k = sigma[i] * math.sqrt(2.0 / tau[i])
        scale = 1e-5 if i < 3 else 1e-4
        v += 40.0 * (math.log(white[i]) - (0.3 if i < 3 else -0.2)) ** 2
        v += 30.0 * ((k - (kg if i < 3 else ka)) / scale) ** 2
        v += 5.0 * (math.log(tau[i]) - math.log(120.0)) ** 2 * (k / scale) ** 2
    v += 25.0 * (math.log(white[0]) + math.log(white[3]) - 0.1) ** 2
    return v + 8.0 * (sigma[0] / 1e-4) * (sigma[3] / 1e-3)


def _drive(n: int = 7200):
    """Two hours at 1 Hz, the first 300 s a stop: what the likelihood reads of a drive besides its runs."""
    return SimpleNamespace(imu=SimpleNamespace(t=np.arange(n, dtype=float)), init=SimpleNamespace(t=0.0),
                           gnss=SimpleNamespace(sigma_ned=np.ones((10, 3))), name="synthetic",
                           static_truth=np.arange(n) < 300)


def estimate(kind: str, groups: tuple, patch, maxfev: int = 40):
    """The estimate on the synthetic likelihood and the θ it evaluated (cache misses), in order; ``patch(name,
    value)`` replaces a global of :mod:`imunoise.inuse.likelihood`."""
    trace: list = []

    def drive_terms(drive, moving, th):  # one term per drive: no scores to estimate a dispersion from (c = 1)
        trace.append(th)
        return np.array([synthetic_nll(kind, th)])

    patch("in_motion_filter", lambda models, w, s, t: (tuple(w), tuple(s), tuple(t)))
    patch("drive_terms", drive_terms)
    est = estimate_in_motion([_drive()], default_axis_models(100.0), freq=100.0, groups=groups, maxfev=maxfev)
    return est, trace


def every_number(maxfev: int = 40) -> dict:
    """Every number of the estimate and every θ evaluated, for each synthetic optimum and group order."""
    saved = {k: getattr(lik_mod, k) for k in ("in_motion_filter", "drive_terms")}
    out = {}
    try:
        for kind in TRUE_K:
            for groups in GROUP_ORDERS:
                est, trace = estimate(kind, groups, lambda k, v: setattr(lik_mod, k, v), maxfev)
                out[f"{kind} {'+'.join(groups)}"] = {
                    "part": est.part.to_dict(), "theta": [est.theta.white, est.theta.sigma, est.theta.tau_s],
                    "nll": est.nll, "nll_static": est.nll_static, "cov_log": est.cov_log,
                    "lr_wander": est.lr_wander, "runs": est.runs, "evaluated": trace}
    finally:
        for k, v in saved.items():
            setattr(lik_mod, k, v)
    return out


def dump(path: str) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(every_number(), fh, indent=0, sort_keys=True)


def test_each_wander_test_compares_with_the_no_wander_model_at_the_other_groups_final_values(monkeypatch):
    """LR_g = 2(NLL(no wander of g, the other groups at their final values) − NLL(θ̂)): the no-wander model the
    test uses was evaluated at exactly the other groups' final values, for either group order."""
    from imunoise.inuse.estimate import GROUPS, LR_WANDER

    for groups in GROUP_ORDERS[:2]:
        est, trace = estimate("wander", groups, lambda k, v: monkeypatch.setattr(lik_mod, k, v))
        th = (est.theta.white, est.theta.sigma, est.theta.tau_s)
        for g in groups:
            assert est.lr_wander[g] > LR_WANDER  # the wander is kept: θ̂ is the search's optimum, not switched off
            others = [i for i in range(6) if i not in GROUPS[g]]
            refs = [x for x in trace if all(x[1][i] == 0.0 for i in GROUPS[g])
                    and all(x[j][i] == th[j][i] for j in range(3) for i in others)]
            assert any(2.0 * (synthetic_nll("wander", x) - est.nll) == est.lr_wander[g] for x in refs), (groups, g)
