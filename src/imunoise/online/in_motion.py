"""The in-motion part of a model file in the online engine (``online --imu-model`` with an ``in_motion`` part;
docs/guide/theory.rst, 'In-use noise').

The engine starts from the file's static part plus the door's moving states
(:func:`imunoise.nav.filter_model.in_motion_filter`). The moving flag is the one ``nav`` uses
(:func:`imunoise.inuse.stops.moving_flag`: not a stop of the static detector, λ0 from the first
``static_duration`` s): at each sample where it flips, an event of the engine
(:meth:`~imunoise.online.navigator.OnlineNavigator.add_event_source`) switches the filter between the in-motion
noise (white PSD × factor², moving states evolving) and the static one (factor 1, moving states frozen)
(:class:`~imunoise.nav.noise_schedule.NoiseControl`). The stops keep refining the static part: each new fit is
composed with the same in-motion part at the swap (:meth:`InMotionSchedule.swap_into`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from imunoise.nav.defaults import normalize_axis_models
from imunoise.nav.filter_model import InMotionFilter, in_motion_filter
from imunoise.nav.moving_run import moving_control
from imunoise.noise.in_motion import InMotionPart

__all__ = ["InMotionSchedule", "attach_in_motion", "initial_models"]


class InMotionSchedule:
    """The in-motion part and the filter's noise control: ``compose`` before building or swapping the filter,
    ``attach`` after, ``set_moving`` when the flag flips."""

    def __init__(self, part: InMotionPart, rate: float) -> None:
        self.white = part.white_factors()
        self.sigma, self.tau = part.moving_gm()
        self.rate = float(rate)
        self.imf: InMotionFilter | None = None
        self.control = None
        self.moving: bool | None = None

    def compose(self, static_models: Any) -> list:
        """The filter models: the static ones plus the moving states."""
        self.imf = in_motion_filter(normalize_axis_models(static_models, self.rate), self.white, self.sigma, self.tau)
        return self.imf.models

    def attach(self, ekf: Any) -> None:
        """Build the noise control on the filter's (new) layout and apply the current flag."""
        self.control = moving_control(ekf, self.imf)
        flag, self.moving = self.moving, None
        self.set_moving(ekf, True if flag is None else flag)

    def set_moving(self, ekf: Any, moving: bool) -> None:
        """Switch the filter's noise when the flag changes."""
        if moving == self.moving or self.control is None:
            return
        self.moving = bool(moving)
        w = np.asarray(self.imf.white, dtype=float) if moving else np.ones(6)
        self.control.set_noise_scale(w, np.ones(6))
        self.control.set_moving(self.moving)
        ekf.set_noise(self.control.arrays())

    def swap_into(self, ekf: Any):
        """A ``swap_model`` for the engine's model swaps: the new static models composed with the moving states,
        then the noise control rebuilt on the new layout."""

        def swap(models, **kw):
            counts = ekf.swap_model(self.compose(models), **kw)
            self.attach(ekf)
            return counts

        return swap


def attach_in_motion(nav: Any, part: InMotionPart, static_models: list, moving: np.ndarray) -> InMotionSchedule:
    """Give the navigator ``nav`` (built on ``compose(static_models)``, see :func:`initial_models`) the in-motion
    schedule: the noise control on its filter and one event per flip of ``moving`` (bool per IMU sample, in push
    order)."""
    sched = InMotionSchedule(part, nav.rate)
    sched.compose(static_models)
    sched.attach(nav.ekf)
    nav.in_motion = sched
    mv = np.asarray(moving, dtype=bool)
    flips = np.concatenate([[0], np.flatnonzero(mv[1:] != mv[:-1]) + 1]).astype(np.int64)
    nav.add_event_source(flips, lambda nv, i: nv.in_motion.set_moving(nv.ekf, bool(mv[i])))
    return sched


def initial_models(part: InMotionPart, static_models: list, rate: float) -> list:
    """The navigator's first filter models: the static part plus the moving states."""
    return InMotionSchedule(part, rate).compose(static_models)
