"""Multi-axis IMU model file (docs/guide/theory.rst, 'Interfaces'): one GMWM fit per axis, the input of ``imunoise
export`` and ``imunoise nav --model``.

JSON layout::

    {"kind": "imunoise.noise.imu_model", "imunoise_version": "...", "freq_hz": f,
     "axes": {"gyro_x": <GMWMFit.to_dict()>, ..., "accel_z": <GMWMFit.to_dict()>},
     "source": {...}, "in_motion": {...}}

``in_motion`` (optional): the noise while moving (:mod:`imunoise.noise.in_motion`); a file without it is the
static model alone and reads, writes and navigates exactly as before.

The per-axis dicts are exactly :meth:`imunoise.noise.estimator.GMWMFit.to_dict` output (discrete and continuous
parameters with units, rate, data span, WV), so any reader of single-axis fits reads them.

This module is the one reader and writer of model files: :meth:`ImuModel.save`/:meth:`ImuModel.load`,
:func:`load_model` (a multi-axis model or a one-axis fit), :func:`parse_model` (the same from parsed JSON,
plus a bare model dict) and :func:`axis_fit_dicts` (the per-axis entries of every layout ``imunoise nav
--model`` accepts, including the simulator's truth.json). Axis names are :data:`imunoise.imu.AXES`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise._version import __version__
from imunoise.errors import DataError, ModelError
from imunoise.imu import AXES, canonical_axis
from imunoise.io.atomic import atomic_write_text
from imunoise.io.files import read_json
from imunoise.io.imu_input import sensor_of
from imunoise.io.jsonutil import json_default
from imunoise.noise.estimator import GMWMFit, gmwm
from imunoise.noise.model import Model

__all__ = [
    "KIND",
    "FIT_KIND",
    "ImuModel",
    "load_model",
    "read_model_json",
    "parse_model",
    "axis_fit_dicts",
    "fit_axis",
    "fit_axis_wv",
]

KIND = "imunoise.noise.imu_model"
FIT_KIND = "imunoise.fit"  # a one-axis fit (GMWMFit.to_dict)


@dataclass(eq=False)
class ImuModel:
    """Per-axis fits (as ``GMWMFit.to_dict()`` dicts) at one sample rate ``freq_hz``."""

    freq_hz: float
    axes: dict[str, dict[str, Any]]
    source: dict[str, Any] = field(default_factory=dict)
    in_motion: dict[str, Any] | None = None  # the in-motion part (imunoise.noise.in_motion); None: static only

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
        d = {
            "kind": KIND,
            "imunoise_version": __version__,
            "freq_hz": self.freq_hz,
            "axes": self.axes,
            "source": self.source,
        }
        if self.in_motion is not None:  # absent key: the file of a static model is unchanged
            d["in_motion"] = self.in_motion
        return d

    def in_motion_part(self):
        """The in-motion part as an :class:`~imunoise.noise.in_motion.InMotionPart`, or None."""
        from imunoise.noise.in_motion import InMotionPart

        return None if self.in_motion is None else InMotionPart.from_dict(self.in_motion)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ImuModel:
        if d.get("kind") != KIND:
            raise ModelError(f"not an imunoise IMU model (kind {d.get('kind')!r}, expected {KIND!r})")
        axes = dict(d["axes"])
        for a, fd in axes.items():
            if fd.get("kind") != FIT_KIND:
                raise ModelError(f"axis {a!r} is not an imunoise fit dict")
        im = d.get("in_motion")
        if im is not None:
            from imunoise.noise.in_motion import InMotionPart

            im = InMotionPart.from_dict(im).to_dict()  # checked and normalised
        return cls(float(d["freq_hz"]), axes, dict(d.get("source", {})), im)

    def save(self, path: str | Path) -> Path:
        """Write the model file (atomically: complete or not at all); returns ``path``."""
        path = Path(path)
        atomic_write_text(path, json.dumps(self.to_dict(), indent=1, default=json_default))
        return path

    @classmethod
    def load(cls, path: str | Path) -> ImuModel:
        return cls.from_dict(read_model_json(path))


def read_model_json(path: str | Path, what: str = "model file") -> Any:
    """The parsed JSON of a model file; a missing, binary or malformed file raises one :class:`ModelError`
    naming it (:func:`imunoise.io.files.read_json`)."""
    return read_json(path, what, error=ModelError)


def parse_model(d: Any, where: str = "model JSON") -> ImuModel | GMWMFit | Model:
    """What a parsed model JSON holds: ``kind: imunoise.noise.imu_model`` → :class:`ImuModel`; ``kind: imunoise.fit``
    → :class:`GMWMFit`; a bare model dict ``{"model": ..., "params": ...}`` (:meth:`Model.to_dict`) →
    :class:`Model`.

    Parameters
    ----------
    d : Any
        Parsed JSON.
    where : str
        The file or option it came from, for the messages.

    Returns
    -------
    ImuModel or GMWMFit or Model
    """
    if not isinstance(d, Mapping):
        raise ModelError(f"{where}: expected a model or fit JSON object, got {type(d).__name__}")
    kind = d.get("kind")
    if kind == KIND:
        return ImuModel.from_dict(d)
    if kind == FIT_KIND:
        return GMWMFit.from_dict(d)
    return Model.from_dict(dict(d))


def load_model(path: str | Path) -> ImuModel | GMWMFit:
    """A multi-axis :class:`ImuModel` or a single-axis :class:`GMWMFit`, whichever the file holds."""
    path = Path(path)
    d = read_model_json(path)
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind not in (KIND, FIT_KIND):
        raise ModelError(
            f"{path} is neither an imunoise fit ('{FIT_KIND}') nor an IMU model ('{KIND}'); kind = {kind!r}"
        )
    return parse_model(d, str(path))  # type: ignore[return-value]


def _single_fit_axis(fit: Mapping[str, Any], where: str) -> str:
    """Axis (gyro_x … accel_z) of a one-axis fit JSON, from the column it was fitted on, or a ModelError
    that says which file the EKF needs instead."""
    column = str((fit.get("extra") or {}).get("column", ""))
    axis = canonical_axis(column)
    if axis is not None:
        return axis
    raise ModelError(
        f"{where} is a one-axis fit of column {column or '?'!r}, which names no IMU axis. The EKF needs a model "
        "per axis: fit the six columns at once (`imunoise fit FILE --columns gyro_x=COL,...,accel_z=COL "
        "--out DIR`, then --model DIR/imu_model.json), or fit a column named gyro_x … accel_z "
        "(`--column gyro_x`); axes without a model get the plain default"
    )


def axis_fit_dicts(src: str | Path | Mapping[str, Any], where: str | None = None) -> dict[str, Any]:
    """The per-axis fit/model dicts of a model JSON (path or parsed), keyed by :data:`imunoise.imu.AXES`
    names, in that order; axes the file does not give are absent.

    Accepted layouts: the multi-axis model file (``kind: imunoise.noise.imu_model`` with ``axes``); ``{"gyro": FIT,
    "accel": FIT}`` (one entry per sensor); ``{"gyro": {"x": FIT, "y": FIT, "z": FIT}, ...}``; per-axis keys
    ``gyro_x``…``accel_z`` or the short ``gx``…``az`` (the simulator's truth.json, also under its ``models``
    key, or under ``imu_models``); one FIT alone (``kind: imunoise.fit``) whose ``extra.column`` names its
    axis. Later keys override earlier ones; keys naming no axis are ignored. The entries are returned as
    they are (the caller checks units and parameters).

    Parameters
    ----------
    src : str, Path or Mapping
        A model JSON file or its parsed content.
    where : str, optional
        Name for the messages (default: the path, or "model JSON").

    Returns
    -------
    dict
        ``{axis: entry}``.
    """
    if not isinstance(src, Mapping):
        where = where or str(src)
        src = read_model_json(src)
    where = where or "model JSON"
    if not isinstance(src, Mapping):
        raise ModelError(f"{where}: expected a JSON object with IMU axis models, got {type(src).__name__}")
    for wrapper in ("imu_models", "models"):  # "models": the simulator's truth.json
        if isinstance(src.get(wrapper), Mapping):
            src = src[wrapper]
            break
    if src.get("kind") == KIND and isinstance(src.get("axes"), Mapping):
        src = src["axes"]  # the multi-axis file of `imunoise fit --columns` / ImuModel.save
    elif src.get("kind") == FIT_KIND:
        src = {_single_fit_axis(src, where): src}  # one axis of `imunoise fit --column gyro_x`
    found: dict[str, Any] = {}
    for key, val in src.items():
        k = str(key).lower()
        if k in ("gyro", "accel"):
            axes = AXES[:3] if k == "gyro" else AXES[3:]
            if isinstance(val, Mapping) and "model" not in val:
                for ax, axis in zip("xyz", axes, strict=True):
                    if ax not in val:
                        raise ModelError(f"{where}: '{key}' needs 'x', 'y', 'z' entries or one fit object")
                    found[axis] = val[ax]
            else:
                for axis in axes:
                    found[axis] = val
        elif (axis := canonical_axis(k)) is not None:
            found[axis] = val
    if not found:
        raise ModelError(f"{where}: no IMU axis models found; expected keys 'gyro'/'accel' or gyro_x..accel_z")
    return {a: found[a] for a in AXES if a in found}


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
    """GMWM fit of one axis: ``model`` given (paper Eq. 6), or ``auto`` model selection
    (docs/guide/theory.rst, 'Model selection'). Returns (fit, ranking or None)."""
    if (model is None) == (not auto):
        raise ModelError("give exactly one of a model structure or auto selection")
    if auto:
        try:
            from imunoise.noise.selection import select_model
        except ImportError as exc:  # pragma: no cover - only before the selection module exists
            raise ModelError("automatic selection needs imunoise.noise.selection, which is not installed") from exc
        ranking = select_model(
            values, freq=freq, criterion=criterion, robust=robust, weights=weights, unit=unit, seed=seed
        )
        fit = ranking.best
        fit.unit = unit
        _store_data_allan(fit, values, freq)
        return fit, ranking
    if np.size(values) < 16:
        raise DataError(f"only {np.size(values)} samples; need a static recording")
    fit = gmwm(model, values, freq=freq, weights=weights, robust=robust, unit=unit, seed=seed)
    _store_data_allan(fit, values, freq)
    return fit, None


def fit_axis_wv(
    wv: Any,
    *,
    model: str | Model | None = None,
    auto: bool = False,
    criterion: str = "wvic",
    weights: str = "efficient",
    unit: str = "u",
    seed: int = 0,
    n_samples: int | None = None,
    values: np.ndarray | None = None,
) -> tuple[GMWMFit, Any]:
    """:func:`fit_axis` from a ready :class:`~imunoise.noise.wv.WaveletVariance` (e.g. of a log streamed through
    :class:`~imunoise.noise.wv_stream.WVStream`): the same GMWM (paper Eq. 6) or selection
    (docs/guide/theory.rst, 'Model selection') on the same ν̂
    and Ω. ``n_samples`` fills ``extra["data_span"]``; ``values``, when the series is at hand, adds its dense
    Allan curve (without it the exports read the octave curve 2ν²_j, :func:`imunoise.noise.allan.data_curve`)."""
    if (model is None) == (not auto):
        raise ModelError("give exactly one of a model structure or auto selection")
    if auto:
        from imunoise.noise.selection import select_model

        ranking = select_model(wv, freq=wv.freq, criterion=criterion, weights=weights, unit=unit, seed=seed)
        fit = ranking.best
        fit.unit = unit
    else:
        ranking = None
        fit = gmwm(model, wv, freq=wv.freq, weights=weights, unit=unit, seed=seed)
    if n_samples is not None:
        span = {"n_samples": int(n_samples), "n_segments": 1, "duration_s": int(n_samples) / float(wv.freq)}
        for f in ranking.fits if ranking is not None else [fit]:
            f.extra["data_span"] = dict(span)
    if values is not None:
        _store_data_allan(fit, values, wv.freq)
    return fit, ranking


def _store_data_allan(fit: GMWMFit, values: Any, freq: float) -> None:
    """Keep the data's dense Allan curve with the fit (``extra["data_allan"]``, ~60 points): the exported K is
    capped at its bound (:func:`imunoise.noise.allan.rw_bound`), and the octave WV alone can stop at half the longest
    averaging time with ≥ 3 degrees of freedom (N/8 samples on the dense grid; the octave grid's power of two
    below it, as low as N/16 — 655 s instead of 1226 s for 10^6 samples at 100 Hz)."""
    from imunoise.noise.allan import allan_variance, curve_to_dict

    fit.extra["data_allan"] = curve_to_dict(allan_variance(values, freq=freq, grid="dense"))
