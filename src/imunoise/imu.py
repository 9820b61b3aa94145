"""The IMU vocabulary shared by every module (docs/guide/theory.rst, 'Conventions'): axis names and the IMU sample
container.

``AXES`` is the one list of sensor axes, in the order used everywhere (filter states, model files, the
simulator's truth, readers): gyro x, y, z (rad/s), accelerometer x, y, z (m/s²), body FRD.
:class:`ImuData` holds IMU samples as increments (or rates). Older files and code name the axes
``gx, gy, gz, ax, ay, az`` (the simulator's truth.json before this vocabulary, the KF-GINS rate CSV
header); :func:`canonical_axis` maps either spelling to the one in ``AXES``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imunoise.errors import DataError

__all__ = ["AXES", "GYRO_AXES", "ACCEL_AXES", "LEGACY_AXES", "ImuData", "canonical_axis"]

AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
GYRO_AXES = AXES[:3]
ACCEL_AXES = AXES[3:]
LEGACY_AXES = dict(zip(("gx", "gy", "gz", "ax", "ay", "az"), AXES, strict=True))
"""Short names of older files (simulator truth.json, rate CSV) → the names in ``AXES``."""


def canonical_axis(name: str) -> str | None:
    """The ``AXES`` name of ``name`` (``"gyro_x"`` or the short ``"gx"``, any case); None if it names no axis."""
    low = str(name).lower()
    if low in AXES:
        return low
    return LEGACY_AXES.get(low)


def as_columns(name: str, a: np.ndarray, n: int, cols: int = 3) -> np.ndarray:
    """``a`` as a float (n, cols) array, or a :class:`DataError` naming the field and the shape it needs."""
    a = np.asarray(a, dtype=float)
    if a.shape != (n, cols):
        raise DataError(f"{name} must have shape ({n}, {cols}), got {a.shape}")
    return a


def as_time_column(t: np.ndarray) -> np.ndarray:
    """``t`` as a 1-D float array of time stamps [s], or a :class:`DataError`."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DataError(f"time must be a 1-D array, got shape {t.shape}")
    return t


def _step(t: np.ndarray) -> np.ndarray:
    """t[k] − t[k−1], the first entry being the median step (docs/guide/theory.rst, 'Conventions' increments
    convention)."""
    n = t.size
    if n < 2:
        return np.full(n, np.nan)
    d = np.diff(t)
    return np.concatenate(([np.median(d)], d))




@dataclass(frozen=True, eq=False)
class ImuData:
    """IMU samples in body FRD (docs/guide/theory.rst, 'Conventions').

    ``kind == "increments"`` (what every reader returns): ``dtheta`` [rad] and ``dv`` [m/s] are the
    increments over (t_{k-1}, t_k]. ``kind == "rates"``: the same fields hold rates [rad/s, m/s²];
    use :meth:`rates`, :meth:`increments` or :meth:`as_increments` to get either form regardless.
    """

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    kind: str = "increments"
    frame: str = "FRD"

    def __post_init__(self) -> None:
        t = as_time_column(self.t)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "dtheta", as_columns("dtheta", self.dtheta, t.size))
        object.__setattr__(self, "dv", as_columns("dv", self.dv, t.size))
        if self.kind not in ("increments", "rates"):
            raise DataError(f"ImuData.kind must be 'increments' or 'rates', got {self.kind!r}")

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> np.ndarray:
        """Sample intervals t[k] − t[k−1] in s; the first is the median interval."""
        return _step(self.t)

    @property
    def rate_hz(self) -> float:
        """Nominal sampling rate 1 / median(Δt) in Hz."""
        return float(1.0 / np.median(np.diff(self.t))) if self.t.size > 1 else float("nan")

    def rates(self) -> tuple[np.ndarray, np.ndarray]:
        """(gyro [rad/s], accel [m/s²]), each (n, 3): increments divided by Δt_k."""
        if self.kind == "rates":
            return self.dtheta, self.dv
        dt = self.dt[:, None]
        return self.dtheta / dt, self.dv / dt

    def increments(self) -> tuple[np.ndarray, np.ndarray]:
        """(Δθ [rad], Δv [m/s]), each (n, 3): rates multiplied by Δt_k when stored as rates."""
        if self.kind == "increments":
            return self.dtheta, self.dv
        dt = self.dt[:, None]
        return self.dtheta * dt, self.dv * dt

    def as_increments(self) -> ImuData:
        """The same samples with ``kind == "increments"``."""
        if self.kind == "increments":
            return self
        dth, dv = self.increments()
        return replace(self, dtheta=dth, dv=dv, kind="increments")

    def slice(self, t0: float, t1: float) -> ImuData:
        """Samples with t0 ≤ t ≤ t1."""
        m = (self.t >= t0) & (self.t <= t1)
        return replace(self, t=self.t[m], dtheta=self.dtheta[m], dv=self.dv[m])
