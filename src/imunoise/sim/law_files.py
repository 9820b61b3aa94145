"""Motion-law files (``--motion-noise FILE.json``) and the shipped laws: the schema's reader
(:func:`law_from_dict`, :func:`load_law`; the schema is in :mod:`imunoise.sim.motion`), the laws shipped in
``src/imunoise/sim/laws/*.json`` by name (:data:`LAWS`, the presets ``none`` and ``drive0708``) and the
resolution of a ``--motion-noise`` value (:func:`resolve_motion`, :func:`motion_arg`)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import Any

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.sim.motion_law import MotionNoise

__all__ = ["LAW_DIR", "LAWS", "NONE", "DRIVE0708", "MOTION_PRESETS", "DEFAULT_MOTION", "law_from_dict", "load_law",
           "resolve_motion", "motion_arg"]

_N = len(AXES)

LAW_DIR = "laws"  # package folder of the shipped law files (imunoise/sim/laws/*.json)
_ACTIVITIES = ("speed", "turn", "accel")
_KEYS = ("name", "doc", "speed_ref_mps", "turn_ref_deg_s", "accel_ref_mps2", "white", "bias", "moving_gm",
         "departure_step", "warmup")


def _six(where: str, key: str, v: Any, *, positive: bool = False) -> tuple[float, ...]:
    ok = isinstance(v, list) and len(v) == _N and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                        and math.isfinite(x) for x in v)
    if not ok or not all((x > 0) if positive else (x >= 0) for x in v):
        raise ModelError(f"{where}: key '{key}' needs a list of {_N} numbers {'> 0' if positive else '≥ 0'} "
                         f"(gyro x, y, z, accel x, y, z; SI units), got {v!r}")
    return tuple(float(x) for x in v)


# Plausible ranges: a value beyond them is a typo or a unit slip (a law with ×1e6 multipliers ran to 52 km RMS),
# refused in one line. Multipliers c add c × the static noise (c = 100: 101× the static σ, far above the real
# drive's 3–7×); SI magnitudes (Gauss–Markov σ, departure steps, warm-up amplitudes) up to 0.2 rad/s (11 °/s) on
# the gyros and 5 m/s² (0.5 g) on the accelerometers, an order above the worst consumer MEMS.
MAX_MULTIPLIER = 100.0
MAX_SI = (0.2, 0.2, 0.2, 5.0, 5.0, 5.0)


def _within(where: str, key: str, values: tuple[float, ...], limits: tuple[float, ...], what: str) -> None:
    for j, (x, lim) in enumerate(zip(values, limits, strict=True)):
        if abs(x) > lim:
            unit = "" if what == "multiplier" else (" rad/s" if j < 3 else " m/s²")
            raise ModelError(f"{where}: key '{key}' has {x:g}{unit} for {AXES[j]}, outside the plausible range "
                             f"±{lim:g}{unit} ({what}; SI units, not degrees or g); correct the value")


def _number(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
        raise ModelError(f"{where}: key '{key}' needs a number > 0, got {v!r}")
    return float(v)


def _table(where: str, key: str, v: Any, allowed: tuple[str, ...]) -> dict:
    if not isinstance(v, dict):
        raise ModelError(f"{where}: key '{key}' needs an object with keys {', '.join(allowed)}, got {v!r}")
    bad = [k for k in v if k not in allowed]
    if bad:
        raise ModelError(f"{where}: unknown key '{key}.{bad[0]}' (allowed: {', '.join(allowed)})")
    return v


def law_from_dict(d: Any, where: str = "motion law") -> MotionNoise:
    """A :class:`MotionNoise` from the law-file schema (:mod:`imunoise.sim.motion`); ``where`` names the source in the
    one-line error.

    Raises
    ------
    ModelError
        Naming the first bad key (unknown key, wrong length or type, negative value, missing τ).
    """
    if not isinstance(d, dict):
        raise ModelError(f"{where}: a law file holds one JSON object, got {type(d).__name__}")
    bad = [k for k in d if k not in _KEYS]
    if bad:
        raise ModelError(f"{where}: unknown key '{bad[0]}' (allowed: {', '.join(_KEYS)})")
    kw: dict[str, Any] = {}
    if "name" in d:
        if not isinstance(d["name"], str) or not d["name"]:
            raise ModelError(f"{where}: key 'name' needs a non-empty string, got {d['name']!r}")
        kw["name"] = d["name"]
    if "doc" in d and not isinstance(d["doc"], str):
        raise ModelError(f"{where}: key 'doc' needs a string")
    for key in ("speed_ref_mps", "turn_ref_deg_s", "accel_ref_mps2"):
        if key in d:
            kw[key] = _number(where, key, d[key])
    for group in ("white", "bias"):
        if group in d:
            for act, v in _table(where, group, d[group], _ACTIVITIES).items():
                kw[f"{group}_{act}"] = _six(where, f"{group}.{act}", v)
                _within(where, f"{group}.{act}", kw[f"{group}_{act}"], (MAX_MULTIPLIER,) * _N, "multiplier")
    if "moving_gm" in d:
        gm = _table(where, "moving_gm", d["moving_gm"], ("sigma", "tau_s"))
        if "tau_s" in gm and "sigma" not in gm:  # else the term would silently add nothing
            raise ModelError(f"{where}: key 'moving_gm.sigma' is needed with 'moving_gm.tau_s' (6 values ≥ 0, "
                             "rad/s for the gyros, m/s² for the accelerometers)")
        if "sigma" in gm:
            if "tau_s" not in gm:
                raise ModelError(f"{where}: key 'moving_gm.tau_s' is needed with 'moving_gm.sigma' (6 values > 0 s)")
            kw["moving_gm_sigma"] = _six(where, "moving_gm.sigma", gm["sigma"])
            kw["moving_gm_tau_s"] = _six(where, "moving_gm.tau_s", gm["tau_s"], positive=True)
            _within(where, "moving_gm.sigma", kw["moving_gm_sigma"], MAX_SI, "a Gauss–Markov σ")
    if "departure_step" in d:
        kw["departure_step"] = _six(where, "departure_step", d["departure_step"])
        _within(where, "departure_step", kw["departure_step"], MAX_SI, "a step's σ")
    if "warmup" in d:
        wu = _table(where, "warmup", d["warmup"], ("amplitude", "tau_s"))
        if "tau_s" in wu and "amplitude" not in wu:  # else the term would silently add nothing
            raise ModelError(f"{where}: key 'warmup.amplitude' is needed with 'warmup.tau_s' (6 values, rad/s for "
                             "the gyros, m/s² for the accelerometers)")
        if "amplitude" in wu:
            if "tau_s" not in wu:
                raise ModelError(f"{where}: key 'warmup.tau_s' is needed with 'warmup.amplitude' (a number > 0 s)")
            amp = wu["amplitude"]
            ok = isinstance(amp, list) and len(amp) == _N and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in amp)
            if not ok:
                raise ModelError(f"{where}: key 'warmup.amplitude' needs a list of {_N} numbers (gyro x, y, z, "
                                 f"accel x, y, z; SI units), got {amp!r}")
            kw["warmup_amplitude"] = tuple(float(x) for x in amp)
            _within(where, "warmup.amplitude", kw["warmup_amplitude"], MAX_SI, "a warm-up amplitude")
            kw["warmup_tau_s"] = _number(where, "warmup.tau_s", wu["tau_s"])
    return MotionNoise(**kw)


def load_law(path: str | Path) -> MotionNoise:
    """A motion law from a JSON file of the law-file schema (:mod:`imunoise.sim.motion`).

    Raises
    ------
    ModelError
        One line naming the file and the bad key (or the JSON error), e.g. from ``--motion-noise FILE``.
    """
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except OSError as exc:
        raise ModelError(f"motion law {p}: cannot read it ({exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise ModelError(f"motion law {p}: not JSON ({exc.msg}, line {exc.lineno})") from None
    law = law_from_dict(d, f"motion law {p}")
    return law if "name" in d else MotionNoise(**{**asdict(law), "name": p.stem})


def _shipped() -> dict[str, MotionNoise]:
    folder = resources.files("imunoise.sim").joinpath(LAW_DIR)
    out = {}
    # the two presets first (the names of the earlier preset list), then the others by name
    for f in sorted(folder.iterdir(), key=lambda f: (f.name not in ("none.json", "drive0708.json"),
                                                      f.name != "none.json", f.name)):
        if f.name.endswith(".json"):
            out[f.name[:-5]] = law_from_dict(json.loads(f.read_text()), f"motion law {f.name}")
    return out


LAWS: dict[str, MotionNoise] = _shipped()
NONE = LAWS["none"]

# Calibrated on the experiments' default scenario (paper IMU preset, 600 s drives with 4 stops) by
# scripts/calibrate_motion_noise.py against the real drive's ratio (std of 10 s means while moving) / (static
# ADEV at 10 s) per gyro axis: 0.91 / 3.9 / 20.5. Gyro x gets no bias amplification: the static model alone
# already gives a larger ratio there (its rate random walk accumulates over a drive). White noise: ×3 on the
# gyros and ×7 on the accelerometers at speed, the earlier simulator's vibration (0.1 °/s and 0.05 m/s² per
# sample at ≥ 3 m/s) against the white σ of the paper/mems presets. The real drive's regressions of the
# errors on speed and |ω_z| explain little (R² 0.08–0.30), so the preset is a moving/at-rest switch ramped
# by speed; the turn terms are 0. Shipped as laws/drive0708.json.
DRIVE0708 = LAWS["drive0708"]

MOTION_PRESETS: dict[str, MotionNoise] = {"none": NONE, "drive0708": DRIVE0708}
DEFAULT_MOTION = "drive0708"


def resolve_motion(spec: str | Path | MotionNoise) -> MotionNoise:
    """A :class:`MotionNoise` from a shipped law's name (:data:`LAWS`, e.g. the presets ``none`` and
    ``drive0708``), a path to a law file (:func:`load_law`: anything ending in ``.json`` or an existing file),
    or a MotionNoise (returned as is).

    Raises
    ------
    ModelError
        For an unknown name (listing the shipped laws), a malformed file (naming the key) or another type.
    """
    if isinstance(spec, MotionNoise):
        return spec
    if isinstance(spec, (str, Path)):
        if isinstance(spec, str) and spec.lower() in LAWS:
            return LAWS[spec.lower()]
        if str(spec).lower().endswith(".json") or Path(spec).is_file():
            return load_law(spec)
    raise ModelError(f"unknown motion-noise preset {spec!r}; choose one of {', '.join(LAWS)} or give a law "
                     "file (FILE.json)")


def motion_arg(spec: str) -> str:
    """The value of ``--motion-noise`` to carry to the workers: a shipped law's name as is, a law file as its
    absolute path (loaded and checked here, so a malformed file fails before any run).

    Raises
    ------
    ModelError
        As :func:`resolve_motion`.
    """
    resolve_motion(spec)
    return spec.lower() if spec.lower() in LAWS else str(Path(spec).resolve())
