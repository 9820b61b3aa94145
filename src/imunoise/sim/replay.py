"""Real noise, known truth: replay a real static IMU recording as a simulated drive's IMU errors (issue 21 §3).

A static recording (a ``.npz`` that states its ``columns`` gyro_x … accel_z, ``units`` and ``freq_hz``, as
the shared ADIS16405 logs do) holds the sensor's real errors with their non-Gaussian, non-model structure.
:func:`load_recording` converts them to SI (deg/s → rad/s, g → m/s² with g = 9.80665, or rad/s and m/s² as
they are) and removes the mean of the whole file per axis, so the truth injected into a drive is the
recording's own fluctuation about its long-run level (bias wander included):

    e_k = r_{s+k} − (1/N) Σ_i r_i,   k = 0 … n − 1,

with s the first sample of the drive's stretch. Drive d of a run (d = seed − first seed) gets the stretch
[d·n, (d + 1)·n) of the recording (no two drives overlap); a stop of the drive therefore shows the recording's
samples at the stop times, inside the drive's stretch. Vehicles of K drives (``--vehicle-drives K``: the same
unit's noise on K drives, scored on the last) get K consecutive stretches each, oldest drive first: vehicle v
(v = seed − first seed), drive j = K − 1 − k when it is the k-th drive before the scored one, replays stretch
index v·K + j (:func:`stretch_index`), so the stretches of all drives of all vehicles are disjoint and K = 1 is
the single-drive layout. A static recording for the denial experiment is taken
from the end of the file, [N − m, N), and no drive may reach into it (:func:`stretch`). The recording must
have the simulator's rate: resampling would change the noise's spectrum, so another rate is refused with the
rate to simulate at.
"""

from __future__ import annotations

import functools
import math
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imunoise.errors import DataError, ModelError
from imunoise.imu import AXES, canonical_axis

__all__ = ["NoiseRecording", "load_recording", "stretch", "stretch_index", "check_vehicles", "drive_samples",
           "static_part", "G0"]

G0 = 9.80665  # m/s² per g (the recordings' README: use it unless a better local value is known)
_UNIT = {"deg/s": math.pi / 180.0, "°/s": math.pi / 180.0, "rad/s": 1.0, "g": G0, "m/s^2": 1.0, "m/s²": 1.0,
         "m/s2": 1.0}
_GYRO_UNITS = ("deg/s", "°/s", "rad/s")
_ACCEL_UNITS = ("g", "m/s^2", "m/s²", "m/s2")


@dataclass(frozen=True)
class NoiseRecording:
    """A static recording's errors in SI, axes :data:`imunoise.imu.AXES`, the whole file's mean removed."""

    path: str
    rate_hz: float
    errors: np.ndarray  # (N, 6): rad/s, m/s²
    mean_removed: tuple[float, ...]  # the removed per-axis mean, SI

    @property
    def n(self) -> int:
        return int(self.errors.shape[0])

    def describe(self) -> dict:
        return {"file": self.path, "rate_hz": self.rate_hz, "samples": self.n, "duration_s": self.n / self.rate_hz,
                "mean_removed_si": list(self.mean_removed), "axes": list(AXES)}


@functools.lru_cache(maxsize=8)
def load_recording(path: str) -> NoiseRecording:
    """The recording at ``path`` (module docstring), cached per process.

    Raises
    ------
    DataError
        If the file cannot be read or lacks ``data``/``columns``/``units``/``freq_hz``, or a column or unit is
        unknown; each message names the file and the key.
    """
    p = Path(path)
    keys = _read_keys(p)
    try:
        data = np.asarray(keys["data"], dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"--imu-noise {p}: key 'data' is not numeric ({keys['data'].dtype}); store a float "
                        "array of shape (samples, columns)") from None
    cols = [str(c) for c in np.atleast_1d(keys["columns"])]
    units = [str(u) for u in np.atleast_1d(keys["units"])]
    if len(units) == 1:
        units = units * len(cols)
    if data.ndim != 2 or data.shape[1] != len(cols) or len(units) != len(cols):
        raise DataError(f"--imu-noise {p}: key 'data' has shape {data.shape} for {len(cols)} columns and "
                        f"{len(units)} units")
    rate = _rate(p, keys["freq_hz"])
    out = np.zeros((data.shape[0], len(AXES)))
    seen = set()
    for j, (c, u) in enumerate(zip(cols, units, strict=True)):
        ax = canonical_axis(c)
        if ax is None:
            raise DataError(f"--imu-noise {p}: key 'columns' has {c!r}; use {', '.join(AXES)}")
        if u not in (_GYRO_UNITS if ax.startswith("gyro") else _ACCEL_UNITS):
            raise DataError(f"--imu-noise {p}: key 'units' has {u!r} for {c}; use deg/s or rad/s (gyros), "
                            "g or m/s^2 (accelerometers)")
        out[:, AXES.index(ax)] = data[:, j] * _UNIT[u]
        seen.add(ax)
    if seen != set(AXES):
        raise DataError(f"--imu-noise {p}: key 'columns' lacks {sorted(set(AXES) - seen)}")
    if not np.all(np.isfinite(out)):
        raise DataError(f"--imu-noise {p}: key 'data' holds non-finite values")
    _check_plausible(p, out, dict(zip([canonical_axis(c) for c in cols], units, strict=True)))
    mean = out.mean(axis=0)
    out -= mean
    out.setflags(write=False)
    return NoiseRecording(str(p.resolve()), rate, out, tuple(float(m) for m in mean))


def _read_keys(p: Path) -> dict[str, np.ndarray]:
    """The four keys of the recording, each read here: a truncated or corrupt archive, a pickled (object)
    array or a missing key is one line naming the file and the key."""
    try:
        z = np.load(p, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DataError(f"--imu-noise {p}: cannot read it as .npz ({exc}); give a recording saved by "
                        "numpy.savez with data, columns, units and freq_hz") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise DataError(f"--imu-noise {p}: a single .npy array, not an .npz recording; save data, columns, units "
                        "and freq_hz with numpy.savez")
    missing = [k for k in ("data", "columns", "units", "freq_hz") if k not in z.files]
    if missing:
        raise DataError(f"--imu-noise {p}: key '{missing[0]}' missing (a recording states data, columns, units "
                        "and freq_hz)")
    out = {}
    for k in ("data", "columns", "units", "freq_hz"):
        try:
            out[k] = z[k]
        except ValueError as exc:  # an object array: loading it would run pickled code
            raise DataError(f"--imu-noise {p}: key '{k}' is a pickled (object) array, not read for safety "
                            f"({exc}); store it as a plain numeric or string array") from None
        except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise DataError(f"--imu-noise {p}: key '{k}' cannot be read, the file is truncated or corrupt "
                            f"({exc}); copy it again") from None
    return out


def _rate(p: Path, value: np.ndarray) -> float:
    """``freq_hz``: one positive finite number."""
    v = np.asarray(value)
    if v.size != 1 or v.dtype.kind not in "iuf":
        raise DataError(f"--imu-noise {p}: key 'freq_hz' must be one number (the sampling rate in Hz), got "
                        f"{v.dtype} of shape {v.shape}")
    rate = float(v.reshape(()))
    if not (math.isfinite(rate) and rate > 0):
        raise DataError(f"--imu-noise {p}: key 'freq_hz' must be > 0, got {rate}")
    return rate


# Static-recording plausibility in SI (before the mean is removed): a gyro at rest reads Earth rate plus its
# bias (|mean| well below 0.1 rad/s = 5.7 °/s for any MEMS) with a per-sample spread far below 0.05 rad/s; the
# accelerometers read gravity, |mean vector| = 9.8 m/s². The shared ADIS16405 logs: gyro std 0.0061–0.0075 rad/s,
# |mean| ≤ 0.0076 rad/s; accel norm 9.97 m/s². Data in deg/s labelled rad/s read 57× larger, in g labelled m/s²
# 9.8× smaller: both far outside.
GYRO_MAX_STD = 0.05  # rad/s
GYRO_MAX_MEAN = 0.1  # rad/s
ACCEL_NORM_RANGE = (7.8, 11.8)  # m/s², g ± 2


def _check_plausible(p: Path, si: np.ndarray, units: dict) -> None:
    """Refuse a recording whose magnitudes contradict its stated units (deg/s labelled rad/s, g labelled m/s²)."""
    for j in range(3):
        ax = AXES[j]
        mean, std = abs(float(si[:, j].mean())), float(si[:, j].std())
        if std > GYRO_MAX_STD or mean > GYRO_MAX_MEAN:
            hint = " (the numbers look like deg/s)" if units[ax] == "rad/s" else ""
            raise DataError(f"--imu-noise {p}: key 'units' says {units[ax]} for {ax}, but at rest it reads a mean "
                            f"of {mean:.3g} rad/s and a spread of {std:.3g} rad/s per sample, no static gyro"
                            f"{hint}; correct the file's units (deg/s or rad/s)")
    norm = float(np.linalg.norm(si[:, 3:].mean(axis=0)))
    if not ACCEL_NORM_RANGE[0] <= norm <= ACCEL_NORM_RANGE[1]:
        stated = ", ".join(sorted({units[a] for a in AXES[3:]}))
        hint = " (the numbers look like g)" if 0.8 <= norm <= 1.2 else (
            " (the numbers look like m/s² labelled g)" if 78.0 <= norm <= 118.0 else "")
        raise DataError(f"--imu-noise {p}: key 'units' says {stated} for the accelerometers, but at rest they read "
                        f"|mean| = {norm:.3g} m/s², not gravity (9.81 m/s²){hint}; correct the file's units "
                        "(g or m/s^2)")


def _check_rate(rec: NoiseRecording, rate_hz: float) -> None:
    if abs(rec.rate_hz - rate_hz) > 1e-9 * rate_hz:
        raise ModelError(f"--imu-noise {rec.path}: recorded at {rec.rate_hz:g} Hz, the simulator runs at "
                         f"{rate_hz:g} Hz; a recording is not resampled (that would change its noise spectrum): "
                         f"simulate at {rec.rate_hz:g} Hz")


def stretch_index(vehicle: int, earlier: int = 0, drives: int = 1) -> int:
    """The stretch index of the ``earlier``-th drive before the scored drive of ``vehicle`` (0-based) when every
    vehicle has ``drives`` drives: vehicle·drives + drives − 1 − earlier (module docstring; K = 1: the vehicle).

    Raises
    ------
    ModelError
        For ``drives`` < 1, a negative vehicle, or ``earlier`` outside 0 … drives − 1 (a method that learns on
        more earlier drives than the vehicle has stretches for).
    """
    if drives < 1:
        raise ModelError(f"--vehicle-drives must be >= 1, got {drives}")
    if vehicle < 0:
        raise ModelError(f"--imu-noise: drive index {vehicle} < 0 (seeds start at --seed0)")
    if not 0 <= earlier < drives:
        raise ModelError(f"--imu-noise with --vehicle-drives {drives}: the drive {earlier} before the scored one has "
                         f"no stretch of the recording (a vehicle replays {drives} stretch(es)); a method that "
                         f"learns on {earlier} earlier drive(s) needs --vehicle-drives {earlier + 1} or more")
    return vehicle * drives + drives - 1 - earlier


def stretch(rec: NoiseRecording, index: int, n: int, rate_hz: float, *, reserve_s: float = 0.0,
            earlier: int = 0, drives: int = 1) -> tuple[int, int]:
    """Samples [a, b) of drive ``index`` (0-based; with ``drives`` > 1 the vehicle, and ``earlier`` the drive's
    place before the vehicle's scored drive, :func:`stretch_index`) for a drive of ``n`` samples at ``rate_hz``:
    a = i·n, b = a + n with i the stretch index, never reaching into the last ``reserve_s`` seconds (the denial
    experiment's static part).

    Raises
    ------
    ModelError
        For another rate than the recording's, a negative index, an ``earlier`` drive the vehicle has no stretch
        for, or a stretch past the usable samples (saying how many drives, or vehicles, of this length fit).
    """
    _check_rate(rec, rate_hz)
    usable = rec.n - int(round(reserve_s * rec.rate_hz))
    i = stretch_index(index, earlier, drives)
    a, b = i * n, (i + 1) * n
    if b > usable:
        fit = max(usable // n, 0)
        kept = f", the last {reserve_s:.0f} s kept for the static recording" if reserve_s else ""
        if drives == 1:
            raise ModelError(f"--imu-noise {rec.path}: drive {index + 1} needs samples [{a}, {b}) but "
                             f"{usable} are usable ({rec.n / rec.rate_hz:.0f} s recorded{kept}); "
                             f"{fit} drive(s) of {n / rate_hz:.0f} s fit: use --seeds ≤ {fit} or shorter drives")
        raise ModelError(f"--imu-noise {rec.path} with --vehicle-drives {drives}: vehicle {index + 1} needs samples "
                         f"[{a}, {b}) (its {drives} drives take {drives} disjoint stretches of {n / rate_hz:.0f} s) "
                         f"but {usable} are usable ({rec.n / rec.rate_hz:.0f} s recorded{kept}); {fit} drive(s) fit, "
                         f"{fit // drives} vehicle(s): use --seeds ≤ {fit // drives}, fewer --vehicle-drives or a "
                         "shorter --duration")
    return a, b


def drive_samples(duration_s: float, rate_hz: float) -> int:
    """IMU samples of a simulated drive of ``duration_s`` at ``rate_hz`` (τ = 0, dt, …, duration, as
    :func:`imunoise.sim.drive.simulate_drive` makes them): the length of its stretch."""
    return int(round(duration_s * rate_hz)) + 1


def check_vehicles(path: str, first: int, seeds: list[int], drives: int, duration_s: float, rate_hz: float,
                   reserve_s: float = 0.0) -> None:
    """Refuse, before any drive is simulated, a run whose vehicles (``seeds``, ``drives`` drives each) do not all
    fit in the recording at ``path`` (the one-line message of :func:`stretch`)."""
    if not seeds:
        return
    rec = load_recording(path)
    v = max(int(s) for s in seeds) - int(first)
    stretch(rec, v, drive_samples(duration_s, rate_hz), rate_hz, reserve_s=reserve_s, drives=drives)


def static_part(rec: NoiseRecording, seconds: float, rate_hz: float) -> np.ndarray:
    """The last ``seconds`` of the recording (the denial experiment's static recording, which no drive uses)."""
    _check_rate(rec, rate_hz)
    m = int(round(seconds * rec.rate_hz))
    if not 0 < m < rec.n:
        raise ModelError(f"--imu-noise {rec.path}: a static part of {seconds:g} s does not fit in "
                         f"{rec.n / rec.rate_hz:.0f} s (use --static-hours below that)")
    return rec.errors[rec.n - m:]
