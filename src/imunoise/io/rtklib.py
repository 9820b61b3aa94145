"""RTKLIB position solutions (``.pos``, rnx2rtkp / RTKPOST / RTKNAVI output) as GNSS input of the navigator.

What is read (RTKLIB's ``outsolheads``/``outpos``; the ``%`` header lines say which variant):

- time: ``yyyy/mm/dd hh:mm:ss.sss`` or ``week tow``, in the time system named at the start of the column
  header line (``%  GPST ...``, ``%  UTC ...`` or ``%  JST ...``); converted to GPS seconds of week (GPST,
  the time base of the KF-GINS files, :mod:`imunoise.io.gpstime`). UTC/JST use the leap seconds at the first
  epoch. Without a column header the file is read as GPST, degrees, with a warning.
- position: ``latitude(deg) longitude(deg)`` (decimal degrees) or ``latitude(d'") longitude(d'")`` (three
  tokens each: degrees, minutes, seconds, the sign on the degrees); ``height(m)`` ellipsoidal. ECEF and
  baseline (ENU) solutions are refused: export lat/lon/height.
- ``Q`` the solution quality (1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP): epochs with ``Q`` above
  ``max_quality`` are skipped and counted.
- ``sdn sde sdu`` [m] → σ N, E, D (σD = σU); σ below ``sigma_floor`` is raised to it, as for the KF-GINS
  GNSS file. The covariance terms, age, ratio and velocities are ignored.
"""

from __future__ import annotations

import calendar
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imunoise.errors import DataError
from imunoise.io.files import is_number, read_text
from imunoise.io.gpstime import GPS_EPOCH_UNIX, SECONDS_PER_WEEK, gps_minus_utc, gps_week
from imunoise.io.kfgins import DataWarning, GnssData

__all__ = ["POS_SUFFIX", "QUALITY_NAMES", "PosSolution", "is_pos", "read_pos"]

POS_SUFFIX = ".pos"
QUALITY_NAMES = {1: "fix", 2: "float", 3: "sbas", 4: "dgps", 5: "single", 6: "ppp"}
"""RTKLIB solution status ``Q`` (``SOLQ_*`` in rtklib.h)."""

_TIME_SYSTEMS = ("GPST", "UTC", "JST")
_JST_MINUS_UTC_S = 9 * 3600


def is_pos(path: str | Path) -> bool:
    """True for an RTKLIB solution file (``.pos``, or ``.pos.gz``)."""
    name = Path(path).name.lower()
    return name.endswith(POS_SUFFIX) or name.endswith(POS_SUFFIX + ".gz")


@dataclass(frozen=True, eq=False)
class PosSolution:
    """An RTKLIB solution: ``sow`` GPS seconds of ``week`` (the first epoch's; later weeks continue past
    604800 s), ``llh`` [lat rad, lon rad, h m], ``sigma_ned`` [m], ``quality`` (Q), and what was skipped;
    ``time_system`` as the file states it. Seconds of week rather than seconds since 1980 keep 0.1 ns in a
    float64."""

    path: str
    week: int
    sow: np.ndarray
    llh: np.ndarray
    sigma_ned: np.ndarray
    quality: np.ndarray
    time_system: str
    dms: bool
    n_skipped: int
    skipped_by_quality: dict[int, int]

    def to_gnssdata(self, week: int | None = None) -> GnssData:
        """The fixes as :class:`GnssData` with ``t`` in GPS seconds of ``week`` (default: the first epoch's
        week; later weeks continue past 604800 s so a run crossing Sunday 00:00 GPST stays monotonic)."""
        w = self.week if week is None else int(week)
        return GnssData(self.sow + (self.week - w) * SECONDS_PER_WEEK, self.llh, self.sigma_ned)


def _header_info(lines: list[str]) -> tuple[str | None, bool | None]:
    """(time system, dms) from the column header line, or (None, None) without one."""
    for line in lines:
        if not line.startswith("%"):
            continue
        if "x-ecef(m)" in line or "e-baseline(m)" in line:
            raise DataError(
                "RTKLIB solution in ECEF or as a baseline (ENU): export lat/lon/height instead "
                "(RTKPOST Options → Output → Solution Format: Lat/Lon/Height)"
            )
        if "latitude(" in line:
            tokens = line.lstrip("%").split()
            system = tokens[0] if tokens and tokens[0] in _TIME_SYSTEMS else None
            if system is None:
                raise DataError(f"RTKLIB column header {line.strip()!r}: time system not GPST, UTC or JST")
            return system, "latitude(d'" in line
    return None, None


def _dms(tokens: list[str]) -> float:
    """Degrees from ``d m s`` tokens; the sign is on the degrees (``-0 05 12.3`` is negative too)."""
    sign = -1.0 if tokens[0].lstrip().startswith("-") else 1.0
    return sign * (abs(float(tokens[0])) + float(tokens[1]) / 60.0 + float(tokens[2]) / 3600.0)


def _epoch_seconds(date: str, clock: str) -> tuple[int, float]:
    """``yyyy/mm/dd`` ``hh:mm:ss.sss`` → (whole seconds since 1970-01-01 of that calendar, fraction)."""
    y, mo, d = (int(x) for x in date.replace("-", "/").split("/"))
    h, mi, s = clock.split(":")
    whole = int(float(s) // 1)
    return calendar.timegm((y, mo, d, int(h), int(mi), 0)) + whole, float(s) - whole


def _parse_row(tokens: list[str], dms: bool) -> tuple[int, float, bool, float, float, float, int, float, float, float]:
    """(whole s, fraction s, is calendar time, lat deg, lon deg, h, Q, sdn, sde, sdu) of one solution line;
    the time is split so that no float holds seconds since an epoch decades ago."""
    calendar_time = "/" in tokens[0] or "-" in tokens[0][1:]
    if calendar_time:
        whole, frac = _epoch_seconds(tokens[0], tokens[1])
    else:
        tow = float(tokens[1])
        whole, frac = int(tokens[0]) * SECONDS_PER_WEEK + int(tow // 1), tow - tow // 1
    k = 2
    if dms:
        lat, lon = _dms(tokens[k : k + 3]), _dms(tokens[k + 3 : k + 6])
        k += 6
    else:
        lat, lon = float(tokens[k]), float(tokens[k + 1])
        k += 2
    h, q = float(tokens[k]), int(float(tokens[k + 1]))
    sdn, sde, sdu = (float(x) for x in tokens[k + 3 : k + 6])
    return whole, frac, calendar_time, lat, lon, h, q, sdn, sde, sdu


def read_pos(path: str | Path, *, max_quality: int = 6, sigma_floor: float = 1e-3) -> PosSolution:
    """Read an RTKLIB ``.pos`` lat/lon/height solution (module docstring for the layout and time rule).

    Parameters
    ----------
    path : str or Path
        The solution file (``.gz`` is decompressed).
    max_quality : int
        Keep epochs with ``Q ≤ max_quality`` (1 = fixed only, 2 = fix + float, 6 = all); the others are
        skipped and counted (a :class:`~imunoise.io.kfgins.DataWarning` says how many of each kind).
    sigma_floor : float
        Smallest σ kept [m] (RTKLIB writes 0 for some solution types).

    Returns
    -------
    PosSolution
        Times in GPS seconds since the GPS epoch; use :meth:`PosSolution.to_gnssdata` for the navigator.

    Raises
    ------
    DataError
        ECEF/ENU solutions, malformed lines (naming the line), fewer than 2 epochs left, time going back.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    if not 1 <= int(max_quality) <= 6:
        raise DataError(f"--min-quality must be an RTKLIB Q between 1 (fix) and 6 (ppp), got {max_quality}")
    lines = read_text(path, "RTKLIB solution file").splitlines()
    system, dms = _header_info(lines)
    if system is None:
        warnings.warn(
            f"RTKLIB file {path} has no '%  GPST latitude(deg) ...' column header; read as GPST, degrees",
            DataWarning,
            stacklevel=2,
        )
        system, dms = "GPST", False
    rows = []
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("%"):
            continue
        tokens = s.split()
        need = 2 + (6 if dms else 2) + 6
        if len(tokens) < need or not all(is_number(x) for x in tokens[2:need]):
            raise DataError(
                f"RTKLIB file {path}, line {i}: expected time, lat, lon, height, Q, ns, sdn, sde, sdu "
                f"({'d m s' if dms else 'degrees'}), got {s[:80]!r}"
            )
        try:
            rows.append(_parse_row(tokens, bool(dms)))
        except ValueError as exc:
            raise DataError(f"RTKLIB file {path}, line {i}: cannot read the time {tokens[0]} {tokens[1]}") from exc
    if not rows:
        raise DataError(f"RTKLIB file {path} has no solution lines")
    whole = np.array([r[0] for r in rows], dtype=np.int64)
    frac = np.array([r[1] for r in rows])
    arr = np.array([r[3:] for r in rows], dtype=float)  # lat, lon, h, Q, sdn, sde, sdu
    shift = -_JST_MINUS_UTC_S if system == "JST" else 0
    if rows[0][2]:  # calendar time: seconds since 1970-01-01 of the file's own calendar
        shift -= GPS_EPOCH_UNIX
        if system != "GPST":
            shift += gps_minus_utc(float(whole[0] - (_JST_MINUS_UTC_S if system == "JST" else 0)))
    elif system != "GPST":  # week + tow written in UTC/JST: the same count, shifted
        shift += gps_minus_utc(float(whole[0] + shift + GPS_EPOCH_UNIX))
    gps_whole = whole + shift
    week = gps_week(float(gps_whole[0]))
    sow = (gps_whole - week * SECONDS_PER_WEEK).astype(float) + frac
    q = arr[:, 3].astype(int)
    keep = q <= int(max_quality)
    skipped = {int(k): int(np.count_nonzero(q[~keep] == k)) for k in np.unique(q[~keep])}
    n_skipped = int((~keep).sum())
    if n_skipped:
        kinds = ", ".join(f"{n} {QUALITY_NAMES.get(k, f'Q={k}')}" for k, n in skipped.items())
        warnings.warn(
            f"RTKLIB file {path}: skipped {n_skipped} of {q.size} epochs with Q > {max_quality} ({kinds})",
            DataWarning,
            stacklevel=2,
        )
    if np.count_nonzero(keep) < 2:
        raise DataError(f"RTKLIB file {path}: {int(np.count_nonzero(keep))} epoch(s) with Q ≤ {max_quality}; "
                        "raise --min-quality")
    sow, arr, q = sow[keep], arr[keep], q[keep]
    back = np.flatnonzero(np.diff(sow) <= 0)
    if back.size:
        raise DataError(
            f"RTKLIB file {path}: time does not increase at epoch {int(back[0]) + 1} "
            f"({sow[back[0]]:.3f} → {sow[back[0] + 1]:.3f} s of GPS week {week}); sort the file or remove "
            "repeated epochs"
        )
    sigma = arr[:, 4:7]
    if (sigma < 0).any() or not np.isfinite(arr).all():
        raise DataError(f"RTKLIB file {path}: negative or non-finite σ/position values; check the file")
    low = sigma < sigma_floor
    if low.any():
        warnings.warn(
            f"RTKLIB file {path}: {int(low.any(axis=1).sum())} epochs with σ < {sigma_floor:g} m; raised to "
            f"{sigma_floor:g} m",
            DataWarning,
            stacklevel=2,
        )
    llh = np.column_stack([np.radians(arr[:, 0]), np.radians(arr[:, 1]), arr[:, 2]])
    return PosSolution(
        path=str(path),
        week=week,
        sow=sow,
        llh=llh,
        sigma_ned=np.maximum(sigma, sigma_floor),
        quality=q,
        time_system=system,
        dms=bool(dms),
        n_skipped=n_skipped,
        skipped_by_quality=skipped,
    )
