"""Default IMU error models and the EKF configuration (docs/guide/theory.rst, 'Navigation filter', issue 4).

The "plain loosely coupled" default, used when nothing is known about the IMU, is per axis
``WN + RW + AR1`` (one first-order Gauss–Markov bias) built from datasheet-like continuous values:

* WN:  σ²_WN = N²·f            (N noise density, unit/√Hz; docs/guide/theory.rst, 'Latent processes' table)
* RW:  γ² = K²/f               (K rate random walk, unit/s/√Hz)
* AR1: φ = exp(−1/(f·T_c)), σ² = σ²_GM(1 − φ²)   (T_c correlation time, σ_GM stationary σ)

Parameters are per sample at the IMU rate ``f`` (docs/guide/theory.rst, 'Conventions'), so the result plugs into
``Model.state_space`` like a GMWM fit. The numbers of :func:`kfgins_loose` are those of the KF-GINS
reference run on the shared drive (its README): ARW 0.5 °/√h, VRW 0.5 m/s/√h, gyro bias σ 100 °/h,
accel bias σ 5000 mGal, correlation time 1 h.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.model import Model, as_model
from imunoise.noise.processes import AR1, RW, WN

DEG = math.pi / 180.0
DEG_PER_H = DEG / 3600.0  # °/h → rad/s
ARW_UNIT = DEG / 60.0  # °/√h → rad/s/√Hz
VRW_UNIT = 1.0 / 60.0  # m/s/√h → m/s²/√Hz
MGAL = 1e-5  # mGal → m/s²

__all__ = [
    "ImuSpec",
    "EkfConfig",
    "plain_default",
    "kfgins_loose",
    "default_axis_models",
    "load_axis_models",
    "normalize_axis_models",
    "DEG",
    "DEG_PER_H",
    "ARW_UNIT",
    "VRW_UNIT",
    "MGAL",
]


@dataclass(frozen=True)
class ImuSpec:
    """Datasheet-like continuous IMU error values in SI units (per sensor type, same on all axes).

    gyro: ``gyro_n`` noise density (rad/s/√Hz), ``gyro_k`` rate random walk (rad/s²/√Hz), ``gyro_sigma_gm``
    bias instability as Gauss–Markov σ (rad/s) with correlation time ``gyro_tau_s``; accel the same in
    m/s² units.
    """

    gyro_n: float = 0.5 * ARW_UNIT
    gyro_k: float = 0.5 * DEG_PER_H  # per √s: 0.5 °/h/√s, ~20 % of the GM's short-term K_eq
    gyro_sigma_gm: float = 100.0 * DEG_PER_H
    gyro_tau_s: float = 3600.0
    accel_n: float = 0.5 * VRW_UNIT
    accel_k: float = 2.5e-4
    accel_sigma_gm: float = 5000.0 * MGAL
    accel_tau_s: float = 3600.0

    def models(self, freq: float) -> tuple[Model, Model]:
        """(gyro model, accel model) with per-sample parameters at ``freq`` Hz, which they carry (module
        docstring)."""
        return (
            _wn_rw_gm(self.gyro_n, self.gyro_k, self.gyro_sigma_gm, self.gyro_tau_s, freq),
            _wn_rw_gm(self.accel_n, self.accel_k, self.accel_sigma_gm, self.accel_tau_s, freq),
        )


def _wn_rw_gm(n: float, k: float, sigma_gm: float, tau: float, freq: float) -> Model:
    """WN + RW + AR1 per sample at ``freq`` from continuous values (module docstring); zero terms dropped."""
    parts = []
    if sigma_gm > 0 and tau > 0:
        phi = math.exp(-1.0 / (freq * tau))
        parts.append(AR1(phi=phi, sigma2=sigma_gm**2 * (1.0 - phi * phi)))
    if n > 0:
        parts.append(WN(sigma2=n * n * freq))
    if k > 0:
        parts.append(RW(gamma2=k * k / freq))
    return Model(parts, freq)


def plain_default() -> ImuSpec:
    """The plain-LC default: KF-GINS' loose values plus a small rate random walk (WN + RW + GM)."""
    return ImuSpec()


def kfgins_loose() -> ImuSpec:
    """Exactly the KF-GINS reference settings of the shared drive (WN + GM, no RW)."""
    return ImuSpec(gyro_k=0.0, accel_k=0.0)


def default_axis_models(freq: float, spec: ImuSpec | None = None) -> list[Model]:
    """Six models at ``freq`` Hz (each carries the rate), gyro x/y/z then accel x/y/z, from ``spec`` (default
    :func:`plain_default`)."""
    g, a = (spec or plain_default()).models(freq)
    return [g] * 3 + [a] * 3


@dataclass(frozen=True)
class EkfConfig:
    """Settings of the loosely coupled EKF (docs/guide/theory.rst, 'Navigation filter'). SI units; angles in rad.

    ``cov_every``: propagate the covariance every this many IMU samples (always also right before a
    measurement update) with Φ = I + FT + ½(FT)² over the accumulated interval T; 1 reproduces KF-GINS'
    per-sample propagation. ``chi2_gate``: innovation NIS threshold (3 dof; 0 disables); after
    ``gate_max_reject`` consecutive rejections the next fix is accepted anyway, so the filter cannot lock
    itself out after a long outage; ``gate_abs_m`` is added (squared) to the innovation covariance of the
    gate test only, so innovations of that size are never called outliers. ``gate_q_scale`` and
    ``fallback`` define the conservative noise used while the docs/guide/theory.rst, 'Static detection' angular-rate
    gate is open. ``zupt_sigma`` (m/s) and ``zupt_every`` (samples) set the zero-velocity updates of the batch run when
    a static mask is given.

    ``aiding``: the optional measurements beside GNSS position and ZUPT, one settings object each (e.g.
    :class:`~imunoise.nav.measurements.nhc.NhcConfig`); the filter runs every one listed, in the batch and
    the step path alike. Empty (the default): the filter is the one without them.

    ``scale_factors`` adds six scale-factor error states (gyro x,y,z, accel x,y,z; dimensionless, the
    21-state filter of KF-GINS): the sensor model is ω̃ = (1 + s_g)ω + b_g, f̃ = (1 + s_a)f + b_a, the
    increments are compensated as (Δθ − b̂_g Δt)/(1 + ŝ_g). Each s is a first-order Gauss–Markov process
    with stationary σ ``gyro_scale_std``/``accel_scale_std`` and correlation time ``scale_tau_s``
    (``math.inf``: a random constant); the initial σ is the stationary σ. Defaults are KF-GINS' (its
    ``config/kf-gins.yaml``: gsstd = asstd = 1000 ppm, corrtime 1 h, init std = the noise std). Off (the
    default) the filter is bit-identical to the one without the option.
    """

    lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sigma_pos0: tuple[float, float, float] = (0.05, 0.05, 0.05)
    sigma_vel0: tuple[float, float, float] = (0.05, 0.05, 0.05)
    sigma_att0: tuple[float, float, float] = (0.5 * DEG, 0.5 * DEG, 3.0 * DEG)
    sigma_gyro_bias0: float = 50.0 * DEG_PER_H
    sigma_accel_bias0: float = 2500.0 * MGAL
    sigma_gyro_drift0: float = 1.0 * DEG_PER_H / 60.0
    sigma_accel_drift0: float = 1e-4
    cov_every: int = 5
    chi2_gate: float = 21.1  # χ²(3) at 99.99 %
    gate_abs_m: float = 0.5
    gate_max_reject: int = 4
    gnss_sigma_floor: float = 0.002
    gnss_sigma_nan: float = 10.0
    gate_q_scale: float = 10.0
    zupt_sigma: float = 0.02
    zupt_every: int = 10
    fallback: ImuSpec = field(default_factory=plain_default)
    scale_factors: bool = False
    gyro_scale_std: float = 1000e-6
    accel_scale_std: float = 1000e-6
    scale_tau_s: float = 3600.0
    aiding: tuple = ()

    def aid(self, kind: type):
        """The settings of ``kind`` in ``aiding``, or None when that measurement is off."""
        return next((a for a in self.aiding if isinstance(a, kind)), None)

    def with_(self, **kw) -> EkfConfig:
        """Copy with some fields replaced (lever arm as any 3-sequence)."""
        if "lever_arm" in kw:
            kw["lever_arm"] = tuple(float(x) for x in np.asarray(kw["lever_arm"], dtype=float).ravel())
        return replace(self, **kw)


_SI_UNITS = {"gyro": ("rad/s", "rad s^-1", "rad/s/sample"), "accel": ("m/s^2", "m/s²", "m/s2", "m s^-2")}


def _model_from_entry(entry: dict, sensor: str, where: str, freq_default: float) -> Model:
    from imunoise.errors import UnitError

    if not isinstance(entry, dict) or "model" not in entry:
        raise ModelError(f"{where}: expected a fit object with 'model' and 'params', got {type(entry).__name__}")
    unit = entry.get("unit")
    if isinstance(unit, str) and unit not in ("", "u", "unknown") and unit not in _SI_UNITS[sensor]:
        raise UnitError(
            f"{where}: parameters are in {unit!r}; the EKF needs SI ({_SI_UNITS[sensor][0]}). "
            "Refit with --units so the data are converted to SI"
        )
    model = Model.from_dict(entry)
    if not model.known:
        raise ModelError(f"{where}: model {model} has no parameter values")
    freq = float(entry.get("freq_hz", entry.get("rate_hz", freq_default)))
    model = model.with_freq(freq)
    scales = (entry.get("wv") or {}).get("scales") if isinstance(entry.get("wv"), dict) else None
    horizon = float(scales[-1]) if scales else None  # a fit file carries the WV it was fitted on
    # imported here: the door loads the equivalent-noise fit (scipy.optimize), which `nav` without a model file
    # never needs (tests/cli/test_cli_startup.py)
    from imunoise.nav.filter_model import AxisFit, filter_axis_models

    (mapped,) = filter_axis_models([AxisFit(model, freq, horizon)], freq, [None])
    return mapped


def load_axis_models(src, freq_default: float) -> list[Model]:
    """Six filter models (each carrying its rate) from a model JSON (path or parsed dict), each axis through the
    one door into the filter (:func:`imunoise.nav.filter_model.filter_axis_models`, without a floor; a fit file's
    WV gives the horizon): ``nav --imu-model`` and ``online --imu-model``.

    Accepted layouts: the multi-axis model file (``kind: imunoise.noise.imu_model`` with ``axes``),
    ``{"gyro": FIT, "accel": FIT}`` (one model per sensor), ``{"gyro": {"x": FIT, "y":
    FIT, "z": FIT}, ...}``, per-axis keys ``gyro_x``…``accel_z`` / ``gx``…``az`` (the simulator's truth
    JSON, also under its ``models`` key), or one FIT alone whose ``extra.column`` names its axis (``imunoise
    fit --column gyro_x``; the other five axes get the plain default). FIT is what ``imunoise fit`` writes
    (``model``, ``params``, ``freq_hz``, ``unit``); parameters per sample at ``freq_hz`` in SI units. A
    sensor that is missing gets the plain default (logged). The file is read and its layout parsed by
    :func:`imunoise.noise.imu_model.axis_fit_dicts`; this function checks SI units and fills the defaults.
    """
    import logging

    from imunoise.imu import AXES
    from imunoise.noise.imu_model import axis_fit_dicts

    where = "model JSON" if isinstance(src, dict) else str(src)
    entries = axis_fit_dicts(src, where)  # every accepted layout, parsed in imunoise.noise.imu_model
    out: list[Model | None] = [None] * 6
    for a, axis in enumerate(AXES):
        if axis in entries:
            out[a] = _model_from_entry(entries[axis], "gyro" if a < 3 else "accel", f"{where}[{axis}]", freq_default)
    default = default_axis_models(freq_default)
    for a in range(6):
        if out[a] is None:
            logging.getLogger(__name__).warning("%s: no model for axis %d: using the plain default", where, a)
            out[a] = default[a]
    return out  # type: ignore[return-value]


def normalize_axis_models(axis_models, freq: float) -> list[Model]:
    """Six models (gyro x,y,z, accel x,y,z), each carrying the rate its parameters are per sample at.

    Accepted: ``None`` (the plain default at ``freq``, the IMU rate); a sequence of 6 models; a dict
    ``{"gyro": m | [mx, my, mz], "accel": ...}``. A model is an imunoise :class:`Model` with its rate
    (``freq``: set by the fits and model files, or stated with ``model.with_freq(rate_hz)``); one without a rate
    is refused (its parameters are per sample at a rate only its fit knows). Deprecated, for one release: a
    (model, freq) pair in place of a model (a DeprecationWarning; ``freq`` 0 or None: the IMU rate).
    """
    if axis_models is None:
        return default_axis_models(freq)

    if isinstance(axis_models, dict):
        out = []
        for sensor in ("gyro", "accel"):
            if sensor not in axis_models:
                raise ModelError(f"axis models need a '{sensor}' entry (one model or three)")
            m = axis_models[sensor]
            ms = list(m) if isinstance(m, list | np.ndarray) else [m] * 3
            if len(ms) != 3:
                raise ModelError(f"'{sensor}' needs one model or three (x, y, z), got {len(ms)}")
            out += [_rated(x, freq) for x in ms]
        models = out
    else:
        models = [_rated(m, freq) for m in axis_models]
    if len(models) != 6:
        raise ModelError(f"need 6 axis models (gyro x,y,z, accel x,y,z), got {len(models)}")
    return models


def _rated(m, freq: float):
    """One axis' model with its rate (:func:`normalize_axis_models`): a model as it is, a pair (deprecated) as
    its model stating the pair's rate."""
    if isinstance(m, tuple) and len(m) == 2:
        warnings.warn(
            "(model, freq) pairs for the filter are deprecated and will be refused in the next release: a model "
            "carries its rate; pass the model (fits and model files set it) or model.with_freq(rate_hz)",
            DeprecationWarning, stacklevel=4,
        )
        m, f = as_model(m[0]), float(m[1] if m[1] else freq)
        return m.with_freq(m.sample_rate(f, "the filter"))
    if not isinstance(m, Model):
        raise ModelError(f"axis model {m!r} is not an imunoise Model; pass e.g. "
                         "(WN(sigma2=...) + RW(gamma2=...)).with_freq(rate_hz)")
    m.sample_rate(None, "the filter")  # refused without a rate, with the fix
    return m
