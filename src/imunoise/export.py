"""Export a GMWM model to the noise parameters of VIO/INS stacks (SPEC §2, §12).

Kalibr ``imu.yaml``, OpenVINS ``kalibr_imu_chain.yaml`` and ORB-SLAM3 ``IMU.*`` all take two
*continuous-time* densities per sensor and discretise them with the update rate f = 1/Δt:

- white noise density N [u/√Hz] = √((σ²_WN + 2Q²)·Δt): exactly σ_WN·√Δt (SPEC §2) for a WN model; a QN
  term adds its per-sample variance 2Q² (the variance of u_t − u_{t−1}) as white noise at the data rate;
- bias random walk K_eq [u/s/√Hz] = √(γ²·f + Σ_i 2σ²_GM,i / T_c,i): RW's K = γ/√Δt plus each Gauss–Markov
  term's driving-noise density q_c = 2σ²_GM/T_c, because these formats have no GM slot and a GM bias
  behaves like a random walk with density √q_c for times shorter than T_c. It is never the
  Allan-variance minimum (bias instability), which is not a random-walk density at all.

A drift (DR) has no slot either; its rate ramp is written as a comment. Three axes of one sensor are
combined by the maximum (default, conservative) or the root mean square of the per-axis values.
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

from imunoise import __version__
from imunoise.errors import DataError, ModelError, UnitError
from imunoise.gmwm import GMWMFit
from imunoise.imu_model import ImuModel, load_model

__all__ = [
    "FORMATS",
    "DEFAULT_FILENAMES",
    "AxisNoise",
    "SensorNoise",
    "axis_noise",
    "sensor_noise",
    "parse_inflate",
    "export_text",
    "write_export",
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
@dataclass(frozen=True)
class AxisNoise:
    """Continuous-time noise of one axis (SPEC §2): ``N`` white-noise density, ``K_rw`` RW density,
    ``q_gm`` Σ 2σ²_GM/T_c over AR1 terms, ``K_eq`` = √(K_rw² + q_gm); ``q2_white`` the QN share of N²."""

    axis: str
    model: str
    unit: str
    freq_hz: float
    N: float
    K_rw: float
    q_gm: float
    K_eq: float
    n_qn: float = 0.0
    gm: tuple[tuple[float, float], ...] = ()  # (T_c s, σ_GM) per AR1
    rate_ramp: float | None = None


def _as_fit(fit: GMWMFit | Mapping[str, Any]) -> GMWMFit:
    return fit if isinstance(fit, GMWMFit) else GMWMFit.from_dict(dict(fit))


def axis_noise(fit: GMWMFit | Mapping[str, Any], axis: str = "") -> AxisNoise:
    """Exportable continuous-time values of one fitted axis (module docstring)."""
    fit = _as_fit(fit)
    f = float(fit.freq)
    cont = fit.continuous()
    white2 = 0.0
    qn2 = 0.0
    rw2 = 0.0
    q_gm = 0.0
    gm = []
    ramp = None
    for key, value in cont.items():
        name, what = key.split(".", 1)
        if what == "noise_density":
            white2 += value * value
        elif what == "random_walk":
            rw2 += value * value
        elif what == "q_c":
            q_gm += value
            gm.append((cont[f"{name}.tau_c"], cont[f"{name}.sigma_gm"]))
        elif what == "rate_ramp":
            ramp = value
    for key, value in fit.params.items():
        if key.endswith(".q2"):
            qn2 += 2.0 * value / f  # per-sample variance 2Q² as white noise: density² = 2Q²·Δt
    return AxisNoise(
        axis=axis,
        model=str(fit.model),
        unit=fit.unit,
        freq_hz=f,
        N=math.sqrt(white2 + qn2),
        K_rw=math.sqrt(rw2),
        q_gm=q_gm,
        K_eq=math.sqrt(rw2 + q_gm),
        n_qn=math.sqrt(qn2),
        gm=tuple(gm),
        rate_ramp=ramp,
    )


@dataclass(frozen=True)
class SensorNoise:
    """What goes into the files for one sensor: ``noise_density`` and ``random_walk`` (continuous, after
    inflation), ``raw_*`` before inflation, the per-axis values, how they were combined."""

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

    @property
    def discrete_sigma(self) -> float:
        """Per-sample white-noise σ at the update rate: N·√f (unit of the sensor)."""
        return self.noise_density * math.sqrt(self.freq_hz)

    @property
    def discrete_bias_step(self) -> float:
        """Per-sample σ of the bias increment at the update rate: K/√f (unit of the sensor)."""
        return self.random_walk / math.sqrt(self.freq_hz)

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
            "random_walk_formula": "K_eq = sqrt(gamma^2*f + sum_i 2*sigma_GM,i^2/T_c,i)",
            "axes": {
                a.axis: {"model": a.model, "N": a.N, "K_rw": a.K_rw, "q_gm": a.q_gm, "K_eq": a.K_eq} for a in self.axes
            },
            "notes": list(self.notes),
        }


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


def sensor_noise(
    model: ImuModel | GMWMFit,
    sensor: str,
    *,
    combine: str = "max",
    inflate: Mapping[str, float] | None = None,
) -> SensorNoise:
    """Combined continuous-time values of one sensor (``"gyro"`` or ``"accel"``) of a multi-axis model,
    or of a single-axis fit (then ``sensor`` says which sensor it is)."""
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
        axes = [axis_noise(model.axes[a], a) for a in names]
    else:
        axes = [axis_noise(model, sensor)]
    notes = _check_unit(sensor, axes)
    Ns = np.array([a.N for a in axes])
    Ks = np.array([a.K_eq for a in axes])
    if combine == "max":
        n_raw, k_raw = float(Ns.max()), float(Ks.max())
    else:
        n_raw, k_raw = float(np.sqrt(np.mean(Ns**2))), float(np.sqrt(np.mean(Ks**2)))
    for a in axes:
        if a.K_eq == 0.0:
            notes.append(f"{a.axis}: model {a.model} has no RW or AR1 term: bias random walk 0")
        if a.rate_ramp is not None:
            notes.append(f"{a.axis}: drift (rate ramp {a.rate_ramp:.4g} {a.unit}/s) has no slot; not exported")
        if a.n_qn > 0:
            notes.append(f"{a.axis}: QN folded into the white-noise density as per-sample variance 2Q^2")
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
    )


def parse_inflate(text: str | None) -> dict[str, float]:
    """``"white=2,rw=10"`` -> {"white": 2.0, "rw": 10.0}."""
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
def _sensors(model: ImuModel | GMWMFit, sensor: str | None, combine: str, inflate) -> dict[str, SensorNoise]:
    if isinstance(model, GMWMFit):
        if sensor not in SENSORS:
            raise ModelError("a single-axis fit needs --sensor gyro|accel (which sensor is this axis?)")
        return {sensor: sensor_noise(model, sensor, combine=combine, inflate=inflate)}
    out = {}
    for s in SENSORS:
        if model.sensor_axes(s) and sensor in (None, s):
            out[s] = sensor_noise(model, s, combine=combine, inflate=inflate)
    if not out:
        raise ModelError(f"no gyro or accel axes in the model (axes: {', '.join(model.axes)})")
    return out


def _value_comments(sn: SensorNoise) -> tuple[str, str]:
    n_unit, k_unit = density_units(sn.sensor)
    base = _BASE_UNIT[sn.sensor]
    axes = ",".join(a.axis for a in sn.axes)
    how = f"{sn.combine} over {axes}" if len(sn.axes) > 1 else axes
    n_c = f"[{n_unit}] continuous-time white-noise density N = sigma_WN*sqrt(dt) ({how})"
    if sn.inflate_white != 1.0:
        n_c += f" = {format_float(sn.raw_noise_density)} (fit) x {sn.inflate_white:g} (--inflate white)"
    n_c += f"; discrete sigma per sample at {sn.freq_hz:g} Hz = {sn.discrete_sigma:.4e} {base}"
    k_c = f"[{k_unit}] continuous-time bias random walk K_eq = sqrt(gamma^2*f + sum 2*sigma_GM^2/T_c) ({how})"
    if sn.inflate_rw != 1.0:
        k_c += f" = {format_float(sn.raw_random_walk)} (fit) x {sn.inflate_rw:g} (--inflate rw)"
    k_c += f"; discrete bias step per sample = {sn.discrete_bias_step:.4e} {base}"
    return n_c, k_c


def _header(model: ImuModel | GMWMFit, sensors: dict[str, SensorNoise], what: str, source: str | None) -> list[str]:
    lines = [
        f"# {what} written by imunoise {__version__} on {time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC"
        + (f" from {source}" if source else ""),
        "# The noise values are CONTINUOUS-TIME densities; the consumer discretises them with the update rate:",
        "#   per-sample white-noise sigma = N*sqrt(f), per-sample bias increment sigma = K/sqrt(f).",
        "# N  = sqrt((sigma_WN^2 + 2*Q^2)*dt)  (exactly sigma_WN*sqrt(dt) without quantisation noise)",
        "# K_eq = sqrt(gamma^2*f + sum_i 2*sigma_GM,i^2/T_c,i): random walk plus the Gauss-Markov driving noise,",
        "#   because GM terms have no slot here. It is NOT the Allan-variance minimum (bias instability).",
        "# Per axis (continuous-time, before inflation):",
    ]
    for sn in sensors.values():
        n_unit, k_unit = density_units(sn.sensor)
        for a in sn.axes:
            gm = "".join(f", GM T_c={tc:.4g} s sigma_GM={s:.4g}" for tc, s in a.gm)
            lines.append(
                f"#   {a.axis}: {a.model}: N={a.N:.6e} {n_unit}, K_rw={a.K_rw:.6e} {k_unit}, "
                f"K_eq={a.K_eq:.6e} {k_unit}{gm}"
            )
        lines += [f"# note: {n}" for n in sn.notes]
    return lines


def _missing_lines(sensors: dict[str, SensorNoise], keys: dict[str, tuple[str, str]], indent: str = "") -> list[str]:
    out = []
    for s in SENSORS:
        if s not in sensors:
            for k in keys[s]:
                out.append(f"{indent}# {k}: not exported (the input model has no {s} axis)")
    return out


def export_text(
    model: ImuModel | GMWMFit | str | Path,
    fmt: str,
    *,
    sensor: str | None = None,
    topic: str | None = None,
    combine: str = "max",
    inflate: Mapping[str, float] | str | None = None,
    source: str | None = None,
) -> str:
    """The file text of ``fmt`` (kalibr, openvins, orbslam3, json) for a multi-axis model or a single
    fit (with ``sensor``). ``topic`` defaults to the model's recorded ROS topic, else ``/imu0``."""
    if fmt not in FORMATS:
        raise ModelError(f"unknown export format {fmt!r}; use one of {', '.join(FORMATS)}")
    if isinstance(model, (str, Path)):
        source = source or str(model)
        model = load_model(model)
    if isinstance(inflate, str) or inflate is None:
        inflate = parse_inflate(inflate)
    sensors = _sensors(model, sensor, combine, inflate)
    freq = next(iter(sensors.values())).freq_hz
    if topic is None:
        src = model.source if isinstance(model, ImuModel) else model.extra
        topic = src.get("topic") or "/imu0"
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
        lines = _header(model, sensors, "Kalibr IMU noise file (imu.yaml)", source)
        for s, title in (("accel", "#Accelerometers"), ("gyro", "#Gyroscopes")):
            lines += ["", title]
            if s in sensors:
                nk, kk = _KALIBR_KEYS[s]
                nc, kc = _value_comments(sensors[s])
                lines.append(f"{nk}: {format_float(sensors[s].noise_density)}  # {nc}")
                lines.append(f"{kk}: {format_float(sensors[s].random_walk)}  # {kc}")
            else:
                lines += _missing_lines(sensors, {x: _KALIBR_KEYS[x] for x in SENSORS if x == s})
        lines += [
            "",
            f"rostopic: {topic}  # the IMU ROS topic",
            f"update_rate: {freq!r}  # [Hz] sample rate the continuous densities are discretised with",
        ]
        return "\n".join(lines) + "\n"
    if fmt == "openvins":
        lines = ["%YAML:1.0 # need to specify the file type at the top!"]
        lines += _header(model, sensors, "OpenVINS IMU file (kalibr_imu_chain.yaml)", source)
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
                nk, kk = _KALIBR_KEYS[s]
                nc, kc = _value_comments(sensors[s])
                lines.append(f"  {nk}: {format_float(sensors[s].noise_density)}  # {nc}")
                lines.append(f"  {kk}: {format_float(sensors[s].random_walk)}  # {kc}")
        lines += _missing_lines(sensors, _KALIBR_KEYS, "  ")
        lines += [
            '  model: "calibrated"  # no IMU intrinsics estimated here',
            f"  rostopic: {topic}",
            "  time_offset: 0.0  # [s]",
            f"  update_rate: {freq!r}  # [Hz] sample rate the continuous densities are discretised with",
        ]
        return "\n".join(lines) + "\n"
    lines = ["%YAML:1.0"]
    lines += _header(model, sensors, "ORB-SLAM3 IMU noise block (paste into the settings file)", source)
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
    lines += _missing_lines(sensors, _ORB_KEYS)
    lines.append(f"IMU.Frequency: {freq!r}  # [Hz] ORB-SLAM3 multiplies N by sqrt(f) and divides K by sqrt(f)")
    return "\n".join(lines) + "\n"


def write_export(
    model: ImuModel | GMWMFit | str | Path,
    fmt: str,
    path: str | Path | None = None,
    **kwargs: Any,
) -> Path:
    """Write :func:`export_text` to ``path`` (default: :data:`DEFAULT_FILENAMES` beside a model file)."""
    if path is None:
        folder = Path(model).parent if isinstance(model, (str, Path)) else Path(".")
        path = folder / DEFAULT_FILENAMES[fmt]
    path = Path(path)
    text = export_text(model, fmt, **kwargs)
    path.write_text(text)
    return path


def read_export(path: str | Path, fmt: str | None = None) -> dict[str, Any]:
    """Read an exported file back: the flat key -> value mapping (Kalibr/ORB-SLAM3 keys; OpenVINS keys of
    ``imu0``; for json the whole document). Used for the round-trip check."""
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
