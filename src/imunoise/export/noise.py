"""Per-axis and per-sensor (N, K) of a fitted model: the pair matched over Δt .. horizon, capped at the data's
Allan bound, combined over three axes (docs/guide/theory.rst, 'Latent processes' and 'Interfaces';
:mod:`imunoise.export`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import ModelError, UnitError
from imunoise.io.imu_input import sensor_of
from imunoise.noise.allan import data_curve
from imunoise.noise.equivalent_noise import WARN_RATIO, Equivalent, default_horizon_s, equivalent_noise
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.imu_model import ImuModel
from imunoise.units import quantity_of

SENSORS = ("gyro", "accel")
BASE_UNIT = {"gyro": "rad/s", "accel": "m/s^2"}
_SI_NAMES = {"gyro": ("rad/s",), "accel": ("m/s²", "m/s2", "m/s^2")}


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
    """Exportable continuous-time (N, K) of one fitted axis (module docstring; docs/guide/theory.rst, 'Interfaces').

    Parameters
    ----------
    fit
        A :class:`GMWMFit` or its ``to_dict()``.
    axis
        Name used in messages.
    horizon_s
        Longest averaging time matched on [s]; default :func:`imunoise.noise.equivalent_noise.default_horizon_s`.

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
    if forced := (fit.extra or {}).get("forced_pair"):  # --force past the pair gate: the data's Allan reading
        N, K = float(forced["N"]), float(forced["K"])
        notes.append(f"{name}: exported with --force: the data's Allan reading N = {N:.4g}, K = {K:.4g} in place "
                     "of the fitted pair, which the data refused")
    if not (math.isfinite(N) and math.isfinite(K) and N > 0 and K > 0):
        raise ModelError(f"{name}: the equivalent densities are not positive and finite (N={N}, K={K})")
    rw = [c.values[0] for c in fit.model.components if c.reading == "random_walk"]
    ramp = next((c.values[0] * f for c in fit.model.components if c.reading == "ramp"), None)
    if ramp is not None:
        notes.append(f"{name}: drift (rate ramp {ramp:.4g} {fit.unit}/s) has no slot; matched from below by K")
    if fit.model.has("QN"):
        notes.append(f"{name}: QN folded into the white-noise density as per-sample variance 2Q^2")
    notes += line_notes(fit, name)
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
            f"{self.worst_axis} at tau = {self.worst_at_s:.4g} s (matched on {range_text(self.tau_range_s)}"
            + (f"; the pair written is the {self.combine} over {len(self.axes)} axes" if len(self.axes) > 1 else "")
            + "): a white-noise + random-walk pair cannot follow that model there; see the routes per axis",
        )

    def match_text(self) -> str:
        """The comment written beside the pair."""
        side = "above" if self.worst_over else "below"
        at = f", pair {side} the {self.worst_axis} model at {self.worst_at_s:.4g} s" if self.worst_ratio > 1.0 else ""
        return (f"matched on tau = {range_text(self.tau_range_s)}; worst AV ratio exported/model = "
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
            "discrete_unit": BASE_UNIT[self.sensor],
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


def line_notes(fit: GMWMFit | Mapping[str, Any], name: str = "") -> list[str]:
    """The export notes from ``fit.extra``: the axis's narrowband lines (``lines``, :mod:`imunoise.lines`) and
    the gate on its pair (``export_gate``, :mod:`imunoise.export.gate`). Every format's header prints
    :attr:`AxisNoise.notes`, so every consumer's file carries them."""
    from imunoise.lines import Line

    extra = _as_fit(fit).extra or {}
    rec = extra.get("lines") or {}
    done = "removed before fitting (not in N, K)" if rec.get("removed", True) else "kept in the fitted data"
    out = [f"{name or 'axis'}: narrowband {Line.from_dict(d).text()}; {done}" for d in rec.get("found", ())]
    if g := extra.get("export_gate"):
        lo, hi = g["tau_range_s"]
        out.append(f"{name or 'axis'}: pair vs data AV over T = {lo:.3g}-{hi:.3g} s: worst {g['worst_ratio']:.3g}x "
                   f"{'above (conservative)' if g['pair_above_data'] else 'below (overconfident)'} at T = "
                   f"{g['worst_at_s']:.3g} s; inflation bounding the data {g['inflation']:.3g}x"
                   + (f"; REFUSED without --force: {g['cause']}" if g["refused"] else ""))
    return out


def range_text(r: tuple[float, float] | None) -> str:
    return "n/a" if r is None else f"{r[0]:.4g}..{r[1]:.4g} s"


def _check_unit(sensor: str, axes: list[AxisNoise]) -> list[str]:
    notes = []
    for a in axes:
        if a.unit in _SI_NAMES[sensor]:
            continue
        if a.unit in ("u", ""):
            notes.append(
                f"{a.axis or 'the fit'}: data unit not recorded (fit without --units); assumed {BASE_UNIT[sensor]}"
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
