"""The negative log-likelihood of the GNSS fixes of whole drives as a function of the in-motion noise
(docs/guide/theory.rst, 'In-use noise').

By the prediction-error decomposition the −log likelihood of the fixes z_1 … z_K under a filter model θ is
Σ_k ½(ν_kᵀ S_k⁻¹ ν_k + log det S_k + 3 log 2π), ν_k the one-step innovation and S_k = H P_k⁻ Hᵀ + R_k its
covariance (:func:`imunoise.nav.filter_loop.innovation_nll`); drives are independent, so the NLLs of several
drives add. Every evaluation is one filter run per drive (:func:`imunoise.nav.ekf.run_ekf` with the door's
:class:`~imunoise.nav.filter_model.InMotionFilter` and the drive's moving flag); results are cached by θ.

A drive is any object with what the experiments' :class:`~imunoise.experiments.common.Scenario` carries:
``imu`` (increments), ``gnss`` (fixes), ``init`` (the start state), ``ekf_config()``, optionally
``extra["score_after_s"]`` (only the fixes from that time on are scored: the filter runs from the start, the
likelihood is that of a later part of the drive) and optionally a stop mask
per IMU sample ``static_truth`` (else the static detector finds the stops: :func:`imunoise.inuse.stops.
moving_flag`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.inuse.stops import moving_flag
from imunoise.nav.ekf import run_ekf
from imunoise.nav.filter_model import in_motion_filter

__all__ = ["Theta", "DriveLikelihood", "drive_moving"]


@dataclass(frozen=True)
class Theta:
    """The in-motion parameters of the six axes: white factor (σ scale), moving GM σ [unit] and τ [s]."""

    white: tuple[float, ...] = (1.0,) * 6
    sigma: tuple[float, ...] = (0.0,) * 6
    tau_s: tuple[float, ...] = (60.0,) * 6

    def key(self) -> tuple:
        return tuple(round(float(x), 10) if x == 0 else float(f"{x:.6e}") for x in (*self.white, *self.sigma,
                                                                                     *self.tau_s))


def drive_moving(drive: Any) -> np.ndarray:
    """The moving flag per IMU sample of ``drive``: its known stops (``static_truth``) or the static detector's."""
    st = getattr(drive, "static_truth", None)
    if st is not None:
        return ~np.asarray(st, dtype=bool)
    return moving_flag(drive.imu)


@dataclass
class DriveLikelihood:
    """The pooled NLL of the GNSS fixes of ``drives`` (module docstring) under the static filter ``pairs`` (the six
    models of the door, each with its rate) plus an in-motion :class:`Theta`; ``nll(theta)`` is cached."""

    drives: Sequence[Any]
    pairs: list
    cache: dict = field(default_factory=dict)
    runs: int = 0
    cpu_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.drives:
            raise DataError("the in-motion estimate needs at least one drive with GNSS")
        self.moving = [drive_moving(d) for d in self.drives]

    def nll(self, theta: Theta) -> float:
        """Σ over drives and fixes of the innovation NLL (inf when a run fails)."""
        k = theta.key()
        if k in self.cache:
            return self.cache[k]
        t0 = time.process_time()
        imf = in_motion_filter(self.pairs, theta.white, theta.sigma, theta.tau_s)
        total = 0.0
        for d, mv in zip(self.drives, self.moving, strict=True):
            try:
                r = run_ekf(d.imu, d.gnss, d.init, d.ekf_config(), in_motion=imf, moving=mv, with_nll=True)
            except (DataError, np.linalg.LinAlgError):  # a filter that diverges under θ: θ explains nothing
                total = math.inf
                break
            t_after = (getattr(d, "extra", None) or {}).get("score_after_s", -math.inf)
            total += float(np.nansum(r.gnss_nll[np.asarray(r.gnss_t) >= t_after]))
        self.runs += len(self.drives)
        self.cpu_s += time.process_time() - t0
        self.cache[k] = total
        return total

    def hours_moving(self) -> float:
        """Hours of driving (moving flag) over the drives."""
        h = 0.0
        for d, mv in zip(self.drives, self.moving, strict=True):
            t = np.asarray(d.imu.t, dtype=float)
            dt = np.diff(t, prepend=t[0])
            h += float(np.sum(dt[mv & (t >= d.init.t)])) / 3600.0
        return h

    def gnss_sigma_m(self) -> float:
        """Median horizontal σ of the fixes [m]."""
        s = np.concatenate([np.asarray(d.gnss.sigma_ned, dtype=float)[:, :2].ravel() for d in self.drives])
        s = s[np.isfinite(s)]
        return float(np.median(s)) if s.size else math.nan
