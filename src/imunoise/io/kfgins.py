"""Readers and writers for the KF-GINS text formats (docs/guide/theory.rst, 'Conventions' and 'Interfaces').

Formats (whitespace separated, ``#`` comments, gzip when the name ends in ``.gz``):

- IMU increments: ``t dθx dθy dθz dvx dvy dvz`` — seconds, rad, m/s; increments over (t_{k-1}, t_k].
  :func:`read_imu` also reads the rate CSV with the header ``sow,gx,gy,gz,ax,ay,az`` (rad/s, m/s²) and
  converts it to increments as rate·Δt_k with Δt_k = t_k − t_{k-1} (the first Δt is the median).
- GNSS: ``t lat lon h σN σE σD`` — seconds, degrees, degrees, m, m (4 columns → default σ, warned).
- Reference / result: ``week t lat lon h vN vE vD roll pitch yaw`` — degrees on disk, NaN attitude allowed.
- Outage windows: ``start duration`` per line (docs/guide/theory.rst, 'Navigation filter').

Inside, everything is SI (radians, m, m/s, s). Time checks on every reader: time going backwards or a
NaN/Inf value raises :class:`~imunoise.errors.DataError` naming the file line; duplicated stamps are
dropped (the first kept) with a :class:`DataWarning` giving their count; gaps longer than
``gap_factor`` × the median step are reported with a :class:`DataWarning` (count and largest gap).

The writers live in :mod:`imunoise.io.kfgins_write` and are importable from here.
"""

from __future__ import annotations

import io
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from imunoise.errors import DataError, DataWarning
from imunoise.imu import LEGACY_AXES, ImuData  # ImuData: re-exported, its old home
from imunoise.io.files import is_number, read_text
from imunoise.io.kfgins_records import GnssData, Reference
from imunoise.io.kfgins_write import write_gnss, write_imu, write_outages, write_reference
from imunoise.io.navchecks import check_gnss_llh

__all__ = [
    "DataWarning",
    "ImuData",
    "GnssData",
    "Reference",
    "read_imu",
    "read_gnss",
    "read_reference",
    "read_outages",
    "write_imu",
    "write_gnss",
    "write_reference",
    "write_outages",
    "DEFAULT_GNSS_SIGMA_M",
]

DEFAULT_GNSS_SIGMA_M = (1.0, 1.0, 2.0)
"""σ (N, E, D) in m used when a GNSS file has only ``t lat lon h``."""

GAP_FACTOR = 5.0
"""A time step longer than this many median steps is reported as a gap (issue 4: gaps > 5 samples)."""


# ----------------------------------------------------------------------------------------------
# low-level text handling
# ----------------------------------------------------------------------------------------------


def _read_table(path: str | Path, what: str) -> tuple[list[str] | None, np.ndarray, np.ndarray]:
    """Read a numeric text table: (header tokens or None, data (n, m), 1-based file line of each row).

    Blank lines and ``#`` comments (whole-line or trailing) are skipped; a first line whose tokens are
    not all numbers is a header. Commas or whitespace separate columns.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    text = read_text(path, f"{what} file")  # binary / truncated .gz -> DataError naming the file
    data = _plain_table(text)
    if data is not None:
        return None, data, np.arange(1, data.shape[0] + 1, dtype=np.int64)
    raw = text.splitlines()
    rows: list[str] = []
    lines: list[int] = []
    header: list[str] | None = None
    sep: str | None = None
    for i, line in enumerate(raw, start=1):
        s = line.split("#", 1)[0].strip()
        if not s:
            continue
        if sep is None:
            sep = "," if "," in s else ""
        toks = [x.strip() for x in s.split(",")] if sep else s.split()
        if not rows and header is None and not all(is_number(x) for x in toks):
            header = [x.lower() for x in toks]
            continue
        rows.append(" ".join(toks) if sep else s)
        lines.append(i)
    if not rows:
        raise DataError(f"{what} file {path} has no data rows")
    line_no = np.asarray(lines, dtype=np.int64)
    ncols = np.fromiter((len(r.split()) for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(ncols != ncols[0])
    if bad.size:
        k = bad[0]
        raise DataError(
            f"{what} file {path}, line {line_no[k]}: {ncols[k]} columns where the first row has {ncols[0]}; "
            "fix or remove the malformed line"
        )
    try:
        data = np.array(" ".join(rows).split(), dtype=float).reshape(len(rows), int(ncols[0]))
    except ValueError as exc:
        for k, r in enumerate(rows):
            if not all(is_number(x) for x in r.split()):
                line = raw[line_no[k] - 1]
                if re.search(r"\d,\d", line) and re.search(r"[;\t]", line):  # 1,25;3,5 (a spreadsheet locale)
                    raise DataError(f"{what} file {path}, line {line_no[k]}: decimal commas ({line.strip()[:40]!r}): "
                                    "this file takes '.' as the decimal mark and commas or spaces between "
                                    "columns; export it with '.' decimals") from exc
                raise DataError(f"{what} file {path}, line {line_no[k]}: non-numeric value in {r!r}") from exc
        raise DataError(f"{what} file {path}: cannot parse numbers ({exc})") from exc
    return header, data, line_no


def _plain_table(text: str) -> np.ndarray | None:
    """The common case read by numpy's C parser: whitespace-separated numbers on every line, no header, no
    comment, no blank line, the same column count everywhere (so the file line of row k is k + 1). None
    otherwise: :func:`_read_table`'s line-by-line path then reads it and names any bad line. Both parse each
    number to the nearest double, so the values are the same."""
    if not text.strip() or "#" in text or "," in text:
        return None
    n_lines = text.count("\n") + (0 if text.endswith("\n") else 1)
    try:
        data = np.loadtxt(io.StringIO(text), dtype=float, ndmin=2)
    except ValueError:
        return None
    return data if data.shape[0] == n_lines else None


def _check_finite(data: np.ndarray, lines: np.ndarray, path: Path, what: str, cols: Sequence[int]) -> None:
    bad = ~np.isfinite(data[:, list(cols)]).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"{what} file {path}, line {lines[k]} (data row {k + 1}): NaN or Inf value "
            f"({int(bad.sum())} such rows); remove or repair these rows"
        )


def _check_time(t: np.ndarray, lines: np.ndarray, path: Path, what: str, gap_factor: float = GAP_FACTOR) -> np.ndarray:
    """Return the mask of rows to keep; raise on backwards time; warn on duplicates and gaps."""
    keep = np.ones(t.size, dtype=bool)
    if t.size < 2:
        return keep
    d = np.diff(t)
    back = np.flatnonzero(d < 0)
    if back.size:
        k = int(back[0]) + 1
        raise DataError(
            f"{what} file {path}, line {lines[k]}: time goes backwards ({t[k - 1]!r} -> {t[k]!r} s, "
            f"{back.size} such steps); sort the file or remove the out-of-order rows"
        )
    dup = np.flatnonzero(d == 0) + 1
    if dup.size:
        keep[dup] = False
        warnings.warn(
            f"{what} file {path}: dropped {dup.size} rows with a duplicated time stamp "
            f"(first at line {lines[dup[0]]}, t = {t[dup[0]]!r} s); the first of each duplicate was kept",
            DataWarning,
            stacklevel=3,
        )
    d = d[d > 0]
    if d.size:
        med = float(np.median(d))
        gaps = d[d > gap_factor * med]
        if gaps.size:
            warnings.warn(
                f"{what} file {path}: {gaps.size} time gaps longer than {gap_factor:g} × the median step "
                f"{med:.6g} s; the largest is {gaps.max():.6g} s",
                DataWarning,
                stacklevel=3,
            )
    return keep


# ----------------------------------------------------------------------------------------------
# readers
# ----------------------------------------------------------------------------------------------

_RATE_COLS = tuple(LEGACY_AXES)  # the rate CSV header names the axes the short way: sow,gx,...,az
_TIME_NAMES = ("sow", "t", "time", "timestamp", "gps_time", "tow")


def read_imu(
    path: str | Path, *, time_offset: float = 0.0, gap_factor: float = GAP_FACTOR, time_unit: str = "s"
) -> ImuData:
    """Read IMU samples as increments (body FRD, SI).

    Accepts the KF-GINS increment format (7 columns, no header: ``t dθxyz [rad] dvxyz [m/s]``; extra
    columns such as an odometer are ignored with a warning) or a
    rate CSV with a header naming ``sow`` (or ``t``/``time``) and ``gx,gy,gz`` [rad/s], ``ax,ay,az``
    [m/s²] in any order; rates become increments rate·Δt_k (first Δt = median), docs/guide/theory.rst, 'Conventions'.
    ``time_offset`` [s] is added to every stamp (e.g. a logging delay).

    Parameters
    ----------
    path : str or Path
        The file (``.gz`` is decompressed).
    time_offset : float
        Added to every stamp [s].
    gap_factor : float
        Gaps longer than this many median steps are reported with a :class:`DataWarning`.
    time_unit : str
        Unit of the file's stamps (s, ms, us, ns; the format's is s), converted to s before anything else.

    Returns
    -------
    ImuData
        Increments, body FRD.

    Raises
    ------
    DataError
        For an unknown layout, non-finite values, fewer than 2 samples or time going backwards (naming the
        line).
    """
    path = Path(path)
    header, data, lines = _read_table(path, "IMU")
    if header is not None:
        cols = {name: i for i, name in enumerate(header)}
        tcol = next((cols[n] for n in _TIME_NAMES if n in cols), None)
        missing = [c for c in _RATE_COLS if c not in cols]
        if tcol is None or missing:
            raise DataError(
                f"IMU file {path}: header {header} lacks "
                f"{'a time column (sow/t/time) ' if tcol is None else ''}{missing or ''}; expected "
                "'sow,gx,gy,gz,ax,ay,az' (rad/s, m/s²) or the 7-column KF-GINS increment format "
                "without header"
            )
        idx = [tcol] + [cols[c] for c in _RATE_COLS]
        _check_finite(data, lines, path, "IMU", idx)
        data, kind = data[:, idx], "rates"
    else:
        if data.shape[1] < 7:
            raise DataError(
                f"IMU file {path}: {data.shape[1]} columns; the KF-GINS IMU format has 7 "
                "(t dθx dθy dθz dvx dvy dvz), or give a CSV with header sow,gx,gy,gz,ax,ay,az"
            )
        if data.shape[1] > 7:  # e.g. KF-GINS files with an odometer column
            warnings.warn(
                f"IMU file {path}: {data.shape[1]} columns; using the first 7 (t dθxyz dvxyz), ignoring the rest",
                DataWarning,
                stacklevel=2,
            )
            data = data[:, :7]
        _check_finite(data, lines, path, "IMU", range(7))
        kind = "increments"
    if data.shape[0] < 2:
        raise DataError(f"IMU file {path}: need at least 2 samples, got {data.shape[0]}")
    if time_unit != "s":
        from imunoise.units import TIME_UNITS

        data[:, 0] *= TIME_UNITS[time_unit]  # before the rates become increments rate·Δt
    keep = _check_time(data[:, 0], lines, path, "IMU", gap_factor)
    data = data[keep]
    imu = ImuData(t=data[:, 0] + float(time_offset), dtheta=data[:, 1:4], dv=data[:, 4:7], kind=kind)
    return imu.as_increments()


def read_gnss(
    path: str | Path,
    *,
    default_sigma: Sequence[float] = DEFAULT_GNSS_SIGMA_M,
    sigma_floor: float = 1e-3,
    gap_factor: float = GAP_FACTOR,
) -> GnssData:
    """Read GNSS fixes ``t lat[deg] lon[deg] h[m] σN σE σD [m]`` (KF-GINS; extra columns ignored).

    With 4 columns the σ are ``default_sigma`` (warned). σ below ``sigma_floor`` (including 0) is raised
    to the floor with a warning so the filter's R stays positive definite; negative σ is an error.

    Parameters
    ----------
    path : str or Path
        The file (``.gz`` is decompressed).
    default_sigma : sequence of float
        σ N, E, D [m] for a file without σ columns.
    sigma_floor : float
        Smallest σ kept [m].
    gap_factor : float
        Gaps longer than this many median steps are reported with a :class:`DataWarning`.

    Returns
    -------
    GnssData
        Times [s], antenna latitude/longitude [rad] and height [m], σ NED [m].

    Raises
    ------
    DataError
        For too few columns, non-finite values, negative σ or time going backwards (naming the line).
    """
    path = Path(path)
    _, data, lines = _read_table(path, "GNSS")
    ncol = data.shape[1]
    if ncol == 4:
        warnings.warn(
            f"GNSS file {path} has no σ columns; using default σ N/E/D = {tuple(default_sigma)} m",
            DataWarning,
            stacklevel=2,
        )
        data = np.column_stack([data, np.tile(np.asarray(default_sigma, float), (data.shape[0], 1))])
    elif ncol < 7:
        raise DataError(f"GNSS file {path}: {ncol} columns; expected 7 (t lat lon h σN σE σD) or 4 (t lat lon h)")
    _check_finite(data, lines, path, "GNSS", range(7))
    check_gnss_llh(data[:, 1], data[:, 2], str(path), lines)  # degrees of a real place, not radians
    sig = data[:, 4:7]
    if (sig < 0).any():
        k = int(np.flatnonzero((sig < 0).any(axis=1))[0])
        raise DataError(f"GNSS file {path}, line {lines[k]}: negative σ; σ columns must be ≥ 0 m")
    low = sig < sigma_floor
    if low.any():
        warnings.warn(
            f"GNSS file {path}: {int(low.any(axis=1).sum())} epochs with σ < {sigma_floor:g} m "
            f"(first at line {lines[int(np.flatnonzero(low.any(axis=1))[0])]}); raised to {sigma_floor:g} m",
            DataWarning,
            stacklevel=2,
        )
    keep = _check_time(data[:, 0], lines, path, "GNSS", gap_factor)
    data = data[keep]
    llh = np.column_stack([np.radians(data[:, 1]), np.radians(data[:, 2]), data[:, 3]])
    return GnssData(t=data[:, 0], llh=llh, sigma_ned=np.maximum(data[:, 4:7], sigma_floor))


def read_reference(path: str | Path, *, gap_factor: float = GAP_FACTOR) -> Reference:
    """Read a reference/result trajectory ``week t lat lon h vN vE vD roll pitch yaw`` (degrees on disk;
    NaN roll/pitch/yaw allowed, NaN elsewhere is an error)."""
    path = Path(path)
    _, data, lines = _read_table(path, "reference")
    if data.shape[1] != 11:
        raise DataError(
            f"reference file {path}: {data.shape[1]} columns; expected 11 (week t lat lon h vN vE vD roll pitch yaw)"
        )
    _check_finite(data, lines, path, "reference", range(8))
    if np.isinf(data[:, 8:11]).any():
        _check_finite(data, lines, path, "reference", range(8, 11))
    keep = _check_time(data[:, 1], lines, path, "reference", gap_factor)
    data = data[keep]
    llh = np.column_stack([np.radians(data[:, 2]), np.radians(data[:, 3]), data[:, 4]])
    return Reference(
        t=data[:, 1],
        llh=llh,
        vel_ned=data[:, 5:8],
        euler=np.radians(data[:, 8:11]),
        week=np.round(data[:, 0]).astype(int),
    )


def read_outages(path: str | Path) -> list[tuple[float, float]]:
    """Outage windows ``start duration`` [s] per line, ``#`` comments allowed
    (docs/guide/theory.rst, 'Navigation filter')."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    out: list[tuple[float, float]] = []
    for i, line in enumerate(read_text(path, "outage file").splitlines(), start=1):
        s = line.split("#", 1)[0].replace(",", " ").split()
        if not s:
            continue
        if len(s) != 2 or not all(is_number(x) for x in s):
            raise DataError(f"outage file {path}, line {i}: expected 'start duration' in s, got {line.strip()!r}")
        start, dur = float(s[0]), float(s[1])
        if not (np.isfinite(start) and np.isfinite(dur)) or dur <= 0:
            raise DataError(f"outage file {path}, line {i}: need finite start and duration > 0, got {line.strip()!r}")
        out.append((start, dur))
    return out
