"""Export a GMWM model to the noise parameters of VIO/INS stacks (SPEC §2, §12).

Kalibr ``imu.yaml``, OpenVINS ``kalibr_imu_chain.yaml`` and ORB-SLAM3 ``IMU.*`` all take two
*continuous-time* densities per sensor — white noise N [u/√Hz] and bias random walk K [u/s/√Hz] — and
discretise them with the update rate f = 1/Δt (σ_d = N·√f per sample, bias step K/√f).

The fitted model is mapped to (N, K) by what the filter will see (:mod:`imunoise.equivalent_noise`, the one
mapping shared with the online filter): the WN + RW pair whose Allan variance best matches the model's, in
log-variance least squares over averaging times from the update period Δt to a horizon (default: the longest
scale of the data the model was fitted on; ``horizon_s`` / ``--horizon S``), each line at or below the
model's AV as in an IEEE Allan reading (K over the whole range, N where the model falls like white noise; a
drift becomes the random walk with its AV at the horizon). Exact closed forms where they exist: WN → N =
σ·√Δt, RW → K = γ/√Δt, QN → white with its per-sample variance 2Q², an AR1 that decorrelates within one
update → white with its zero-frequency density σ/(1−φ)·√Δt (→ σ_GM·√(2T_c)). A Gauss–Markov term is white on
scales ≫ T_c and a random walk on scales ≪ T_c: a slow one (T_c ≫ horizon) goes to K, a fast one to N, and
one in between is neither — its Allan bump is what the pair cannot follow. K is never the Allan-variance
minimum (bias instability). K never exceeds the data's Allan bound min_τ AD(τ)·√(3/τ) over the points with
≥ 3 equivalent degrees of freedom (the densest curve the fit carries, :func:`imunoise.allan.data_curve`): a
fitted RW term that overshoots the data's long-τ AV is capped there, and the file says so beside K.

Beside each written pair: the τ range it was matched on and the worst ratio between the written pair's AV
and each axis model's AV there; a ratio above 2 is a warning (:attr:`SensorNoise.warnings`). Never a zero
or non-finite density: white noise not identified over the range → the largest white line under the
model's AV when the model has a process that decorrelates inside the range, else :class:`ModelError`;
random walk not identified (the model's AV does not rise) → half the largest RW under it, with a note.
Three axes of one sensor are combined by the maximum (default) or the root mean square.
Optional inflation factors (``white=2,rw=10``) multiply the written values and are shown beside them.
Every number is followed by its unit and the words continuous / discrete in a comment.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise._version import __version__
from imunoise.allan import data_curve
from imunoise.equivalent_noise import WARN_RATIO, Equivalent, default_horizon_s, equivalent_noise
from imunoise.errors import DataError, ModelError, UnitError
from imunoise.estimator import GMWMFit
from imunoise.imu_model import ImuModel, load_model
from imunoise.io.atomic import atomic_write_text
from imunoise.io.imu_input import sensor_of
from imunoise.units import quantity_of

__all__ = [
    "FORMATS",
    "DEFAULT_FILENAMES",
    "AxisNoise",
    "SensorNoise",
    "RULE",
    "axis_noise",
    "infer_sensor",
    "model_sensors",
    "sensor_noise",
    "parse_inflate",
    "export_text",
    "write_export",
    "update_into",
    "model_topic",
    "required_keys",
    "read_export",
    "format_float",
    "density_units",
]

FORMATS = ("kalibr", "openvins", "orbslam3", "json")
DEFAULT_FILENAMES = {
    "kalibr": "imu.yaml",
    "openvins": "kalibr_imu_chain.yaml",
    "orbslam3": "orbslam3_imu.yaml",
    "json": "imu_noise.json",
}
SENSORS = ("gyro", "accel")
_BASE_UNIT = {"gyro": "rad/s", "accel": "m/s^2"}
_SI_NAMES = {"gyro": ("rad/s",), "accel": ("m/s²", "m/s2", "m/s^2")}
_KALIBR_KEYS = {
    "gyro": ("gyroscope_noise_density", "gyroscope_random_walk"),
    "accel": ("accelerometer_noise_density", "accelerometer_random_walk"),
}
_ORB_KEYS = {"gyro": ("IMU.NoiseGyro", "IMU.GyroWalk"), "accel": ("IMU.NoiseAcc", "IMU.AccWalk")}


def density_units(sensor: str) -> tuple[str, str]:
    """(white-noise density unit, random-walk density unit) in ASCII for YAML files."""
    if sensor == "gyro":
        return "rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)"
    return "m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)"


def format_float(x: float) -> str:
    """Shortest scientific notation that reads back to the same float, always with a '.' and a signed
    exponent (``1.5e-04``), so that YAML 1.1 (PyYAML, Kalibr) and OpenCV (OpenVINS, ORB-SLAM3) both read
    a real number."""
    x = float(x)
    if not math.isfinite(x):
        raise ModelError(f"cannot export a non-finite value ({x})")
    for p in range(1, 18):
        s = f"{x:.{p}e}"
        if float(s) == x:
            return s
    return f"{x:.17e}"


# ----------------------------------------------------------------------------------------------
# per-axis and per-sensor noise values
# ----------------------------------------------------------------------------------------------
NOT_IDENTIFIED = 1e-9  # a matched N² or K² below this fraction of its cap sits at the bound 0
RULE = (
    "WN+RW pair whose Allan variance best matches the model's (log-variance least squares, each line at or "
    "below the model's AV) over tau = update period .. horizon; WN, RW, QN (2Q^2) and AR1s faster than one "
    "update (sigma/(1-phi)*sqrt(dt)) by exact closed forms; K capped at the data's Allan bound min AD*sqrt(3/tau) "
    "over points with >= 3 dof"
)


@dataclass(frozen=True)
class AxisNoise:
    """Continuous-time pair of one axis (module docstring): ``N`` [u/√Hz], ``K`` [u/s/√Hz], ``K_rw`` the
    fitted RW term alone, ``equivalent`` the matching with its τ range, worst AV ratio and routes."""

    axis: str
    model: str
    unit: str
    freq_hz: float
    N: float
    K: float
    K_rw: float
    equivalent: Equivalent
    rate_ramp: float | None = None
    notes: tuple[str, ...] = ()

    @property
    def K_eq(self) -> float:
        """The random-walk density written (alias of ``K``)."""
        return self.K

    @property
    def tau_range_s(self) -> tuple[float, float] | None:
        return self.equivalent.tau_range_s

    @property
    def worst_ratio(self) -> float:
        return self.equivalent.worst_ratio


def _as_fit(fit: GMWMFit | Mapping[str, Any]) -> GMWMFit:
    return fit if isinstance(fit, GMWMFit) else GMWMFit.from_dict(dict(fit))


def axis_noise(fit: GMWMFit | Mapping[str, Any], axis: str = "", *, horizon_s: float | None = None) -> AxisNoise:
    """Exportable continuous-time (N, K) of one fitted axis (module docstring; SPEC §12).

    Parameters
    ----------
    fit
        A :class:`GMWMFit` or its ``to_dict()``.
    axis
        Name used in messages.
    horizon_s
        Longest averaging time matched on [s]; default :func:`imunoise.equivalent_noise.default_horizon_s`.

    Returns
    -------
    AxisNoise
        Never a zero or non-finite density; raises :class:`ModelError` when no white noise can be given.
    """
    fit = _as_fit(fit)
    f = float(fit.freq)
    name = axis or "the fit"
    h = default_horizon_s(fit) if horizon_s is None else float(horizon_s)
    eq = equivalent_noise(fit.model, f, horizon_s=h, data_av=data_curve(fit))
    notes = []
    s2, g2 = eq.sigma2, eq.gamma2
    if not s2 > NOT_IDENTIFIED * eq.sigma2_cap:
        tcs = [tc for c in fit.model.components if (tc := c.correlation_time(f)) is not None]
        if any(tc < h for tc in tcs) and eq.sigma2_cap > 0:
            s2 = eq.sigma2_cap
            notes.append(f"{name}: no white noise identified; N = the largest white line under the model's AV "
                         "(from its AR1 that decorrelates inside the range)")
        else:
            raise ModelError(
                f"{name}: model {fit.model} has no white-noise-like process between {1 / f:g} s and the horizon "
                f"{h:g} s (its Allan variance never falls), so no white-noise density can be exported; fit a "
                "model with WN (e.g. --model \"AR1+WN+RW\") or check the data"
            )
    if not g2 > NOT_IDENTIFIED * eq.gamma2_cap:
        if not eq.gamma2_cap > 0:
            raise ModelError(f"{name}: no random walk can be derived from model {fit.model}")
        g2 = 0.5 * eq.gamma2_cap
        notes.append(f"{name}: model {fit.model} shows no random walk up to {h:g} s; K = half the largest random "
                     "walk under its AV (an upper-bound reading, not a fitted value)")
    if (s2, g2) != (eq.sigma2, eq.gamma2):
        eq = eq.with_pair(s2, g2)
    N, K = eq.N, eq.K
    if not (math.isfinite(N) and math.isfinite(K) and N > 0 and K > 0):
        raise ModelError(f"{name}: the equivalent densities are not positive and finite (N={N}, K={K})")
    rw = [c.values[0] for c in fit.model.components if c.reading == "random_walk"]
    ramp = next((c.values[0] * f for c in fit.model.components if c.reading == "ramp"), None)
    if ramp is not None:
        notes.append(f"{name}: drift (rate ramp {ramp:.4g} {fit.unit}/s) has no slot; matched from below by K")
    if fit.model.has("QN"):
        notes.append(f"{name}: QN folded into the white-noise density as per-sample variance 2Q^2")
    return AxisNoise(
        axis=axis,
        model=str(fit.model),
        unit=fit.unit,
        freq_hz=f,
        N=N,
        K=K,
        K_rw=math.sqrt(rw[0] * f) if rw else 0.0,
        equivalent=eq,
        rate_ramp=ramp,
        notes=tuple(notes),
    )


@dataclass(frozen=True)
class SensorNoise:
    """What goes into the files for one sensor: ``noise_density`` and ``random_walk`` (continuous, after
    inflation), ``raw_*`` before inflation, the per-axis values, how they were combined; ``tau_range_s``
    the averaging times matched on, ``worst_ratio`` the worst factor between the written (raw) pair's AV
    and any axis model's there (``worst_axis``, ``worst_at_s``, ``worst_over``: pair above the model)."""

    sensor: str
    freq_hz: float
    noise_density: float
    random_walk: float
    raw_noise_density: float
    raw_random_walk: float
    inflate_white: float
    inflate_rw: float
    combine: str
    axes: tuple[AxisNoise, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    tau_range_s: tuple[float, float] | None = None
    worst_ratio: float = 1.0
    worst_axis: str = ""
    worst_at_s: float = math.nan
    worst_over: bool = False

    @property
    def discrete_sigma(self) -> float:
        """Per-sample white-noise σ at the update rate: N·√f (unit of the sensor)."""
        return self.noise_density * math.sqrt(self.freq_hz)

    @property
    def discrete_bias_step(self) -> float:
        """Per-sample σ of the bias increment at the update rate: K/√f (unit of the sensor)."""
        return self.random_walk / math.sqrt(self.freq_hz)

    @property
    def warnings(self) -> tuple[str, ...]:
        """One line when the written pair's AV is off an axis model's by more than ``WARN_RATIO``."""
        if not self.worst_ratio > WARN_RATIO:
            return ()
        side = "above" if self.worst_over else "below"
        return (
            f"{self.sensor}: the exported pair's Allan variance is {self.worst_ratio:.3g}x {side} the fitted model of "
            f"{self.worst_axis} at tau = {self.worst_at_s:.4g} s (matched on {_range_text(self.tau_range_s)}"
            + (f"; the pair written is the {self.combine} over {len(self.axes)} axes" if len(self.axes) > 1 else "")
            + "): a white-noise + random-walk pair cannot follow that model there; see the routes per axis",
        )

    def match_text(self) -> str:
        """The comment written beside the pair."""
        side = "above" if self.worst_over else "below"
        at = f", pair {side} the {self.worst_axis} model at {self.worst_at_s:.4g} s" if self.worst_ratio > 1.0 else ""
        return (f"matched on tau = {_range_text(self.tau_range_s)}; worst AV ratio exported/model = "
                f"{self.worst_ratio:.3g}{at}{' (> 2: WARNING)' if self.worst_ratio > WARN_RATIO else ''}")

    def to_dict(self) -> dict[str, Any]:
        n_unit, k_unit = density_units(self.sensor)
        return {
            "noise_density": self.noise_density,
            "noise_density_unit": n_unit,
            "random_walk": self.random_walk,
            "random_walk_unit": k_unit,
            "kind": "continuous-time densities",
            "discrete_sigma_per_sample": self.discrete_sigma,
            "discrete_bias_step_per_sample": self.discrete_bias_step,
            "discrete_unit": _BASE_UNIT[self.sensor],
            "update_rate_hz": self.freq_hz,
            "fit_noise_density": self.raw_noise_density,
            "fit_random_walk": self.raw_random_walk,
            "inflate": {"white": self.inflate_white, "rw": self.inflate_rw},
            "combine": self.combine,
            "rule": RULE,
            "tau_range_s": list(self.tau_range_s) if self.tau_range_s else None,
            "worst_av_ratio": self.worst_ratio,
            "worst_av_ratio_axis": self.worst_axis,
            "worst_av_ratio_at_s": self.worst_at_s,
            "worst_av_ratio_pair_above": self.worst_over,
            "axes": {
                a.axis: {
                    "model": a.model,
                    "N": a.N,
                    "K": a.K,
                    "K_rw": a.K_rw,
                    "tau_range_s": list(a.tau_range_s) if a.tau_range_s else None,
                    "worst_av_ratio": a.worst_ratio,
                    "K_model": a.equivalent.K_model,
                    "K_data": a.equivalent.K_data,
                    "K_data_at_s": a.equivalent.K_data_at_s,
                    "K_capped_at_data": a.equivalent.capped,
                    "routes": [{"process": r.process, "slot": r.slot, "how": r.how} for r in a.equivalent.routes],
                }
                for a in self.axes
            },
            "notes": list(self.notes),
        }


def _range_text(r: tuple[float, float] | None) -> str:
    return "n/a" if r is None else f"{r[0]:.4g}..{r[1]:.4g} s"


def _check_unit(sensor: str, axes: list[AxisNoise]) -> list[str]:
    notes = []
    for a in axes:
        if a.unit in _SI_NAMES[sensor]:
            continue
        if a.unit in ("u", ""):
            notes.append(
                f"{a.axis or 'the fit'}: data unit not recorded (fit without --units); assumed {_BASE_UNIT[sensor]}"
            )
            continue
        raise UnitError(
            f"{a.axis or 'the fit'} is in {a.unit!r}, but a {sensor} export needs {_SI_NAMES[sensor][0]}: "
            "refit with --units so the data are converted to SI"
        )
    return notes


def infer_sensor(fit: GMWMFit | Mapping[str, Any]) -> str | None:
    """``"gyro"`` or ``"accel"`` of a single-axis fit from its unit (rad/s, deg/s, … → gyro; m/s², g, … →
    accel; the SI unit, else the unit of the source data) or else its column name; None when neither says.

    Parameters
    ----------
    fit : GMWMFit or mapping
        A fit or its ``to_dict()``.

    Returns
    -------
    str or None
    """
    d = fit.to_dict() if isinstance(fit, GMWMFit) else dict(fit)
    extra = d.get("extra") or {}
    for unit in (d.get("unit"), extra.get("source_unit")):
        if not unit or unit in ("u", "1"):
            continue
        try:
            q = quantity_of(str(unit))
        except UnitError:
            continue
        if q in ("rate", "angle_increment"):
            return "gyro"
        if q in ("accel", "velocity_increment"):
            return "accel"
    return sensor_of(str(extra.get("column") or ""), None)


def sensor_noise(
    model: ImuModel | GMWMFit,
    sensor: str,
    *,
    combine: str = "max",
    inflate: Mapping[str, float] | None = None,
    horizon_s: float | None = None,
) -> SensorNoise:
    """Combined continuous-time values of one sensor (``"gyro"`` or ``"accel"``) of a multi-axis model,
    or of a single-axis fit (then ``sensor`` says which sensor it is). ``horizon_s``: see :func:`axis_noise`.

    Parameters
    ----------
    model : ImuModel or GMWMFit
        A multi-axis model or a single-axis fit.
    sensor : {"gyro", "accel"}
        Which sensor.
    combine : {"max", "rms"}
        How the three axes' values are combined.
    inflate : mapping, optional
        Factors ``{"white": w, "rw": r}`` (> 0) applied to N and K (default 1).
    horizon_s : float, optional
        Longest averaging time matched on [s] (default: the data's).

    Returns
    -------
    SensorNoise

    Raises
    ------
    ModelError
        For an unknown sensor or combination, a factor ≤ 0 or a model without that sensor.
    """
    if sensor not in SENSORS:
        raise ModelError(f"sensor must be 'gyro' or 'accel', got {sensor!r}")
    if combine not in ("max", "rms"):
        raise ModelError(f"combine must be 'max' or 'rms', got {combine!r}")
    inflate = dict(inflate or {})
    w, r = float(inflate.get("white", 1.0)), float(inflate.get("rw", 1.0))
    if not (w > 0 and r > 0):
        raise ModelError(f"inflation factors must be > 0, got white={w}, rw={r}")
    if isinstance(model, ImuModel):
        names = model.sensor_axes(sensor)
        if not names:
            raise ModelError(
                f"the model has no {sensor} axis (axes: {', '.join(model.axes)}); name the columns "
                f"{sensor}_x/_y/_z or fit with SI units"
            )
        axes = [axis_noise(model.axes[a], a, horizon_s=horizon_s) for a in names]
    else:
        axes = [axis_noise(model, str(model.extra.get("column") or sensor), horizon_s=horizon_s)]
    notes = _check_unit(sensor, axes)
    Ns = np.array([a.N for a in axes])
    Ks = np.array([a.K for a in axes])
    if combine == "max":
        n_raw, k_raw = float(Ns.max()), float(Ks.max())
    else:
        n_raw, k_raw = float(np.sqrt(np.mean(Ns**2))), float(np.sqrt(np.mean(Ks**2)))
    worst = (1.0, "", math.nan, False)
    for a in axes:
        notes += list(a.notes)
        ratio, at, over = a.equivalent.mismatch(n_raw, k_raw)
        if ratio > worst[0]:
            worst = (ratio, a.axis, at, over)
    ranges = [a.tau_range_s for a in axes if a.tau_range_s]
    tau_range = (min(x[0] for x in ranges), max(x[1] for x in ranges)) if ranges else None
    return SensorNoise(
        sensor=sensor,
        freq_hz=axes[0].freq_hz,
        noise_density=n_raw * w,
        random_walk=k_raw * r,
        raw_noise_density=n_raw,
        raw_random_walk=k_raw,
        inflate_white=w,
        inflate_rw=r,
        combine=combine,
        axes=tuple(axes),
        notes=tuple(notes),
        tau_range_s=tau_range,
        worst_ratio=worst[0],
        worst_axis=worst[1],
        worst_at_s=worst[2],
        worst_over=worst[3],
    )


def parse_inflate(text: str | None) -> dict[str, float]:
    """``"white=2,rw=10"`` -> {"white": 2.0, "rw": 10.0}.

    Parameters
    ----------
    text : str or None
        Comma-separated ``key=factor`` with keys ``white`` and ``rw``; empty or None: both 1.

    Returns
    -------
    dict
        ``{"white": w, "rw": r}``.

    Raises
    ------
    ModelError
        For an unknown key, a non-number or a factor ≤ 0.
    """
    out = {"white": 1.0, "rw": 1.0}
    if not text:
        return out
    for item in text.split(","):
        if "=" not in item:
            raise ModelError(f"--inflate {text!r}: use white=FACTOR,rw=FACTOR")
        k, v = (s.strip() for s in item.split("=", 1))
        if k not in out:
            raise ModelError(f"--inflate: unknown key {k!r}; use 'white' and/or 'rw'")
        try:
            out[k] = float(v)
        except ValueError as exc:
            raise ModelError(f"--inflate: {v!r} is not a number") from exc
        if not out[k] > 0:
            raise ModelError(f"--inflate {k}={v}: factors must be > 0")
    return out


# ----------------------------------------------------------------------------------------------
# text formats
# ----------------------------------------------------------------------------------------------
def model_sensors(model: ImuModel | GMWMFit, sensor: str | None, combine: str, inflate,
                  horizon_s: float | None = None) -> dict[str, SensorNoise]:
    """The exported (N, K) of every sensor a model holds.

    Parameters
    ----------
    model : ImuModel or GMWMFit
        A six-axis model, or one axis' fit (its sensor from ``sensor``, else from its unit or column name).
    sensor : {"gyro", "accel"} or None
        Needed only for a single-axis fit whose unit and column name do not say.
    combine : {"max", "rms"}
        How the three axes of a sensor are combined.
    inflate : mapping or None
        Visible inflation factors (:func:`parse_inflate`).
    horizon_s : float, optional
        Longest averaging time of the match [s] (default: the data's longest scale).

    Returns
    -------
    dict
        ``{"gyro": SensorNoise, "accel": SensorNoise}`` for the sensors present.
    """
    if isinstance(model, GMWMFit):
        sensor = sensor or infer_sensor(model)
        if sensor not in SENSORS:
            raise ModelError(
                "a single-axis fit whose unit and column name do not say gyro or accel needs --sensor gyro|accel"
            )
        return {sensor: sensor_noise(model, sensor, combine=combine, inflate=inflate, horizon_s=horizon_s)}
    out = {}
    for s in SENSORS:
        if model.sensor_axes(s) and sensor in (None, s):
            out[s] = sensor_noise(model, s, combine=combine, inflate=inflate, horizon_s=horizon_s)
    if not out:
        raise ModelError(f"no gyro or accel axes in the model (axes: {', '.join(model.axes)})")
    return out


def _value_comments(sn: SensorNoise) -> tuple[str, str]:
    n_unit, k_unit = density_units(sn.sensor)
    base = _BASE_UNIT[sn.sensor]
    axes = ",".join(a.axis for a in sn.axes)
    how = f"{sn.combine} over {axes}" if len(sn.axes) > 1 else axes
    n_c = f"[{n_unit}] continuous-time white-noise density N, matched ({how})"
    if sn.inflate_white != 1.0:
        n_c += f" = {format_float(sn.raw_noise_density)} (fit) x {sn.inflate_white:g} (--inflate white)"
    n_c += f"; discrete sigma per sample at {sn.freq_hz:g} Hz = {sn.discrete_sigma:.4e} {base}"
    k_c = f"[{k_unit}] continuous-time bias random walk K, matched ({how})"
    if sn.inflate_rw != 1.0:
        k_c += f" = {format_float(sn.raw_random_walk)} (fit) x {sn.inflate_rw:g} (--inflate rw)"
    capped = [a.axis for a in sn.axes if a.equivalent.capped]
    if capped:
        k_c += f"; capped at the data's Allan bound on {','.join(capped)} (per-axis lines above)"
    k_c += f"; discrete bias step per sample = {sn.discrete_bias_step:.4e} {base}"
    return n_c, k_c


def axis_lines(a: AxisNoise, prefix: str = "") -> list[str]:
    """Per axis: the pair, its τ range and worst AV ratio, and which process went where."""
    n_unit, k_unit = density_units(sensor_of(a.axis, a.unit) or "gyro")
    e = a.equivalent
    side = "above" if e.worst_over else "below"
    worst = f"{e.worst_ratio:.3g}" + (f" (pair {side} the model at {e.worst_at_s:.4g} s)" if e.worst_ratio > 1 else "")
    lines = [
        f"{prefix}{a.axis or 'axis'}: {a.model}: N={a.N:.6e} {n_unit}, K={a.K:.6e} {k_unit} "
        f"(fitted RW alone K_rw={a.K_rw:.6e}); matched on tau = {_range_text(e.tau_range_s)}, worst AV ratio {worst}"
    ]
    if e.capped:
        lines.append(f"{prefix}    {e.cap_text()}")
    lines += [f"{prefix}    {r.process} -> {r.slot}: {r.how}" for r in e.routes]
    return lines


def _header(model: ImuModel | GMWMFit, sensors: dict[str, SensorNoise], what: str, source: str | None) -> list[str]:
    lines = [
        f"# {what} written by imunoise {__version__} on {time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC"
        + (f" from {source}" if source else ""),
        "# The noise values are CONTINUOUS-TIME densities; the consumer discretises them with the update rate:",
        "#   per-sample white-noise sigma = N*sqrt(f), per-sample bias increment sigma = K/sqrt(f).",
        "# (N, K) = the white-noise + random-walk pair whose Allan variance best matches the fitted model's",
        "#   (log-variance least squares, each line at or below the model's AV) over tau = update period .. horizon.",
        "#   Exact: WN -> N = sigma*sqrt(dt), RW -> K = gamma/sqrt(dt), QN -> white 2Q^2 per sample, AR1 faster than",
        "#   one update -> white sigma/(1-phi)*sqrt(dt). A Gauss-Markov term is white on scales >> T_c and a random",
        "#   walk on scales << T_c, neither in between. K is NOT the Allan-variance minimum (bias instability).",
        "#   K never exceeds the data's Allan bound min AD(tau)*sqrt(3/tau) over points with >= 3 dof (capped where",
        "#   the fitted model's K is above it; said per axis below).",
        "# Per axis (continuous-time, before inflation):",
    ]
    for sn in sensors.values():
        for a in sn.axes:
            lines += axis_lines(a, "#   ")
        lines += [f"# note: {n}" for n in sn.notes]
        lines += [f"# WARNING: {w}" for w in sn.warnings]
    return lines


def _missing_lines(sensors: dict[str, SensorNoise], keys: dict[str, tuple[str, str]], indent: str = "") -> list[str]:
    out = []
    for s in SENSORS:
        if s not in sensors:
            for k in keys[s]:
                out.append(f"{indent}# {k}: not exported (the input model has no {s} axis)")
    return out


def _kalibr_lines(sensors: dict[str, SensorNoise], s: str, indent: str = "") -> list[str]:
    """Kalibr's noise density and random walk keys of sensor ``s``, each with its value comment, and the
    match note: the lines of Kalibr's imu.yaml and of OpenVINS's imu0 block (which reads Kalibr's keys)."""
    nk, kk = _KALIBR_KEYS[s]
    nc, kc = _value_comments(sensors[s])
    return [
        f"{indent}{nk}: {format_float(sensors[s].noise_density)}  # {nc}",
        f"{indent}{kk}: {format_float(sensors[s].random_walk)}  # {kc}",
        f"{indent}# {sensors[s].match_text()}",
    ]


# The OpenVINS >= v2.7 intrinsics, as OpenVINS' config/euroc_mav/kalibr_imu_chain.yaml writes them: nested
# sequences, which YamlParser::parse(.., Eigen::Matrix3d&) reads row by row as node[r][c] (an !!opencv-matrix
# map would not index so); identity = no intrinsic calibration, zero Tg = no gravity sensitivity.
_EYE3 = ("- [ 1.0, 0.0, 0.0 ]", "- [ 0.0, 1.0, 0.0 ]", "- [ 0.0, 0.0, 1.0 ]")
OPENVINS_INTRINSICS: dict[str, tuple[str, ...]] = {
    "Tw": _EYE3,
    "R_IMUtoGYRO": _EYE3,
    "Ta": _EYE3,
    "R_IMUtoACC": _EYE3,
    "Tg": ("- [ 0.0, 0.0, 0.0 ]",) * 3,
}
OPENVINS_VERSIONS = (
    "Read by OpenVINS v2.6 (imu0: the four noise densities, rostopic) and >= v2.7, which also requires model "
    "and the 3x3 Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg (identity / zero here: no IMU intrinsic calibration)."
)
ORBSLAM3_VERSIONS = (
    'ORB-SLAM3 v1.0 settings (File.version: "1.0") read IMU.Frequency as a real; legacy settings (no File.version, '
    "ORB-SLAM3 <= 0.4) need an integer (imunoise export --legacy, or --into detects it)."
)


def model_topic(model: ImuModel | GMWMFit) -> str | None:
    """The ROS topic of the bag the model's data came from, as recorded in its metadata (``source.topic`` of a
    multi-axis model, else its axes' ``extra.topic``; ``extra.topic`` of a single fit); None when not recorded.

    Parameters
    ----------
    model : ImuModel or GMWMFit
        The model.

    Returns
    -------
    str or None
    """
    if isinstance(model, ImuModel):
        if model.source.get("topic"):
            return str(model.source["topic"])
        extras = [d.get("extra") or {} for d in model.axes.values()]
        topics = {str(e["topic"]) for e in extras if e.get("topic")}
        return topics.pop() if len(topics) == 1 else None
    return str(model.extra["topic"]) if model.extra.get("topic") else None


def required_keys(fmt: str, *, legacy: bool = False) -> tuple[str, ...]:
    """The IMU keys a tool requires (its reader stops without them; tests/test_export_clients.py cites the reads).

    Parameters
    ----------
    fmt : {"kalibr", "openvins", "orbslam3"}
        The tool.
    legacy : bool
        ORB-SLAM3 legacy settings (``Tbc`` instead of ``IMU.T_b_c1``).

    Returns
    -------
    tuple of str
    """
    noise = tuple(k for s in ("gyro", "accel") for k in (_KALIBR_KEYS if fmt != "orbslam3" else _ORB_KEYS)[s])
    if fmt == "kalibr":
        return (*noise, "rostopic", "update_rate")
    if fmt == "openvins":
        return (*noise, "rostopic", "model", *OPENVINS_INTRINSICS)
    return (*noise, "IMU.Frequency", "Tbc" if legacy else "IMU.T_b_c1")


def _one_sensor_error(sensors: Mapping[str, SensorNoise], fmt: str, what: str) -> ModelError:
    have = next(iter(sensors))
    other = "accel" if have == "gyro" else "gyro"
    keys = (_ORB_KEYS if fmt == "orbslam3" else _KALIBR_KEYS)[other]
    name = {"kalibr": "a Kalibr imu.yaml", "openvins": "an OpenVINS imu0 block", "orbslam3": "ORB-SLAM3 settings"}[fmt]
    return ModelError(
        f"{what} has no {other} axes, and {name} needs {', '.join(keys)} (the tool stops without them): "
        f"write the {have} block alone with --sensor {have}, merge it into the tool's existing file with "
        f"`imunoise export MODEL --to {fmt} --into FILE`, or export json"
    )


def _frequency_text(freq: float, legacy: bool) -> tuple[str, str | None]:
    """IMU.Frequency: a real for v1.0, an integer for legacy ORB-SLAM3 (and a note when rounded)."""
    if not legacy:
        return repr(float(freq)), None
    n = int(round(freq))
    note = None if abs(n - freq) <= 1e-6 * freq else (
        f"IMU.Frequency written as {n}: legacy ORB-SLAM3 reads an integer, the data rate is {freq:.6g} Hz")
    return str(n), note


def export_text(
    model: ImuModel | GMWMFit | str | Path,
    fmt: str,
    *,
    sensor: str | None = None,
    topic: str | None = None,
    combine: str = "max",
    inflate: Mapping[str, float] | str | None = None,
    source: str | None = None,
    horizon_s: float | None = None,
    partial: bool = False,
    legacy: bool = False,
) -> str:
    """The file text of ``fmt`` (kalibr, openvins, orbslam3, json) for a multi-axis model or a single
    fit (``sensor`` when its unit and column name do not say). ``topic`` defaults to the model's recorded
    ROS topic (:func:`model_topic`), else ``/imu0``; ``horizon_s`` the longest averaging time matched on
    (default: the data's).

    Parameters
    ----------
    model : ImuModel, GMWMFit, str or Path
        The model, or the path of a saved model/fit JSON.
    fmt : str
        One of :data:`FORMATS`.
    sensor : {"gyro", "accel"}, optional
        Export only this sensor; for a single fit, which sensor it is when its unit and column name do not say.
    topic : str, optional
        ROS topic written (Kalibr/OpenVINS); default: the topic of the model's bag.
    combine, inflate
        As for :func:`sensor_noise` (``inflate`` also as text, :func:`parse_inflate`).
    source : str, optional
        Where the model came from, for the header comment.
    horizon_s : float, optional
        Longest averaging time matched on [s].
    partial : bool
        Allow a file with one sensor's keys only (the sensor block, to merge by hand). Without it a
        one-sensor export to kalibr/openvins/orbslam3, which each tool refuses, raises :class:`ModelError`.
    legacy : bool
        ORB-SLAM3: write ``IMU.Frequency`` as the integer legacy settings (no ``File.version``) need.

    Returns
    -------
    str
        The file's text.
    """
    if fmt not in FORMATS:
        raise ModelError(f"unknown export format {fmt!r}; use one of {', '.join(FORMATS)}")
    if isinstance(model, (str, Path)):
        source = source or str(model)
        model = load_model(model)
    if isinstance(inflate, str) or inflate is None:
        inflate = parse_inflate(inflate)
    sensors = model_sensors(model, sensor, combine, inflate, horizon_s)
    if fmt != "json" and len(sensors) < len(SENSORS) and not partial:
        raise _one_sensor_error(sensors, fmt, source or "the model")
    freq = next(iter(sensors.values())).freq_hz
    known = topic or model_topic(model)
    topic = known or "/imu0"
    topic_note = "the IMU ROS topic" + (
        " of the data" if known else " (not recorded with the data: the default; set it with --topic)")
    block = ([f"# SENSOR BLOCK ONLY ({', '.join(sensors)}): not a complete file for the tool; merge it with --into"]
             if fmt != "json" and len(sensors) < len(SENSORS) else [])
    if fmt == "json":
        return json.dumps(
            {
                "kind": "imunoise.export",
                "imunoise_version": __version__,
                "source": source,
                "update_rate_hz": freq,
                "rostopic": topic,
                "units_note": "noise_density and random_walk are continuous-time densities; "
                "discrete_* are per-sample values at update_rate_hz",
                "sensors": {s: sn.to_dict() for s, sn in sensors.items()},
                "model": model.to_dict(),
            },
            indent=1,
        )
    if fmt == "kalibr":
        lines = _header(model, sensors, "Kalibr IMU noise file (imu.yaml)", source) + block
        for s, title in (("accel", "#Accelerometers"), ("gyro", "#Gyroscopes")):
            lines += ["", title]
            if s in sensors:
                lines += _kalibr_lines(sensors, s)
            else:
                lines += _missing_lines(sensors, {x: _KALIBR_KEYS[x] for x in SENSORS if x == s})
        lines += [
            "",
            f"rostopic: {topic}  # {topic_note}",
            f"update_rate: {freq!r}  # [Hz] sample rate the continuous densities are discretised with",
        ]
        return "\n".join(lines) + "\n"
    if fmt == "openvins":
        lines = ["%YAML:1.0 # need to specify the file type at the top!"]
        lines += _header(model, sensors, "OpenVINS IMU file (kalibr_imu_chain.yaml)", source) + block
        lines += [f"# {OPENVINS_VERSIONS}", f"# rostopic: {topic_note}"]
        lines += [
            "",
            "imu0:",
            "  T_i_b:  # IMU to body transform (identity: body = IMU)",
            "    - [1.0, 0.0, 0.0, 0.0]",
            "    - [0.0, 1.0, 0.0, 0.0]",
            "    - [0.0, 0.0, 1.0, 0.0]",
            "    - [0.0, 0.0, 0.0, 1.0]",
        ]
        for s in ("accel", "gyro"):
            if s in sensors:
                lines += _kalibr_lines(sensors, s, "  ")
        lines += _missing_lines(sensors, _KALIBR_KEYS, "  ")
        lines += [
            f"  rostopic: {topic}",  # no comment on this line: OpenCV keeps it in an unquoted string
            "  time_offset: 0.0  # [s]",
            f"  update_rate: {freq!r}  # [Hz] sample rate the continuous densities are discretised with",
            '  model: "kalibr"  # OpenVINS >= v2.7: kalibr (= calibrated), rpng',
        ]
        for key, rows in OPENVINS_INTRINSICS.items():
            lines += [f"  {key}:", *(f"    {r}" for r in rows)]
        return "\n".join(lines) + "\n"
    f_text, f_note = _frequency_text(freq, legacy)
    lines = ["%YAML:1.0"]
    lines += _header(model, sensors, "ORB-SLAM3 IMU noise block (merge with imunoise export --into SETTINGS.yaml)",
                     source) + block
    lines += [f"# {ORBSLAM3_VERSIONS}"] + ([f"# note: {f_note}"] if f_note else [])
    lines.append("")
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = _ORB_KEYS[s]
            nc, kc = _value_comments(sensors[s])
            lines.append(f"{nk}: {format_float(sensors[s].noise_density)}  # {nc}")
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = _ORB_KEYS[s]
            nc, kc = _value_comments(sensors[s])
            lines.append(f"{kk}: {format_float(sensors[s].random_walk)}  # {kc}")
            lines.append(f"# {nk}, {kk}: {sensors[s].match_text()}")
    lines += _missing_lines(sensors, _ORB_KEYS)
    lines.append(f"IMU.Frequency: {f_text}  # [Hz] ORB-SLAM3 multiplies N by sqrt(f) and divides K by sqrt(f)")
    return "\n".join(lines) + "\n"


def _into_comment(sn: SensorNoise, which: str) -> str:
    n_unit, k_unit = density_units(sn.sensor)
    if which == "N":
        return (f"[{n_unit}] continuous-time, imunoise {__version__}; discrete sigma at {sn.freq_hz:g} Hz = "
                f"{sn.discrete_sigma:.4e} {_BASE_UNIT[sn.sensor]}")
    return (f"[{k_unit}] continuous-time, imunoise {__version__}; discrete bias step = {sn.discrete_bias_step:.4e} "
            f"{_BASE_UNIT[sn.sensor]}")


def update_into(
    model: ImuModel | GMWMFit | str | Path,
    fmt: str,
    into: str | Path,
    *,
    sensor: str | None = None,
    topic: str | None = None,
    combine: str = "max",
    inflate: Mapping[str, float] | str | None = None,
    horizon_s: float | None = None,
    legacy: bool | None = None,
) -> Any:
    """Set the IMU keys of the existing file ``into`` (``--into``) in place (:mod:`imunoise.io.tool_settings`).

    Parameters
    ----------
    model, fmt, sensor, combine, inflate, horizon_s
        As for :func:`export_text` (``fmt`` one of kalibr, openvins, orbslam3).
    into : str or Path
        The tool's file to update (ORB-SLAM3 settings, OpenVINS ``kalibr_imu_chain.yaml``, Kalibr ``imu.yaml``).
    topic : str, optional
        rostopic to write (Kalibr/OpenVINS); default the model's bag topic; when neither is known the file's
        own rostopic stays.
    legacy : bool, optional
        ORB-SLAM3: integer ``IMU.Frequency``; default: detected (no ``File.version: "1.0"`` = legacy).

    Returns
    -------
    imunoise.io.tool_settings.IntoResult
        What was updated, appended or removed, and the backup written.

    Raises
    ------
    DataError
        A file not of the tool's kind, or one that would still miss a key the tool requires.
    """
    from imunoise.io.tool_settings import inspect_settings, update_file

    if isinstance(model, (str, Path)):
        if Path(model).resolve() == Path(into).resolve():
            raise ModelError(f"--into {into} is the input model file; give the tool's settings file")
        model = load_model(model)
    if isinstance(inflate, str) or inflate is None:
        inflate = parse_inflate(inflate)
    sf = inspect_settings(into, fmt)
    sensors = model_sensors(model, sensor, combine, inflate, horizon_s)
    freq = next(iter(sensors.values())).freq_hz
    keys = _ORB_KEYS if fmt == "orbslam3" else _KALIBR_KEYS
    scalars: dict[str, tuple[str, str | None]] = {}
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = keys[s]
            scalars[nk] = (format_float(sensors[s].noise_density), _into_comment(sensors[s], "N"))
            scalars[kk] = (format_float(sensors[s].random_walk), _into_comment(sensors[s], "K"))
    notes = []
    topic = topic or model_topic(model)
    if fmt == "orbslam3":
        is_legacy = bool(legacy) or bool(sf.legacy)
        f_text, f_note = _frequency_text(freq, is_legacy)
        scalars["IMU.Frequency"] = (f_text, "[Hz] " + ("integer: legacy settings" if is_legacy else "ORB-SLAM3 v1.0"))
        notes += [f_note] if f_note else []
        # the transform the file must hold follows its reader (sf.legacy), not the --legacy frequency format
        return update_file(sf, scalars, required=required_keys(fmt, legacy=bool(sf.legacy)), anchor="IMU.",
                           model_keys=[*keys["gyro"], *keys["accel"]], notes=notes)
    if topic:
        # OpenCV keeps a comment after an unquoted string in the string: none on OpenVINS' rostopic line
        scalars["rostopic"] = (topic, None if fmt == "openvins" else "the IMU ROS topic of the data")
    elif not any(ln.split("#")[0].strip().startswith("rostopic:") for ln in sf.lines):
        scalars["rostopic"] = ("/imu0", None if fmt == "openvins" else "default: the topic was not recorded")
        notes.append("rostopic: the model does not record its bag topic; /imu0 written (set it with --topic)")
    scalars["update_rate"] = (repr(float(freq)), "[Hz] sample rate the continuous densities are discretised with")
    blocks = None
    if fmt == "openvins":
        blocks = dict(OPENVINS_INTRINSICS)
        if not any(ln.split("#")[0].strip().startswith("model:") for ln in sf.lines):
            scalars["model"] = ('"kalibr"', "OpenVINS >= v2.7: kalibr (= calibrated), rpng")
    return update_file(sf, scalars, blocks=blocks, required=required_keys(fmt),
                       model_keys=[*keys["gyro"], *keys["accel"]], notes=notes)


def write_export(
    model: ImuModel | GMWMFit | str | Path,
    fmt: str,
    path: str | Path | None = None,
    *,
    into: str | Path | None = None,
    **kwargs: Any,
) -> Path:
    """Write :func:`export_text` to ``path`` (default: :data:`DEFAULT_FILENAMES` beside a model file),
    atomically; or, with ``into``, update that existing file in place (:func:`update_into`).

    Parameters
    ----------
    model, fmt
        As for :func:`export_text`.
    path : str or Path, optional
        Output file; must not be the input model file.
    into : str or Path, optional
        An existing tool file to update instead (``path`` is then ignored).
    **kwargs
        Passed to :func:`export_text` (or :func:`update_into`).

    Returns
    -------
    Path
        The file written.
    """
    if into is not None:
        kwargs.pop("source", None)
        kwargs.pop("partial", None)
        return update_into(model, fmt, into, **kwargs).path
    if path is None:
        folder = Path(model).parent if isinstance(model, (str, Path)) else Path(".")
        path = folder / DEFAULT_FILENAMES[fmt]
    path = Path(path)
    if isinstance(model, (str, Path)) and path.resolve() == Path(model).resolve():
        raise ModelError(f"the output {path} is the input model file; choose another --out (it would be overwritten)")
    text = export_text(model, fmt, **kwargs)
    atomic_write_text(path, text)
    return path


def read_export(path: str | Path, fmt: str | None = None) -> dict[str, Any]:
    """Read an exported file back: the flat key -> value mapping (Kalibr/ORB-SLAM3 keys; OpenVINS keys of
    ``imu0``; for json the whole document). Used for the round-trip check.

    Parameters
    ----------
    path : str or Path
        An exported file.
    fmt : {"json", "yaml"}, optional
        Default: json when the text starts with ``{``, else YAML (Kalibr, OpenVINS, ORB-SLAM3).

    Returns
    -------
    dict

    Raises
    ------
    DataError
        When the YAML cannot be parsed.
    """
    import yaml

    path = Path(path)
    text = path.read_text()
    if fmt is None:
        fmt = "json" if text.lstrip().startswith("{") else "yaml"
    if fmt == "json":
        return json.loads(text)
    # OpenCV's "%YAML:1.0" directive is not YAML 1.1; drop it for PyYAML
    body = "\n".join(ln for ln in text.splitlines() if not ln.startswith("%YAML"))
    try:
        data = yaml.safe_load(body)
    except yaml.YAMLError as exc:
        raise DataError(f"{path}: not readable as YAML: {exc}") from exc
    if isinstance(data, dict) and "imu0" in data and isinstance(data["imu0"], dict):
        data = data["imu0"]
    return dict(data or {})
