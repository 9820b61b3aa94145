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

The drives' runs of one evaluation are independent: an optional ``mapper`` runs them elsewhere (on Dask:
:mod:`imunoise.inuse.fleet`) and hands back the per-drive NLLs in drive order, which are summed in that order
as the serial loop sums them, so the pooled NLL is the same to the last bit.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.inuse.stops import moving_flag
from imunoise.nav.ekf import run_ekf
from imunoise.nav.filter_model import in_motion_filter

__all__ = ["Theta", "DriveLikelihood", "DriveMapper", "drive_moving", "drive_nll", "drive_terms"]


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


def drive_terms(drive: Any, moving: np.ndarray, imf: Any) -> np.ndarray:
    """The innovation NLL of each of one drive's scored fixes under the in-motion filter ``imf``, in time order
    (NaN where a fix has none); ``[inf]`` when the filter fails under it: a θ that makes the filter diverge
    explains nothing."""
    try:
        r = run_ekf(drive.imu, drive.gnss, drive.init, drive.ekf_config(), in_motion=imf, moving=moving,
                    with_nll=True)
    except (DataError, np.linalg.LinAlgError):
        return np.array([math.inf])
    t_after = (getattr(drive, "extra", None) or {}).get("score_after_s", -math.inf)
    return np.asarray(r.gnss_nll[np.asarray(r.gnss_t) >= t_after], dtype=float)


def drive_nll(drive: Any, moving: np.ndarray, imf: Any) -> float:
    """The innovation NLL of one drive's scored fixes under the in-motion filter ``imf`` (the sum of
    :func:`drive_terms`; inf when the filter fails under it)."""
    return float(np.nansum(drive_terms(drive, moving, imf)))


DriveMapper = Callable[[Callable[[Any, np.ndarray, Any], Any], Sequence[Any], Sequence[np.ndarray], Any],
                       Sequence[Any]]
"""``mapper(fn, drives, moving, imf)`` → per drive ``fn(drive, moving, imf)`` (:func:`drive_terms`), in drive
order."""


@dataclass
class DriveLikelihood:
    """The pooled NLL of the GNSS fixes of ``drives`` (module docstring) under the static filter ``models`` (the
    six models of the door, each with its rate) plus an in-motion :class:`Theta`; ``nll(theta)`` and the per-fix
    terms behind it (``terms(theta)``) are cached. ``mapper`` (a :data:`DriveMapper`): where the drives' runs go
    (default: one after the other, here)."""

    drives: Sequence[Any]
    models: list
    mapper: DriveMapper | None = None
    cache: dict = field(default_factory=dict)
    term_cache: dict = field(default_factory=dict)
    runs: int = 0
    cpu_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.drives:
            raise DataError("the in-motion estimate needs at least one drive with GNSS")
        self.moving = [drive_moving(d) for d in self.drives]

    @property
    def pairs(self) -> list:
        """Deprecated name of :attr:`models` (they are models with their rate, not pairs)."""
        import warnings

        warnings.warn("DriveLikelihood.pairs is renamed .models (the six filter models, not pairs); the old name "
                      "goes in the next release", DeprecationWarning, stacklevel=2)
        return self.models

    def nll(self, theta: Theta) -> float:
        """Σ over drives and fixes of the innovation NLL (inf when a run fails)."""
        k = theta.key()
        if k in self.cache:
            return self.cache[k]
        t0 = time.process_time()
        imf = in_motion_filter(self.models, theta.white, theta.sigma, theta.tau_s)
        if self.mapper is None:  # lazily: the runs stop at the first drive that fails
            per = (drive_terms(d, mv, imf) for d, mv in zip(self.drives, self.moving, strict=True))
        else:
            per = self.mapper(drive_terms, self.drives, self.moving, imf)
        total = 0.0
        terms = []
        for a in per:  # in drive order, whoever ran them
            x = float(np.nansum(a))
            terms.append(a)
            total += x
            if math.isinf(x):
                break
        self.runs += len(self.drives)
        self.cpu_s += time.process_time() - t0
        self.cache[k] = total
        self.term_cache[k] = terms
        return total

    def terms(self, theta: Theta) -> list[np.ndarray]:
        """Per drive the NLL of each scored fix under ``theta`` (:func:`drive_terms`; fewer drives when a run
        failed), from the same runs as :meth:`nll`."""
        self.nll(theta)
        return self.term_cache[theta.key()]

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
