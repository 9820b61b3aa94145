"""The text of each export format: Kalibr, OpenVINS, ORB-SLAM3 and JSON
(docs/guide/theory.rst, 'Latent processes' and 'Interfaces'; :mod:`imunoise.export`)."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path

from imunoise._version import __version__
from imunoise.errors import ModelError
from imunoise.export.in_use import apply_noise, in_use_comment, in_use_header
from imunoise.export.noise import (
    BASE_UNIT,
    SENSORS,
    AxisNoise,
    SensorNoise,
    density_units,
    format_float,
    infer_sensor,
    parse_inflate,
    range_text,
    sensor_noise,
)
from imunoise.export.vins_lio import TOOL_FILENAMES, TOOL_FORMATS, TOOL_KEYS, tool_text
from imunoise.io.imu_input import sensor_of
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.imu_model import ImuModel, load_model

FORMATS = ("kalibr", "openvins", "orbslam3", *TOOL_FORMATS, "json")
DEFAULT_FILENAMES = {
    "kalibr": "imu.yaml",
    "openvins": "kalibr_imu_chain.yaml",
    "orbslam3": "orbslam3_imu.yaml",
    **TOOL_FILENAMES,
    "json": "imu_noise.json",
}
KALIBR_KEYS = {
    "gyro": ("gyroscope_noise_density", "gyroscope_random_walk"),
    "accel": ("accelerometer_noise_density", "accelerometer_random_walk"),
}
ORB_KEYS = {"gyro": ("IMU.NoiseGyro", "IMU.GyroWalk"), "accel": ("IMU.NoiseAcc", "IMU.AccWalk")}
TOOL_NAMES = {"kalibr": "a Kalibr imu.yaml", "openvins": "an OpenVINS imu0 block", "orbslam3": "ORB-SLAM3 settings",
              "vins": "a VINS config", "lio-sam": "LIO-SAM's lio_sam parameters", "fast-lio": "FAST-LIO's mapping "
              "parameters"}  # fmt: skip


def noise_keys(fmt: str) -> dict[str, tuple[str, str]]:
    """Per sensor the (white-noise, random-walk) key names of a tool format."""
    return {"orbslam3": ORB_KEYS, **TOOL_KEYS}.get(fmt, KALIBR_KEYS)

# ----------------------------------------------------------------------------------------------
# text formats
# ----------------------------------------------------------------------------------------------
def model_sensors(model: ImuModel | GMWMFit, sensor: str | None, combine: str, inflate,
                  horizon_s: float | None = None, noise: str = "in-use") -> dict[str, SensorNoise]:
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
    noise : {"in-use", "static"}
        ``--noise``: the in-use pair where the model has an in-motion part (:mod:`imunoise.export.in_use`), or the
        static pair.

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
        return apply_noise(model, {sensor: sensor_noise(model, sensor, combine=combine, inflate=inflate,
                                                         horizon_s=horizon_s)}, noise)
    out = {}
    for s in SENSORS:
        if model.sensor_axes(s) and sensor in (None, s):
            out[s] = sensor_noise(model, s, combine=combine, inflate=inflate, horizon_s=horizon_s)
    if not out:
        raise ModelError(f"no gyro or accel axes in the model (axes: {', '.join(model.axes)})")
    return apply_noise(model, out, noise)


def _value_comments(sn: SensorNoise) -> tuple[str, str]:
    n_unit, k_unit = density_units(sn.sensor)
    base = BASE_UNIT[sn.sensor]
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
    return n_c + in_use_comment(sn, "N"), k_c + in_use_comment(sn, "K")


def axis_lines(a: AxisNoise, prefix: str = "") -> list[str]:
    """Per axis: the pair, its τ range and worst AV ratio, and which process went where."""
    n_unit, k_unit = density_units(sensor_of(a.axis, a.unit) or "gyro")
    e = a.equivalent
    side = "above" if e.worst_over else "below"
    worst = f"{e.worst_ratio:.3g}" + (f" (pair {side} the model at {e.worst_at_s:.4g} s)" if e.worst_ratio > 1 else "")
    lines = [
        f"{prefix}{a.axis or 'axis'}: {a.model}: N={a.N:.6e} {n_unit}, K={a.K:.6e} {k_unit} "
        f"(fitted RW alone K_rw={a.K_rw:.6e}); matched on tau = {range_text(e.tau_range_s)}, worst AV ratio {worst}"
    ]
    if e.capped:
        lines.append(f"{prefix}    {e.cap_text()}")
    lines += [f"{prefix}    {r.process} -> {r.slot}: {r.how}" for r in e.routes]
    return lines


def _header(model: ImuModel | GMWMFit, sensors: dict[str, SensorNoise], what: str, source: str | None,
            continuous: bool = True) -> list[str]:
    written = [
        "# The noise values are CONTINUOUS-TIME densities; the consumer discretises them with the update rate:",
        "#   per-sample white-noise sigma = N*sqrt(f), per-sample bias increment sigma = K/sqrt(f).",
    ] if continuous else [
        "# (N, K) below are CONTINUOUS-TIME densities; the values written are converted to this tool's own",
        "#   convention (stated below and beside each value), at the IMU rate f of the data.",
    ]
    lines = [
        f"# {what} written by imunoise {__version__} on {time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC"
        + (f" from {source}" if source else ""),
        *written,
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
    return lines + in_use_header(sensors)


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
    nk, kk = KALIBR_KEYS[s]
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
    """The IMU keys a tool requires (its reader stops without them).

    ``tests/export/test_export_clients.py`` cites the reads.

    Parameters
    ----------
    fmt : {"kalibr", "openvins", "orbslam3", "vins", "lio-sam", "fast-lio"}
        The tool (VINS, LIO-SAM and FAST-LIO fall back on a default or zero without a key: all four required).
    legacy : bool
        ORB-SLAM3 legacy settings (``Tbc`` instead of ``IMU.T_b_c1``).

    Returns
    -------
    tuple of str
    """
    noise = tuple(k for s in ("gyro", "accel") for k in noise_keys(fmt)[s])
    if fmt in TOOL_FORMATS:
        return noise
    if fmt == "kalibr":
        return (*noise, "rostopic", "update_rate")
    if fmt == "openvins":
        return (*noise, "rostopic", "model", *OPENVINS_INTRINSICS)
    return (*noise, "IMU.Frequency", "Tbc" if legacy else "IMU.T_b_c1")


def _one_sensor_error(sensors: Mapping[str, SensorNoise], fmt: str, what: str) -> ModelError:
    have = next(iter(sensors))
    other = "accel" if have == "gyro" else "gyro"
    keys = noise_keys(fmt)[other]
    name = TOOL_NAMES[fmt]
    return ModelError(
        f"{what} has no {other} axes, and {name} needs {', '.join(keys)} (the tool stops without them): "
        f"write the {have} block alone with --sensor {have}, merge it into the tool's existing file with "
        f"`imunoise export MODEL --to {fmt} --into FILE`, or export json"
    )


def frequency_text(freq: float, legacy: bool) -> tuple[str, str | None]:
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
    noise: str = "in-use",
) -> str:
    """The file text of ``fmt`` (kalibr, openvins, orbslam3, vins, lio-sam, fast-lio, json) for a multi-axis
    model or a single fit (``sensor`` when its unit and column name do not say). ``topic`` defaults to the
    model's recorded ROS topic (:func:`model_topic`), else ``/imu0``; ``horizon_s`` the longest averaging time
    matched on (default: the data's).

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
    noise : {"in-use", "static"}
        ``--noise``: the in-use values where the model has an in-motion part (default), or the static ones.

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
    sensors = model_sensors(model, sensor, combine, inflate, horizon_s, noise)
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
    if fmt in TOOL_FORMATS:
        what = {"vins": "VINS-Mono / VINS-Fusion IMU noise block", "lio-sam": "LIO-SAM IMU noise parameters",
                "fast-lio": "FAST-LIO IMU noise parameters"}[fmt]
        return tool_text(fmt, sensors, _header(model, sensors, what, source, continuous=fmt == "lio-sam") + block)
    if fmt == "kalibr":
        lines = _header(model, sensors, "Kalibr IMU noise file (imu.yaml)", source) + block
        for s, title in (("accel", "#Accelerometers"), ("gyro", "#Gyroscopes")):
            lines += ["", title]
            if s in sensors:
                lines += _kalibr_lines(sensors, s)
            else:
                lines += _missing_lines(sensors, {x: KALIBR_KEYS[x] for x in SENSORS if x == s})
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
        lines += _missing_lines(sensors, KALIBR_KEYS, "  ")
        lines += [
            f"  rostopic: {topic}",  # no comment on this line: OpenCV keeps it in an unquoted string
            "  time_offset: 0.0  # [s]",
            f"  update_rate: {freq!r}  # [Hz] sample rate the continuous densities are discretised with",
            '  model: "kalibr"  # OpenVINS >= v2.7: kalibr (= calibrated), rpng',
        ]
        for key, rows in OPENVINS_INTRINSICS.items():
            lines += [f"  {key}:", *(f"    {r}" for r in rows)]
        return "\n".join(lines) + "\n"
    f_text, f_note = frequency_text(freq, legacy)
    lines = ["%YAML:1.0"]
    lines += _header(model, sensors, "ORB-SLAM3 IMU noise block (merge with imunoise export --into SETTINGS.yaml)",
                     source) + block
    lines += [f"# {ORBSLAM3_VERSIONS}"] + ([f"# note: {f_note}"] if f_note else [])
    lines.append("")
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = ORB_KEYS[s]
            nc, kc = _value_comments(sensors[s])
            lines.append(f"{nk}: {format_float(sensors[s].noise_density)}  # {nc}")
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = ORB_KEYS[s]
            nc, kc = _value_comments(sensors[s])
            lines.append(f"{kk}: {format_float(sensors[s].random_walk)}  # {kc}")
            lines.append(f"# {nk}, {kk}: {sensors[s].match_text()}")
    lines += _missing_lines(sensors, ORB_KEYS)
    lines.append(f"IMU.Frequency: {f_text}  # [Hz] ORB-SLAM3 multiplies N by sqrt(f) and divides K by sqrt(f)")
    return "\n".join(lines) + "\n"
