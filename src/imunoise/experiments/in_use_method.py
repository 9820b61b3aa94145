"""The ``in_use`` row of the dense-window evidence: the model a vehicle's earlier drives give, used on its next
drive from the first sample (docs/guide/theory.rst, 'In-use noise' and 'Experiments').

Learning (:func:`learn_in_use`), on the earlier drives alone, as ``imunoise calibrate LOG... --in-motion`` would:

* the static part: GMWM (GOF selection, as ``gmwm_hindsight``) on the stops of the earlier drives pooled (the
  static detector's segments, bias removed), mapped to the filter as every method's models are
  (:func:`imunoise.experiments.common.filter_models`);
* the in-motion part: :func:`imunoise.inuse.estimate_in_motion` on the earlier drives, GNSS-aided throughout in the
  run's GNSS regime (:func:`imunoise.experiments.carry_over.learning_drives`), on top of that static part.

Navigating (:func:`run_windows_in_use`): the door's in-motion filter of that model
(:func:`imunoise.nav.filter_model.in_motion_filter`: white factor² on the white PSD while moving, a moving
Gauss–Markov state per axis with wander, frozen at stops) in the batch kernel, piece by piece where the drive's
moving flag flips (:func:`imunoise.inuse.likelihood.drive_moving`: the known stops on the simulator, as the
estimate used), with the protocol of :func:`imunoise.experiments.oracle_law.run_windows_law` (one aided run, a
GNSS-free branch per window; NEES of the aided run). The model is fixed through the drive: no refit at stops.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from imunoise.experiments.common import Scenario, filter_models, static_segments

__all__ = ["learn_in_use", "run_windows_in_use", "InUseModel"]


class InUseModel:
    """What ``in_use`` carries to the next drive: the six static filter pairs and the in-motion part, with the
    estimate's cost and the learning drives' names."""

    def __init__(self, pairs: list, part: Any, cpu_s: float, runs: int, drives: list[str]) -> None:
        self.pairs, self.part, self.cpu_s, self.runs, self.drives = pairs, part, cpu_s, runs, drives

    def summary(self) -> dict[str, Any]:
        """The part as the model file writes it, and the cost of the estimate."""
        return {"in_motion": self.part.to_dict(), "cpu_s": self.cpu_s, "filter_runs": self.runs,
                "drives": self.drives}


def _static_fits(scs: Sequence[Scenario]) -> list:
    """GMWM (GOF selection, ``gmwm_hindsight``'s) of the six axes on the stops of ``scs`` pooled."""
    from imunoise.noise.selection import select_model
    from imunoise.online import COMPLETE

    segs = [s for sc in scs for s in static_segments(sc)[0]]
    return [select_model([s[:, a] for s in segs], freq=scs[0].rate, complete=COMPLETE, criterion="gof", top=1,
                         unit="rad/s" if a < 3 else "m/s²").best for a in range(6)]


def learn_in_use(drives: Sequence[tuple[Scenario, Any]], base=None) -> InUseModel:
    """The ``in_use`` model of a vehicle from its earlier ``drives`` ((scenario, GNSS) pairs; module docstring)."""
    from imunoise.inuse import estimate_in_motion
    from imunoise.online import OnlineConfig

    scs = [replace(sc, gnss=g) for sc, g in drives]
    cfg = (base or OnlineConfig()).with_(ekf=scs[0].ekf_config())
    pairs = filter_models(_static_fits(scs), scs[0].rate, cfg)
    est = estimate_in_motion(scs, pairs, freq=scs[0].rate, names=[sc.name for sc in scs])
    return InUseModel(pairs, est.part, est.cpu_s, est.runs, [sc.name for sc in scs])


def _moving_law_filter(sc: Scenario, model: InUseModel, starts, base):
    """The oracle-law batch filter's inputs with the in-motion filter of ``model`` and its pieces where the
    moving flag flips (and at the window starts)."""
    from imunoise.experiments.oracle_law import LawFilter, law_filter
    from imunoise.inuse.likelihood import drive_moving
    from imunoise.nav.filter_model import in_motion_filter
    from imunoise.nav.moving_run import moving_bounds, moving_control

    sig, tau = model.part.moving_gm()
    imf = in_motion_filter(model.pairs, model.part.white_factors(), sig, tau)
    lf = law_filter(sc, starts, base, models=imf.models)  # constant pieces: 0, the window starts, n − 1
    n = lf.imu.t.size
    mv = drive_moving(sc)[-n:]  # filter sample k is drive sample k + i0 (the filter starts at sc.init)
    b_mv, f_mv = moving_bounds(mv)
    bounds = np.unique(np.concatenate([lf.bounds, b_mv[:-1]])).astype(np.int64)
    moving = np.array([f_mv[int(np.searchsorted(b_mv, a, side="right")) - 1] for a in bounds], dtype=bool)
    white = np.where(moving[:, None], np.asarray(imf.white, dtype=float)[None, :], 1.0)
    k = bounds.size
    return LawFilter(lf.ekf, moving_control(lf.ekf, imf), lf.imu, bounds, white, np.ones((k, 6)), moving,
                     np.zeros(k, dtype=bool), np.zeros(6))


def run_windows_in_use(sc: Scenario, gnss, windows, model: InUseModel, *, base=None, nees: bool = False) -> dict:
    """:func:`imunoise.experiments.dense.run_windows`'s keys for ``in_use`` on drive ``sc`` with ``model``."""
    from imunoise.experiments.oracle_law import run_windows_law

    return run_windows_law(sc, gnss, windows, base=base, nees=nees,
                           make=lambda s, starts, b: _moving_law_filter(s, model, starts, b))
