"""Dataset folders described by a ``dataset.json`` manifest (docs/guide/theory.rst, 'Interfaces').

``{"name", "imu", "imu_kind": "increments"|"rates", "gnss", "ref" (optional), "outages" (optional),
"lever_arm_m": [x, y, z], "imu_time_offset_s", "license"}``; paths are relative to the folder holding the
manifest. Other keys are kept in ``extra`` (e.g. ``imu_rate_hz``, notes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from imunoise.errors import DataError
from imunoise.io.files import read_json

__all__ = ["Dataset", "read_dataset", "MANIFEST"]

MANIFEST = "dataset.json"
_KNOWN = {"name", "imu", "imu_kind", "gnss", "ref", "outages", "lever_arm_m", "imu_time_offset_s", "license"}


@dataclass(frozen=True)
class Dataset:
    """A resolved dataset manifest: absolute paths, lever arm (body FRD, m), IMU time offset (s)."""

    root: Path
    name: str
    imu: Path
    gnss: Path | None
    imu_kind: str = "increments"
    ref: Path | None = None
    outages: Path | None = None
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_time_offset_s: float = 0.0
    license: str = ""
    extra: dict = field(default_factory=dict)


def read_dataset(path: str | Path, required: tuple[str, ...] = ("imu", "gnss")) -> Dataset:
    """Read and validate ``dataset.json`` in folder ``path`` (or the manifest file itself).

    Parameters
    ----------
    path : str or Path
        The dataset folder or its manifest.
    required : tuple of str
        Keys the manifest must name (navigation needs IMU and GNSS; static detection only the IMU).

    Returns
    -------
    Dataset
        Absolute paths (None for an absent optional file) and the checked values.

    Raises :class:`DataError` for a missing manifest, missing required keys, files that do not exist,
    or malformed values.
    """
    p = Path(path)
    manifest = p / MANIFEST if p.is_dir() else p
    if not manifest.exists():
        raise DataError(f"no {MANIFEST} in {p}; a dataset folder needs a manifest "
                        f"(docs/guide/theory.rst, 'Interfaces')")
    d = read_json(manifest, "dataset manifest")  # binary / malformed -> DataError naming the file
    if not isinstance(d, dict):
        raise DataError(f"{manifest}: the manifest must be a JSON object")
    root = manifest.parent.resolve()
    missing = [k for k in required if not d.get(k)]
    if missing:
        raise DataError(f"{manifest}: missing required key(s) {missing} (paths relative to the folder)")

    def resolve(key: str) -> Path | None:
        v = d.get(key)
        if v in (None, ""):
            return None
        if not isinstance(v, str):
            raise DataError(f"{manifest}: '{key}' must be a path string, got {v!r}")
        f = (root / v).resolve()
        if not f.exists():
            raise DataError(f"{manifest}: '{key}' file {f} does not exist")
        return f

    kind = d.get("imu_kind", "increments")
    if kind not in ("increments", "rates"):
        raise DataError(f"{manifest}: imu_kind must be 'increments' or 'rates', got {kind!r}")
    lever = d.get("lever_arm_m", [0.0, 0.0, 0.0])
    try:
        lever_t = tuple(float(x) for x in lever)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{manifest}: lever_arm_m must be three numbers [x, y, z] m, got {lever!r}") from exc
    if len(lever_t) != 3 or not all(math.isfinite(x) for x in lever_t):
        raise DataError(f"{manifest}: lever_arm_m must be three finite numbers [x, y, z] m, got {lever!r}")
    try:
        offset = float(d.get("imu_time_offset_s", 0.0))
    except (TypeError, ValueError) as exc:
        raise DataError(f"{manifest}: imu_time_offset_s must be a number (s)") from exc
    if not math.isfinite(offset):
        raise DataError(f"{manifest}: imu_time_offset_s must be finite")
    return Dataset(
        root=root,
        name=str(d.get("name", root.name)),
        imu=resolve("imu"),
        gnss=resolve("gnss"),
        imu_kind=kind,
        ref=resolve("ref"),
        outages=resolve("outages"),
        lever_arm_m=lever_t,  # type: ignore[arg-type]
        imu_time_offset_s=offset,
        license=str(d.get("license", "")),
        extra={k: v for k, v in d.items() if k not in _KNOWN},
    )
