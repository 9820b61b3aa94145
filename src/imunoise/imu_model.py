"""Multi-axis IMU model file (SPEC §12): one GMWM fit per axis, the input of ``imunoise export`` and
``imunoise nav --model``.

JSON layout::

    {"kind": "imunoise.imu_model", "imunoise_version": "...", "freq_hz": f,
     "axes": {"gyro_x": <GMWMFit.to_dict()>, ..., "accel_z": <GMWMFit.to_dict()>},
     "source": {...}}

The per-axis dicts are exactly :meth:`imunoise.gmwm.GMWMFit.to_dict` output (discrete and continuous
parameters with units, rate, data span, WV), so any reader of single-axis fits reads them.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise import __version__
from imunoise.errors import DataError, ModelError
from imunoise.gmwm import GMWMFit, gmwm
from imunoise.io.imu_input import sensor_of
from imunoise.model import Model

__all__ = ["KIND", "ImuModel", "load_model", "fit_axis"]

KIND = "imunoise.imu_model"


@dataclass(eq=False)
class ImuModel:
    """Per-axis fits (as ``GMWMFit.to_dict()`` dicts) at one sample rate ``freq_hz``."""

    freq_hz: float
    axes: dict[str, dict[str, Any]]
    source: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_fits(cls, fits: Mapping[str, GMWMFit], source: dict[str, Any] | None = None) -> ImuModel:
        if not fits:
            raise ModelError("an IMU model needs at least one axis fit")
        freqs = {float(f.freq) for f in fits.values()}
        if len(freqs) != 1:
            raise ModelError(f"all axes must be fitted at one sample rate, got {sorted(freqs)} Hz")
        return cls(freqs.pop(), {a: f.to_dict() for a, f in fits.items()}, dict(source or {}))

    def fit(self, axis: str) -> GMWMFit:
        if axis not in self.axes:
            raise ModelError(f"no axis {axis!r} in this model; axes: {', '.join(self.axes)}")
        return GMWMFit.from_dict(self.axes[axis])

    def sensor_axes(self, sensor: str) -> list[str]:
        """Axes of ``"gyro"`` or ``"accel"`` (by name, else by unit)."""
        return [a for a, d in self.axes.items() if sensor_of(a, d.get("unit")) == sensor]

    def continuous(self) -> dict[str, dict[str, float]]:
        return {a: dict(d["continuous"]) for a, d in self.axes.items()}

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": KIND,
            "imunoise_version": __version__,
            "freq_hz": self.freq_hz,
            "axes": self.axes,
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ImuModel:
        if d.get("kind") != KIND:
            raise ModelError(f"not an imunoise IMU model (kind {d.get('kind')!r}, expected {KIND!r})")
        axes = dict(d["axes"])
        for a, fd in axes.items():
            if fd.get("kind") != "imunoise.fit":
                raise ModelError(f"axis {a!r} is not an imunoise fit dict")
        return cls(float(d["freq_hz"]), axes, dict(d.get("source", {})))

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path: str | Path) -> ImuModel:
        return cls.from_dict(json.loads(Path(path).read_text()))


def load_model(path: str | Path) -> ImuModel | GMWMFit:
    """A multi-axis :class:`ImuModel` or a single-axis :class:`GMWMFit`, whichever the file holds."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ModelError(f"{path} is not JSON: {exc}") from exc
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind == KIND:
        return ImuModel.from_dict(d)
    if kind == "imunoise.fit":
        return GMWMFit.from_dict(d)
    raise ModelError(f"{path} is neither an imunoise fit ('imunoise.fit') nor an IMU model ('{KIND}'); kind = {kind!r}")


def fit_axis(
    values: np.ndarray,
    *,
    freq: float,
    model: str | Model | None = None,
    auto: bool = False,
    criterion: str = "wvic",
    weights: str = "efficient",
    robust: bool = False,
    unit: str = "u",
    seed: int = 0,
) -> tuple[GMWMFit, Any]:
    """GMWM fit of one axis: ``model`` given (paper Eq. 6), or ``auto`` model selection (SPEC §5).
    Returns (fit, ranking or None)."""
    if (model is None) == (not auto):
        raise ModelError("give exactly one of a model structure or auto selection")
    if auto:
        try:
            from imunoise.selection import select_model
        except ImportError as exc:  # pragma: no cover - only before the selection module exists
            raise ModelError("automatic selection needs imunoise.selection, which is not installed") from exc
        ranking = select_model(
            values, freq=freq, criterion=criterion, robust=robust, weights=weights, unit=unit, seed=seed
        )
        fit = ranking.best
        fit.unit = unit
        return fit, ranking
    if np.size(values) < 16:
        raise DataError(f"only {np.size(values)} samples; need a static recording")
    fit = gmwm(model, values, freq=freq, weights=weights, robust=robust, unit=unit, seed=seed)
    return fit, None
