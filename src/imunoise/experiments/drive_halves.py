"""Cross-fitting on the two halves of one drive (``--learn-half first|second``; docs/guide/theory.rst,
'Experiments'): the ``in_use`` row learns its in-motion model on one half of the drive and every row is scored on
the other half only, so one real drive gives a learn-here, navigate-there comparison in both directions.

The halves are cut at the midpoint between the navigation start (``init.t``, the alignment at the drive's first
stop) and the last GNSS fix. A filter started mid-drive from the reference state diverged on the real drive, so
every run, learning or scored, starts from the drive's own alignment and runs through both halves; what makes a
half is what is *scored*:

* learning on the first half: the drive cut at the midpoint, all its fixes scored by the in-motion likelihood;
* learning on the second half: the whole drive, only the fixes from the midpoint on scored
  (``extra["score_after_s"]``, :mod:`imunoise.inuse.likelihood`); the filter state at the midpoint carries what
  the first half's fixes told it, and nothing else of the first half enters the likelihood;
* scored half: the dense windows whose whole outage lies inside it (:func:`windows_in`) and the NEES epochs inside
  it (``extra["score_span_s"]``, :func:`imunoise.experiments.nees.scored_epochs`).

The static part of the ``in_use`` model is GMWM with GOF selection on all stops the static detector finds in the
drive (``gmwm_hindsight``'s fit, :func:`imunoise.experiments.dense_methods.hindsight_fits`), the same in both
directions, so ``in_use`` / ``gmwm_hindsight`` isolates what the in-motion part adds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario, filter_models

__all__ = ["HALVES", "half_spans", "other_half", "check_half", "learning_half", "windows_in", "scored_half",
           "learn_on_half"]

HALVES = ("first", "second")


def check_half(which: Any) -> str:
    """``--learn-half`` as "first" or "second", else a one-line :class:`ModelError`."""
    if which not in HALVES:
        raise ModelError(f"--learn-half must be 'first' or 'second' (the half of the drive in_use learns on), "
                         f"got {which!r}")
    return str(which)


def other_half(which: str) -> str:
    """The half that is scored when ``which`` is learned on."""
    return HALVES[1 - HALVES.index(check_half(which))]


def half_spans(sc: Scenario) -> dict[str, tuple[float, float]]:
    """The two halves of drive ``sc`` in data time [s]: first = [init.t, mid), second = [mid, last fix + 1 s), mid
    the midpoint between the navigation start and the last GNSS fix."""
    t0 = float(sc.init.t)
    t1 = float(np.max(np.asarray(sc.gnss.t, dtype=float)))
    if not t1 > t0:
        raise ModelError(f"{sc.name}: no GNSS fix after the navigation start ({t0:.3f} s): no halves to cut")
    mid = 0.5 * (t0 + t1)
    return {"first": (t0, mid), "second": (mid, t1 + 1.0)}


def learning_half(sc: Scenario, gnss, which: str) -> Scenario:
    """Drive ``sc`` with fixes ``gnss`` as the in-motion estimate sees it when it learns on half ``which``
    (module docstring): cut at the half's end, fixes scored from the half's start."""
    lo, hi = half_spans(sc)[check_half(which)]
    imu = sc.imu.slice(float(sc.imu.t[0]), hi)
    keep = np.asarray(sc.imu.t) <= hi
    st = None if sc.static_truth is None else np.asarray(sc.static_truth)[keep]
    extra = {k: v for k, v in sc.extra.items() if k != "job_cache"}
    return replace(sc, name=f"{sc.name} ({which} half)", imu=imu, gnss=gnss.slice(float(np.min(gnss.t)), hi),
                   static_truth=st, extra={**extra, "score_after_s": lo})


def windows_in(windows: Sequence[tuple[float, float]], span: tuple[float, float]) -> list[tuple[float, float]]:
    """The windows (start, L) whose outage [start, start + L] lies inside ``span`` = [a, b), in their order."""
    a, b = span
    return [w for w in windows if w[0] >= a - 1e-9 and w[0] + w[1] <= b + 1e-9]


def scored_half(sc: Scenario, learn: str) -> Scenario:
    """Drive ``sc`` whose NEES is scored on the other half than ``learn`` only (``extra["score_span_s"]``)."""
    return replace(sc, extra={**sc.extra, "score_span_s": half_spans(sc)[other_half(learn)]})


def learn_on_half(sc: Scenario, gnss, which: str, base=None, cache: dict | None = None):
    """The ``in_use`` model (:class:`~imunoise.experiments.in_use_method.InUseModel`) learned on half ``which`` of
    drive ``sc`` with fixes ``gnss``: static part ``gmwm_hindsight``'s fit on all the drive's stops, in-motion part
    :func:`imunoise.inuse.estimate_in_motion` on :func:`learning_half`."""
    from imunoise.experiments.dense_methods import hindsight_fits
    from imunoise.experiments.in_use_method import InUseModel
    from imunoise.inuse import estimate_in_motion
    from imunoise.online import OnlineConfig

    cfg = (base or OnlineConfig()).with_(ekf=sc.ekf_config())
    models = filter_models(hindsight_fits(sc, "gmwm_hindsight", cache if cache is not None else {}), sc.rate, cfg)
    d = learning_half(sc, gnss, which)
    est = estimate_in_motion([d], models, freq=sc.rate, names=[d.name])
    return InUseModel(models, est.part, est.cpu_s, est.runs, [d.name])
