"""The ``in_use`` row of the dense-window evidence: the model a vehicle's earlier drives give, used on its next
drive from the first sample (docs/guide/theory.rst, 'In-use noise' and 'Experiments').

Learning (:func:`learn_in_use`), on the earlier drives alone:

* the static part: the fits the online engine (the ``gmwm`` row) holds at the end of its GNSS-aided run on the
  earlier drives (:func:`imunoise.experiments.dense_warm.gmwm_on_drives`: the stops its stop guard kept, identified
  and refit by :class:`~imunoise.online.modeller.StopModeller`), mapped to the filter as every method's models are
  (:func:`imunoise.experiments.common.filter_models`). One way of fitting stops for both rows: ``in_use`` is
  ``gmwm``'s static model plus the in-motion part. (The earlier fit, GMWM with GOF selection on every segment the
  IMU-only detector finds, pooled the false stops a noisy IMU's detector lets through while the car cruises: on
  the ADIS16405 replay 15 and 16 of a learning drive's 20 such segments failed the stop guard, and accel_x got a
  random walk from them: docs/evidence/in_use_carry_over.md);
* the in-motion part: :func:`imunoise.inuse.estimate_in_motion` on the earlier drives, GNSS-aided throughout in the
  run's GNSS regime (:func:`imunoise.experiments.carry_over.learning_drives`), on top of that static part.

Navigating (:func:`run_windows_in_use`): the door's in-motion filter of that model
(:func:`imunoise.nav.filter_model.in_motion_filter`: white factor² on the white PSD while moving, a moving
Gauss–Markov state per axis with wander, frozen at stops) in the batch kernel, piece by piece where the drive's
moving flag flips (:func:`imunoise.inuse.likelihood.drive_moving`: the known stops on the simulator, as the
estimate used), with the protocol of :func:`imunoise.experiments.oracle_law.run_windows_law` (one aided run, a
GNSS-free branch per window; NEES of the aided run). The model is fixed through the drive: no refit at stops.

``in_use_stops`` (:func:`in_use_stops_run`) navigates the same model the way ``online --imu-model`` does:
the online engine (the ``gmwm`` row's) starts from the static part plus the in-motion schedule
(:func:`imunoise.online.in_motion.attach_in_motion`, on the same moving flag), pools the learning drives' stops
(``earlier_static``, as ``gmwm_warm``) and keeps refitting the static part at the scored drive's stops, each refit
composed with the same in-motion part. ``in_use`` against ``gmwm`` compares one drive's stops with another's;
``in_use_stops`` has the stops of both, so what it adds over ``gmwm`` is the earlier stops and the in-motion part.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario, filter_models

__all__ = ["learn_in_use", "run_windows_in_use", "in_use_stops_run", "in_motion_law_filter", "InUseModel"]


class InUseModel:
    """What ``in_use`` carries to the next drive: the six static filter models (``models``: each model with
    its rate) and the in-motion part, with the estimate's cost and the learning drives' names; ``static_pieces``:
    the learning drives' pooled stops (:attr:`~imunoise.online.result.OnlineResult.static_pieces`; None where the
    static part was not fitted on them), which ``in_use_stops`` pools with the scored drive's."""

    def __init__(self, models: list, part: Any, cpu_s: float, runs: int, drives: list[str],
                 static_pieces: list[np.ndarray] | None = None) -> None:
        self.models, self.part, self.cpu_s, self.runs, self.drives = models, part, cpu_s, runs, drives
        self.static_pieces = static_pieces

    def summary(self) -> dict[str, Any]:
        """The part as the model file writes it, and the cost of the estimate."""
        return {"in_motion": self.part.to_dict(), "cpu_s": self.cpu_s, "filter_runs": self.runs,
                "drives": self.drives}


def learn_in_use(drives: Sequence[tuple[Scenario, Any]], fits: Sequence[Any], base=None,
                 static_pieces: list[np.ndarray] | None = None) -> InUseModel:
    """The ``in_use`` model of a vehicle from its earlier ``drives`` ((scenario, GNSS) pairs) and ``fits``, the six
    per-axis fits the online engine identified at their stops (``gmwm_on_drives(drives, base).fits``; module
    docstring); ``static_pieces`` those stops (``gmwm_on_drives(drives, base).static_pieces``)."""
    from imunoise.inuse import estimate_in_motion
    from imunoise.online import OnlineConfig

    if len(fits) != 6:
        raise ModelError(f"in_use needs the six per-axis fits of the online engine (gyro x, y, z, accel x, y, z), "
                         f"got {len(fits)}; pass gmwm_on_drives(drives).fits")
    scs = [replace(sc, gnss=g) for sc, g in drives]
    cfg = (base or OnlineConfig()).with_(ekf=scs[0].ekf_config())
    models = filter_models(list(fits), scs[0].rate, cfg)
    est = estimate_in_motion(scs, models, freq=scs[0].rate, names=[sc.name for sc in scs])
    return InUseModel(models, est.part, est.cpu_s, est.runs, [sc.name for sc in scs], static_pieces)


def in_motion_law_filter(sc: Scenario, models: list, white_factor, gm_sigma, gm_tau_s, starts, base):
    """The oracle-law batch filter's inputs with the in-motion filter of the static filter models ``models`` and the
    per-axis white factor, moving GM σ and τ (:func:`imunoise.nav.filter_model.in_motion_filter`), its pieces where
    the moving flag flips (and at the window starts); also the ``oracle_const`` row's filter."""
    from imunoise.experiments.oracle_law import LawFilter, law_filter
    from imunoise.inuse.likelihood import drive_moving
    from imunoise.nav.filter_model import in_motion_filter
    from imunoise.nav.moving_run import moving_bounds, moving_control

    imf = in_motion_filter(models, white_factor, gm_sigma, gm_tau_s)
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


def _moving_law_filter(sc: Scenario, model: InUseModel, starts, base):
    """:func:`in_motion_law_filter` of ``model``."""
    sig, tau = model.part.moving_gm()
    return in_motion_law_filter(sc, model.models, model.part.white_factors(), sig, tau, starts, base)


def run_windows_in_use(sc: Scenario, gnss, windows, model: InUseModel, *, base=None, nees: bool = False) -> dict:
    """:func:`imunoise.experiments.dense.run_windows`'s keys for ``in_use`` on drive ``sc`` with ``model``."""
    from imunoise.experiments.oracle_law import run_windows_law

    return run_windows_law(sc, gnss, windows, base=base, nees=nees,
                           make=lambda s, starts, b: _moving_law_filter(s, model, starts, b))


def in_use_stops_run(sc: Scenario, model: InUseModel, *, base=None, cache=None) -> tuple[Any, dict]:
    """``in_use_stops`` on drive ``sc`` with ``model`` (module docstring): (the online engine's config, the keywords
    of :func:`imunoise.experiments.dense.run_windows`): the engine from ``model``, refitting its static part at the
    stops."""
    from imunoise.experiments.dense_methods import method_setup
    from imunoise.inuse.likelihood import drive_moving
    from imunoise.online.in_motion import attach_in_motion, initial_models

    if model.static_pieces is None:
        raise ModelError("in_use_stops pools the stops in_use learned its static part on, and this model has none "
                         "(--learn-half fits its static part on the whole drive's stops); use in_use")
    cfg, _, upd = method_setup("gmwm", sc, base, cache)
    moving = drive_moving(sc)  # per IMU sample in push order, the flag the estimate and in_use use
    return cfg, {"initial_models": initial_models(model.part, model.models, sc.rate), "updater": upd,
                 "earlier_static": model.static_pieces,
                 "prepare": lambda nav: attach_in_motion(nav, model.part, model.models, moving)}
