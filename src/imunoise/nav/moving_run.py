"""A filter run whose process noise follows the vehicle's moving flag: the in-motion part of a model file while
moving, the static part at stops (docs/guide/theory.rst, 'In-use noise').

The filter is the door's :class:`~imunoise.nav.filter_model.InMotionFilter` (static models plus one moving
Gauss–Markov state per axis with bias wander); :func:`run_moving` runs the batch kernel piece by piece between
the samples where the moving flag flips (:func:`imunoise.nav.noise_schedule.run_pieces`): while moving the white
PSD of axis j is scaled by its white factor squared and the moving states evolve; at a stop the scale is 1 and
the moving states are frozen (:class:`~imunoise.nav.noise_schedule.NoiseControl`). The moving flag is the
caller's, one boolean per filter sample (the step into sample k): ``nav``, ``online`` and the estimate take
it from :func:`imunoise.inuse.stops.moving_flag` (the static detector's stops) unless the caller knows the stops.
"""

from __future__ import annotations

import numpy as np

from imunoise.nav.filter_loop import FilterArrays, ImuInput, Outputs
from imunoise.nav.filter_model import InMotionFilter, moving_state_rows
from imunoise.nav.noise_schedule import NoiseControl, run_pieces
from imunoise.nav.streams import StreamSet

__all__ = ["moving_control", "moving_bounds", "run_moving"]


def moving_control(ekf, imf: InMotionFilter) -> NoiseControl:
    """The noise control of filter ``ekf`` (built on ``imf.models``): the moving state of each axis is the
    component :func:`~imunoise.nav.filter_model.in_motion_filter` appended (``imf.gm_index``), found in the
    layout by its canonical name."""
    model, _ = ekf.kernel_parts()
    return NoiseControl(ekf.layout, model, ekf.dt_nom, moving_state_rows(imf.models, imf.gm_index, ekf.layout.labels))


def moving_bounds(moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Piece starts (0 … n − 1, the last sample included) where the flag of the step into the next sample flips,
    and each piece's flag."""
    mv = np.asarray(moving, dtype=bool)
    n = mv.size
    step = mv[1:]  # step into k + 1 from piece start k
    change = np.flatnonzero(step[1:] != step[:-1]) + 1
    bounds = np.unique(np.concatenate([[0], change, [n - 1]])).astype(np.int64)
    flags = np.array([bool(step[min(b, n - 2)]) for b in bounds[:-1]])
    return bounds, flags


def run_moving(ekf, imf: InMotionFilter, imu: ImuInput, f: FilterArrays, streams: StreamSet, out: Outputs,
               moving: np.ndarray) -> None:
    """Run all samples of ``imu`` on state ``f`` with the in-motion noise while ``moving`` and the static noise
    at stops (module docstring); outputs and stream results as :func:`~imunoise.nav.filter_loop.run_steps`."""
    ctl = moving_control(ekf, imf)
    bounds, flags = moving_bounds(moving)
    white = np.asarray(imf.white, dtype=float)
    ones = np.ones(6)

    def before(a: int):
        i = int(np.searchsorted(bounds, a, side="right")) - 1
        ctl.set_noise_scale(white if flags[i] else ones, ones)
        ctl.set_moving(bool(flags[i]))
        return ctl.arrays()

    run_pieces(ekf, imu, f, streams, out, [int(b) for b in bounds], before)
