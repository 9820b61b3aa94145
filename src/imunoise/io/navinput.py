"""The IMU and GNSS inputs of a navigation run from whatever file holds them (docs/guide/theory.rst, 'Interfaces'):
KF-GINS text files,
ROS bags (ROS 1 ``.bag``, ROS 2 ``.db3`` / ``.mcap`` / folder, :mod:`imunoise.io.rosbag`) and RTKLIB ``.pos``
solutions (:mod:`imunoise.io.rtklib`), all leaving as :class:`~imunoise.imu.ImuData` increments in body FRD and
:class:`~imunoise.io.kfgins.GnssData` in one time base.

Time base: GPS seconds of week, as the KF-GINS files. Bag stamps at or above 1e9 s are Unix time (UTC, the
ROS convention) and are converted exactly in integer ns to GPS seconds of the week of the first IMU stamp
(GPST − UTC leap seconds, :mod:`imunoise.io.gpstime`); smaller stamps are taken as already in the data's time
base. A ``.pos`` is converted from its GPST/UTC/JST to GPS seconds of that same week (its own first week when
the IMU is a text file, whose stamps are already seconds of week).

IMU rates → increments: a bag holds rates [rad/s, m/s²] at the header stamps; they become increments over
(t_{k−1}, t_k] as rate_k · Δt_k with Δt_k = t_k − t_{k−1} (the first Δt the median step), the rule of the
KF-GINS rate CSV (:meth:`imunoise.imu.ImuData.as_increments`). So a bag written with rate_k = Δθ_k / Δt_k at the
exact stamps gives back the increments of a KF-GINS file to rounding.

Body frame: ROS uses FLU (x forward, y left, z up, REP 103), the filter FRD (docs/guide/theory.rst, 'Conventions'). FLU
→ FRD is diag(1, −1, −1) on both the gyro and the accelerometer. The default frame follows the source (bags: FLU;
KF-GINS text: FRD) and is checked: at rest the specific force points up, so FRD reads f_z ≈ −g and FLU
f_z ≈ +g over the first seconds; the other sign is refused with the option that fixes it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imunoise.errors import DataError
from imunoise.imu import ImuData
from imunoise.io.gpstime import (
    GPS_EPOCH_UNIX,
    SECONDS_PER_WEEK,
    UNIX_STAMP_MIN_S,
    gps_minus_utc,
    gps_week,
    unix_ns_to_gps_ns,
)
from imunoise.io.kfgins import DataWarning, GnssData, read_gnss, read_imu
from imunoise.io.navchecks import check_gnss_llh
from imunoise.io.rosbag import is_bag, read_imu_bag, read_navsat_bag, write_imu_bag
from imunoise.io.rtklib import is_pos, read_pos

__all__ = [
    "IMU_FRAMES",
    "FLU_TO_FRD",
    "FRAME_CHECK_S",
    "NavImu",
    "default_imu_frame",
    "check_imu_frame",
    "to_frd",
    "bag_stamps_to_seconds",
    "read_nav_imu",
    "read_nav_gnss",
    "write_nav_bag",
]

IMU_FRAMES = ("flu", "frd")
FLU_TO_FRD = np.array([1.0, -1.0, -1.0])
"""diag(1, −1, −1): FLU (REP 103) → FRD for gyro and accelerometer alike (a proper rotation by π about x)."""

FRAME_CHECK_S = 2.0
"""Seconds at the start of the IMU data whose mean specific force must point the way the frame says."""

_G = 9.80665


@dataclass(frozen=True, eq=False)
class NavImu:
    """IMU data for the filter (increments, FRD) and where its time base came from: ``week`` the GPS week its
    ``t`` counts from when bag stamps were converted from Unix time (None: stamps used as they are)."""

    imu: ImuData
    week: int | None
    source: str


def default_imu_frame(path: str | Path) -> str:
    """``"flu"`` for a ROS bag (REP 103), ``"frd"`` for anything else (the KF-GINS convention)."""
    return "flu" if is_bag(path) else "frd"


def check_imu_frame(imu: ImuData, frame: str, source: str, window_s: float = FRAME_CHECK_S) -> None:
    """Refuse IMU data whose mean specific force over the first ``window_s`` s points the other way than
    ``frame`` says (at rest f = −g_n: FRD f_z ≈ −g, FLU f_z ≈ +g). A mean f_z of magnitude below g/2 says nothing about
    the frame (sensor on its side, or moving) and is let through.

    Raises
    ------
    DataError
        One line naming the source, the value read and the ``--imu-frame`` that matches it.
    """
    if frame not in IMU_FRAMES:
        raise DataError(f"--imu-frame must be one of {', '.join(IMU_FRAMES)}, got {frame!r}")
    m = imu.t < imu.t[0] + window_s
    if np.count_nonzero(m) < 2:
        m = np.arange(imu.t.size) < 2
    dth, dv = imu.increments()
    fz = float(dv[m, 2].sum() / imu.dt[m].sum())
    if abs(fz) < 0.5 * _G:
        return
    actual = "frd" if fz < 0 else "flu"
    if actual != frame:
        raise DataError(
            f"the first {window_s:g} s of {source} read f_z = {fz:+.1f} m/s² which is {actual.upper()} "
            f"(z {'down' if actual == 'frd' else 'up'}), not {frame.upper()}; pass --imu-frame {actual}"
        )


def to_frd(imu: ImuData, frame: str) -> ImuData:
    """``imu`` with its axes in FRD: unchanged for ``"frd"``, y and z negated for ``"flu"``."""
    if frame == "frd":
        return imu
    if frame != "flu":
        raise DataError(f"--imu-frame must be one of {', '.join(IMU_FRAMES)}, got {frame!r}")
    return ImuData(imu.t, imu.dtheta * FLU_TO_FRD, imu.dv * FLU_TO_FRD, kind=imu.kind, frame="FRD")


def bag_stamps_to_seconds(stamp_ns: np.ndarray, week: int | None = None) -> tuple[np.ndarray, int | None, int]:
    """Bag stamps [ns] → seconds in the navigation time base (module docstring).

    Returns
    -------
    tuple
        (t [s], GPS week the seconds count from (None when the stamps were not Unix time), leap seconds used).
    """
    stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
    if stamp_ns.size == 0 or stamp_ns[0] < UNIX_STAMP_MIN_S * 1e9:
        return stamp_ns.astype(float) * 1e-9, None, 0
    gps_ns, leap = unix_ns_to_gps_ns(stamp_ns)
    if week is None:
        week = gps_week(float(gps_ns[0]) * 1e-9)
    # integer ns relative to the week first: the float then holds ~0.1 ns, not the 0.2 µs of Unix seconds
    return (gps_ns - np.int64(week) * SECONDS_PER_WEEK * 1_000_000_000).astype(float) * 1e-9, week, leap


def read_nav_imu(
    path: str | Path, *, topic: str | None = None, frame: str | None = None, time_offset: float = 0.0
) -> NavImu:
    """Read the IMU of a navigation run: a bag's ``sensor_msgs/Imu`` topic (rates → increments) or a KF-GINS
    file; checked against ``frame`` (default :func:`default_imu_frame`) and returned in FRD.

    Parameters
    ----------
    path : str or Path
        Bag or KF-GINS IMU file.
    topic : str, optional
        The bag topic; None takes the only ``sensor_msgs/Imu`` topic (the topics are listed otherwise).
    frame : {"flu", "frd"}, optional
        Body frame of the data.
    time_offset : float
        Seconds added to every stamp (after the time-base conversion).

    Returns
    -------
    NavImu
        Increments in FRD, the GPS week of a converted bag, a name for messages.
    """
    frame = default_imu_frame(path) if frame is None else frame
    if frame not in IMU_FRAMES:
        raise DataError(f"--imu-frame must be one of {', '.join(IMU_FRAMES)}, got {frame!r}")
    if not is_bag(path):
        if topic is not None:
            raise DataError(f"--imu-topic {topic} is for a ROS bag, but {path} is a text file")
        imu = read_imu(path, time_offset=time_offset)
        check_imu_frame(imu, frame, str(path))
        return NavImu(to_frd(imu, frame), None, str(path))
    bag = read_imu_bag(path, topic)
    t, week, leap = bag_stamps_to_seconds(bag.stamp_ns)
    if week is not None:
        warnings.warn(
            f"{path}:{bag.topic}: header stamps are Unix time (UTC); converted to GPS seconds of week {week} "
            f"(GPST − UTC = {leap} s)",
            DataWarning,
            stacklevel=2,
        )
    rates = ImuData(t + float(time_offset), bag.gyro, bag.accel, kind="rates", frame=frame.upper())
    imu = rates.as_increments()
    source = f"{path}:{bag.topic}"
    check_imu_frame(imu, frame, bag.topic)
    return NavImu(to_frd(imu, frame), week, source)


def read_nav_gnss(
    path: str | Path, *, topic: str | None = None, max_quality: int = 6, week: int | None = None
) -> GnssData:
    """Read the GNSS fixes of a navigation run: a bag's ``sensor_msgs/NavSatFix`` topic (fixes with status
    NO_FIX skipped and counted, σ from ``position_covariance``), an RTKLIB ``.pos`` (Q ≤ ``max_quality``) or a
    KF-GINS GNSS file; times in GPS seconds of ``week`` when the IMU's bag stamps were converted (see the module
    docstring).

    Raises
    ------
    DataError
        Options that do not fit the file (a topic for a text file, a quality for a bag), or the readers' errors.
    """
    if is_bag(path):
        if max_quality != 6:
            raise DataError(f"--min-quality is for an RTKLIB .pos file; {path} is a ROS bag (NO_FIX is always skipped)")
        fix = read_navsat_bag(path, topic)
        t, w, leap = bag_stamps_to_seconds(fix.stamp_ns, week)
        if w is not None and week is None:
            warnings.warn(
                f"{path}:{fix.topic}: header stamps are Unix time (UTC); converted to GPS seconds of week {w} "
                f"(GPST − UTC = {leap} s)",
                DataWarning,
                stacklevel=2,
            )
        check_gnss_llh(np.degrees(fix.llh[:, 0]), np.degrees(fix.llh[:, 1]), f"{path}:{fix.topic}")
        return GnssData(t, fix.llh, fix.sigma_ned)
    if topic is not None:
        raise DataError(f"--gnss-topic {topic} is for a ROS bag, but {path} is not one")
    if is_pos(path):
        gnss = read_pos(path, max_quality=max_quality).to_gnssdata(week)
        check_gnss_llh(np.degrees(gnss.llh[:, 0]), np.degrees(gnss.llh[:, 1]), str(path))
        return gnss
    if max_quality != 6:
        raise DataError(f"--min-quality is for an RTKLIB .pos file, but {path} is a KF-GINS GNSS file")
    return read_gnss(path)


def write_nav_bag(
    path: str | Path,
    imu: ImuData,
    gnss: GnssData,
    *,
    week: int | None = None,
    imu_topic: str = "/imu",
    gnss_topic: str = "/fix",
) -> Path:
    """Write KF-GINS-style IMU (FRD) and GNSS data as a ROS bag the way a ROS driver would record them:
    ``sensor_msgs/Imu`` rates in FLU and ``sensor_msgs/NavSatFix`` with σ as an ENU ``position_covariance``
    (format from the suffix, :func:`imunoise.io.rosbag.write_imu_bag`).

    Rates are Δθ_k / Δt_k and Δv_k / Δt_k (:meth:`ImuData.rates`, the inverse of the reader's rule), stamped at
    the exact t_k in ns, so :func:`read_nav_imu` gives the increments back to float rounding (≈1e-9 relative).
    With ``week`` the stamps are Unix time (UTC) of those GPS seconds of week, as a ROS recording's; without,
    the seconds of week themselves.

    Returns
    -------
    Path
        The bag (the storage file of a ROS 2 bag).
    """
    gyro, accel = imu.rates()
    shift = 0
    if week is not None:
        unix0 = int(week) * SECONDS_PER_WEEK + GPS_EPOCH_UNIX
        shift = (unix0 - gps_minus_utc(unix0 + float(imu.t[0]))) * 1_000_000_000
    cov = np.zeros((len(gnss), 9))
    cov[:, [0, 4, 8]] = gnss.sigma_ned[:, [1, 0, 2]] ** 2  # ROS: ENU
    navsat = (
        np.round(gnss.t * 1e9).astype(np.int64) + shift,
        np.degrees(gnss.llh[:, 0]),
        np.degrees(gnss.llh[:, 1]),
        gnss.llh[:, 2],
        cov,
    )
    stamps = np.round(imu.t * 1e9).astype(np.int64) + shift
    return write_imu_bag(
        path, stamps, gyro * FLU_TO_FRD, accel * FLU_TO_FRD, topic=imu_topic, navsat=navsat, navsat_topic=gnss_topic
    )
