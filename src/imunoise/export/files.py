"""Export files written, read back and updated in place (docs/guide/theory.rst, 'Latent processes' and 'Interfaces';
:mod:`imunoise.export`)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from imunoise._version import __version__
from imunoise.errors import DataError, ModelError
from imunoise.export.formats import (
    DEFAULT_FILENAMES,
    OPENVINS_INTRINSICS,
    export_text,
    frequency_text,
    model_sensors,
    model_topic,
    noise_keys,
    required_keys,
)
from imunoise.export.in_use import in_use_comment
from imunoise.export.noise import BASE_UNIT, SensorNoise, density_units, format_float, parse_inflate
from imunoise.export.vins_lio import TOOL_FORMATS, tool_comment, tool_values
from imunoise.io.atomic import atomic_write_text
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.imu_model import ImuModel, load_model


def _into_comment(sn: SensorNoise, which: str) -> str:
    n_unit, k_unit = density_units(sn.sensor)
    if which == "N":
        return (f"[{n_unit}] continuous-time, imunoise {__version__}; discrete sigma at {sn.freq_hz:g} Hz = "
                f"{sn.discrete_sigma:.4e} {BASE_UNIT[sn.sensor]}{in_use_comment(sn, 'N')}")
    return (f"[{k_unit}] continuous-time, imunoise {__version__}; discrete bias step = {sn.discrete_bias_step:.4e} "
            f"{BASE_UNIT[sn.sensor]}{in_use_comment(sn, 'K')}")


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
    noise: str = "in-use",
) -> Any:
    """Set the IMU keys of the existing file ``into`` (``--into``) in place (:mod:`imunoise.io.tool_settings`).

    Parameters
    ----------
    model, fmt, sensor, combine, inflate, horizon_s
        As for :func:`export_text` (``fmt`` one of kalibr, openvins, orbslam3, vins, lio-sam, fast-lio).
    into : str or Path
        The tool's file to update (ORB-SLAM3 settings, OpenVINS ``kalibr_imu_chain.yaml``, Kalibr ``imu.yaml``,
        a VINS config, LIO-SAM ``params.yaml``, a FAST-LIO config such as ``avia.yaml``).
    topic : str, optional
        rostopic to write (Kalibr/OpenVINS); default the model's bag topic; when neither is known the file's
        own rostopic stays.
    legacy : bool, optional
        ORB-SLAM3: integer ``IMU.Frequency``; default: detected (no ``File.version: "1.0"`` = legacy).
    noise : {"in-use", "static"}
        As for :func:`export_text`.

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
    sensors = model_sensors(model, sensor, combine, inflate, horizon_s, noise)
    freq = next(iter(sensors.values())).freq_hz
    keys = noise_keys(fmt)
    scalars: dict[str, tuple[str, str | None]] = {}
    if fmt in TOOL_FORMATS:  # the four noise keys alone: the file's topics and everything else stay
        for s in ("accel", "gyro"):
            if s in sensors:
                (nk, kk), (nv, kv) = keys[s], tool_values(sensors[s], fmt)
                scalars[nk] = (format_float(nv), tool_comment(sensors[s], fmt, "N"))
                scalars[kk] = (format_float(kv), tool_comment(sensors[s], fmt, "K"))
        return update_file(sf, scalars, required=required_keys(fmt), model_keys=[*keys["gyro"], *keys["accel"]])
    for s in ("gyro", "accel"):
        if s in sensors:
            nk, kk = keys[s]
            scalars[nk] = (format_float(sensors[s].noise_density), _into_comment(sensors[s], "N"))
            scalars[kk] = (format_float(sensors[s].random_walk), _into_comment(sensors[s], "K"))
    notes = []
    topic = topic or model_topic(model)
    if fmt == "orbslam3":
        is_legacy = bool(legacy) or bool(sf.legacy)
        f_text, f_note = frequency_text(freq, is_legacy)
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
