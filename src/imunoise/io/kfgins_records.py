"""The in-memory records of KF-GINS text files (GNSS fixes, the reference trajectory), shared by the reader
(:mod:`imunoise.io.kfgins`, which re-exports them) and the writers (:mod:`imunoise.io.kfgins_write`)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from imunoise.errors import DataError
from imunoise.imu import as_columns, as_time_column

__all__ = ["GnssData", "Reference"]


@dataclass(frozen=True, eq=False)
class GnssData:
    """GNSS position fixes: ``llh`` = [lat rad, lon rad, h m] (antenna), ``sigma_ned`` in m."""

    t: np.ndarray
    llh: np.ndarray
    sigma_ned: np.ndarray

    def __post_init__(self) -> None:
        t = as_time_column(self.t)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "llh", as_columns("llh", self.llh, t.size))
        object.__setattr__(self, "sigma_ned", as_columns("sigma_ned", self.sigma_ned, t.size))

    def __len__(self) -> int:
        return int(self.t.size)

    def _take(self, m: np.ndarray) -> GnssData:
        return replace(self, t=self.t[m], llh=self.llh[m], sigma_ned=self.sigma_ned[m])

    def slice(self, t0: float, t1: float) -> GnssData:
        """Epochs with t0 ≤ t ≤ t1."""
        return self._take((self.t >= t0) & (self.t <= t1))

    def without(self, windows: Iterable[tuple[float, float]]) -> GnssData:
        """Drop the epochs inside any outage window: start ≤ t < start + duration
        (docs/guide/theory.rst, 'Navigation filter')."""
        keep = np.ones(self.t.size, dtype=bool)
        for start, dur in windows:
            keep &= ~((self.t >= start) & (self.t < start + dur))
        return self._take(keep)


@dataclass(frozen=True, eq=False)
class Reference:
    """Reference (or result) trajectory: llh [rad, rad, m], vel_ned [m/s], euler (roll, pitch, yaw) [rad]
    (NaN when unknown), GPS ``week`` (0 when unknown)."""

    t: np.ndarray
    llh: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    week: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def __post_init__(self) -> None:
        t = as_time_column(self.t)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "llh", as_columns("llh", self.llh, t.size))
        object.__setattr__(self, "vel_ned", as_columns("vel_ned", self.vel_ned, t.size))
        object.__setattr__(self, "euler", as_columns("euler", self.euler, t.size))
        week = np.asarray(self.week)
        if week.size == 0 and t.size:
            week = np.zeros(t.size, dtype=int)
        elif week.ndim == 0:
            week = np.full(t.size, int(week), dtype=int)
        if week.shape != t.shape:
            raise DataError(f"week must have shape {t.shape}, got {week.shape}")
        object.__setattr__(self, "week", week.astype(int))

    def __len__(self) -> int:
        return int(self.t.size)

    def slice(self, t0: float, t1: float) -> Reference:
        """Epochs with t0 ≤ t ≤ t1."""
        m = (self.t >= t0) & (self.t <= t1)
        return replace(
            self,
            t=self.t[m],
            llh=self.llh[m],
            vel_ned=self.vel_ned[m],
            euler=self.euler[m],
            week=self.week[m],
        )
