"""Reading and checking what the shared options name: the series, the navigation inputs, ``--out``, the outage
windows and the learning window (issue "Trustworthy outputs" §3, §4; re-exported by :mod:`imunoise.cli.options`).

Not a command (no ``register``). Light at import (no numpy): the readers import what they need when they run.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imunoise.errors import DataError, ModelError

if TYPE_CHECKING:
    import numpy as np

# ---------------------------------------------------------------------------------------------------
# reading what the options name
# ---------------------------------------------------------------------------------------------------
def parse_units(text: str | None) -> str | dict[str, str] | None:
    """``--units`` as given: one unit for all columns, or ``group=unit,column=unit`` pairs as a dict."""
    if text is None or "=" not in text:
        return text
    return {k.strip(): v.strip() for k, v in (item.split("=", 1) for item in text.split(",") if item.strip())}


def imu_source(args: argparse.Namespace, path: Any, **override: Any) -> Any:
    """The :class:`~imunoise.io.imu_source.ImuSource` the reader options of a command name (``--topic``,
    ``--columns``, ``--units``, ``--time-column``, ``--time-unit``, ``--freq``, ``--stamps``: those it has) for
    ``path``; ``override`` replaces fields (e.g. a command's own reading of ``--columns``). An option the command
    lacks takes the ImuSource default."""
    from imunoise.io.imu_source import SOURCE_FIELDS, ImuSource

    given = {k: getattr(args, k) for k in SOURCE_FIELDS if k not in ("columns", "units") and hasattr(args, k)}
    if getattr(args, "units", None) is not None:
        given["units"] = parse_units(args.units)
    if getattr(args, "columns", None) is not None:
        from imunoise.io.tabular import parse_column_map

        given["columns"] = parse_column_map(args.columns)
    return ImuSource(path, **{**given, **override})


def check_freq(freq: float | None) -> None:
    """Refuse a ``--freq`` that is given but not a positive rate."""
    if freq is not None and not freq > 0:
        raise ModelError(f"--freq must be a positive rate in Hz, got {freq}")


def load_series(args: argparse.Namespace) -> Any:
    """Read the one axis the options of :func:`add_series_options` name, in SI; sets ``args.freq`` from
    the stamps when not given and ``args.data_warnings`` (printed now, kept by :func:`source_extra`).

    Returns
    -------
    imunoise.io.tabular.Series
        The values, their SI unit, the axis name and the unit as given.
    """
    from imunoise.io.imu_input import read_imu_source
    from imunoise.io.rosbag import is_bag
    from imunoise.io.tabular import Series

    check_freq(args.freq)
    bag = is_bag(args.data)
    if bag and args.column is None:
        raise DataError("a bag holds six axes: choose one with --column gyro_x|gyro_y|gyro_z|accel_x|...")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        series = read_imu_source(imu_source(args, args.data, columns=[args.column] if args.column is not None else None,
                                            units=args.units))
    args.data_warnings = print_warnings(caught)  # printed now, kept in the output by source_extra
    if len(series.data) != 1:
        raise DataError(
            f"{args.data} has {len(series.data)} data columns ({', '.join(series.data)}); choose one with --column"
        )
    (axis,) = series.data
    args.freq = series.freq
    return Series(series.data[axis], series.unit[axis], axis, series.source_unit[axis])


def source_extra(args: argparse.Namespace, series: Any) -> dict[str, Any]:
    """What a fit records about its input: file, column, unit as given, and the data warnings."""
    extra: dict[str, Any] = {"source": str(args.data), "column": series.name, "source_unit": series.source_unit}
    if getattr(args, "data_warnings", None):
        extra["warnings"] = list(args.data_warnings)
    return extra


def out_dir(args: argparse.Namespace, suffix: str) -> Path:
    """The ``--out`` folder, default ``<data name>_<suffix>``, created (:func:`prepare_out_dir`)."""
    return prepare_out_dir(args.out or f"{Path(args.data).name.split('.')[0]}_{suffix}")


def resolve_nav_inputs(args: argparse.Namespace) -> tuple[Any, str, str, str | None, str | None, np.ndarray, float]:
    """The files of :func:`add_nav_input_options`; explicit options override the ``--data`` manifest.

    Returns
    -------
    tuple
        (dataset or None, imu path, gnss path, reference path or None, outage path or None,
        lever arm [m] (3,), IMU time offset [s]).
    """
    import numpy as np

    from imunoise.io.dataset import read_dataset

    ds = read_dataset(args.data) if args.data else None
    imu = args.imu or (str(ds.imu) if ds else None)
    gnss = args.gnss or (str(ds.gnss) if ds else None)
    if not imu or not gnss:
        raise DataError("give --imu and --gnss, or --data DIR with a dataset.json")
    ref = args.ref or (str(ds.ref) if ds and ds.ref else None)
    outages = args.outages or (str(ds.outages) if ds and ds.outages and args.outage_runs else None)
    lever = args.lever_arm if args.lever_arm is not None else (list(ds.lever_arm_m) if ds else [0.0, 0.0, 0.0])
    offset = args.imu_time_offset if args.imu_time_offset is not None else (ds.imu_time_offset_s if ds else 0.0)
    return ds, imu, gnss, ref, outages, np.asarray(lever, dtype=float), float(offset)


def read_nav_files(
    imu_path: str,
    gnss_path: str,
    ref_path: str | None,
    time_offset: float,
    log: logging.Logger,
    *,
    imu_topic: str | None = None,
    gnss_topic: str | None = None,
    imu_frame: str | None = None,
    min_quality: int = 6,
) -> tuple[Any, Any, Any, list[str]]:
    """Read the IMU, GNSS and (optional) reference files of a navigation run (KF-GINS formats, ROS bags,
    RTKLIB .pos; :mod:`imunoise.io.navinput`, docs/guide/theory.rst, 'Interfaces'); each warning of the readers (sorted,
    duplicated, gaps,
    fixes without a fix, skipped RTKLIB qualities, time-base conversions) is logged once as one line and
    returned.

    Returns
    -------
    tuple
        (IMU data (increments, FRD), GNSS data, reference or None, the warning messages for metrics.json).
    """
    from imunoise.io.kfgins import read_reference
    from imunoise.io.navinput import read_nav_gnss, read_nav_imu

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nav_imu = read_nav_imu(imu_path, topic=imu_topic, frame=imu_frame, time_offset=float(time_offset))
        imu = nav_imu.imu
        gnss = read_nav_gnss(gnss_path, topic=gnss_topic, max_quality=min_quality, week=nav_imu.week)
        ref = read_reference(ref_path) if ref_path else None
    for w in caught:
        log.warning("%s", w.message)
    return imu, gnss, ref, [str(w.message) for w in caught]


def prepare_out_dir(path: str | Path, option: str = "--out") -> Path:
    """Create the output folder ``path`` (and its parents) or raise one clear :class:`DataError`.

    Parameters
    ----------
    path : str or Path
        The output folder.
    option : str
        The option name for the message.

    Returns
    -------
    Path
        The folder, existing and writable.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise DataError(f"{option} {out} is an existing file, not a folder; give a folder name")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError as exc:
        raise DataError(f"{option} {out}: {exc.filename or 'a parent'} is a file, not a folder") from exc
    except PermissionError as exc:
        raise DataError(f"{option} {out}: permission denied creating the folder; choose a writable place") from exc
    except OSError as exc:
        # e.g. /proc/x: ENOENT from a read-only pseudo file system, reported as the OUTPUT that cannot be made
        raise DataError(f"{option} {out}: cannot create the folder ({exc.strerror or exc})") from exc
    if not os.access(out, os.W_OK | os.X_OK):
        raise DataError(f"{option} {out}: the folder is not writable; choose a writable place")
    return out


def read_json_option(path: str | Path, option: str) -> Any:
    """The parsed JSON file given to ``option`` (e.g. ``--model``, ``--init``), or one clear error."""
    from imunoise.io.files import read_json

    return read_json(path, option, error=ModelError)


def print_warnings(caught: Iterable[warnings.WarningMessage], prefix: str = "warning") -> list[str]:
    """Print each caught warning as one ``warning: ...`` line on stderr; return the messages (for the
    output's metadata)."""
    msgs = []
    for w in caught:
        msg = str(w.message)
        if msg not in msgs:
            msgs.append(msg)
            print(f"{prefix}: {msg}", file=sys.stderr)
    return msgs


def check_outage_windows(
    windows: Sequence[tuple[float, float]], t0: float, t1: float, source: str | None
) -> list[str]:
    """Refuse outage windows that do not overlap the navigated span [t0, t1] (they would silently give
    ``outages: []``); return warnings for windows cut by the end of the data.

    Parameters
    ----------
    windows : sequence of (start, duration) [s]
        Outage windows (docs/guide/theory.rst, 'Navigation filter'), in the data's time base.
    t0, t1 : float
        Start and end of the navigated span [s].
    source : str or None
        The outage file, for the message.

    Returns
    -------
    list of str
        One warning per window that ends after ``t1``.
    """
    where = f"outage file {source}" if source else "outage windows"
    notes = []
    for k, (start, dur) in enumerate(windows, start=1):
        if start + dur <= t0 or start >= t1:
            raise DataError(
                f"{where}: window {k} ({start:.3f} s + {dur:g} s) lies outside the navigated data "
                f"[{t0:.3f}, {t1:.3f}] s; outage starts are in the data's time base (e.g. GPS seconds of week)"
            )
        if start < t0:
            raise DataError(
                f"{where}: window {k} starts at {start:.3f} s, before the navigation start {t0:.3f} s; "
                "an outage needs aided navigation before it"
            )
        if start + dur > t1:
            notes.append(
                f"{where}: window {k} ({start:.3f} s + {dur:g} s) ends after the data ({t1:.3f} s); "
                f"only {t1 - start:.1f} s of it are navigated"
            )
    return notes


MIN_NAV_GNSS_EPOCHS = 2
"""GNSS epochs needed inside the navigated span: one to initialise, one more to aid."""


def check_nav_span(
    imu: Any,
    gnss: Any,
    ref: Any,
    t0: float,
    t_end: float | None,
    static_duration: float,
    imu_path: str,
    start_from: str = "--start",
    gnss_path: str = "",
) -> list[str]:
    """Refuse a navigation run whose result could not mean anything: IMU and GNSS stamps that do not overlap
    (different time bases: both ranges named), a start ``t0`` outside the IMU data or an end ``t_end`` not after
    it, an IMU file shorter than the levelling window, fewer than 2 GNSS epochs or (with a reference) fewer
    than 2 reference epochs inside the navigated span. ``start_from`` says where ``t0`` came from ("--start",
    the manifest's start_sow, or "" for the default). Returns warnings (none for now; the list keeps the
    signature stable).
    """
    import numpy as np

    gnss_name = f" {gnss_path}" if gnss_path else ""
    if gnss.t[-1] < imu.t[0] or gnss.t[0] > imu.t[-1]:
        raise DataError(
            f"the IMU{' ' + imu_path} stamps [{imu.t[0]:.3f}, {imu.t[-1]:.3f}] s and the GNSS{gnss_name} stamps "
            f"[{gnss.t[0]:.3f}, {gnss.t[-1]:.3f}] s do not overlap: the files are in different time bases (e.g. "
            "GPS seconds of week vs Unix time or time since power-on); convert one, or shift the IMU with "
            "--imu-time-offset"
        )
    if not (imu.t[0] <= t0 < imu.t[-1]):
        what = f"{start_from} {t0:.3f}" if start_from else f"the start {t0:.3f} (first GNSS epoch)"
        raise DataError(f"{what} is outside the IMU data [{imu.t[0]:.3f}, {imu.t[-1]:.3f}]")
    if t_end is not None and t_end <= t0:
        raise DataError(f"--end {t_end} must be after the start {t0:.3f}")
    t_last = float(imu.t[-1]) if t_end is None else min(float(t_end), float(imu.t[-1]))
    span = float(imu.t[-1] - imu.t[0])
    if span < static_duration:
        raise DataError(
            f"IMU file {imu_path} covers only {span:.3g} s ({len(imu.t)} samples), less than the "
            f"--static-duration {static_duration:g} s used for levelling; give a longer recording "
            "(or a shorter --static-duration if the stop is shorter)"
        )
    n_gnss = int(np.count_nonzero((gnss.t >= t0) & (gnss.t <= t_last)))
    if n_gnss < MIN_NAV_GNSS_EPOCHS:
        raise DataError(
            f"only {n_gnss} GNSS epoch(s) between the start {t0:.3f} s and the end {t_last:.3f} s of the IMU "
            f"data {imu_path}; the GNSS and IMU files must overlap"
        )
    if ref is not None:
        n_ref = int(np.count_nonzero((ref.t >= t0) & (ref.t <= t_last)))
        if n_ref < 2:
            raise DataError(
                f"only {n_ref} reference epoch(s) between {t0:.3f} s and {t_last:.3f} s: the metrics would "
                "rest on nothing; check the reference file's time base"
            )
    return []


def check_learn_from(
    learn_s: float, t: np.ndarray, window: int, rate_hz: float, imu_path: str, option: str = "--learn-from"
) -> None:
    """Refuse a λ0 learning window that is not a positive span inside the record with enough samples
    (2·window, :func:`imunoise.detect.learn_lambda0`), instead of silently learning from driving or
    falling back to a default."""
    import numpy as np

    if not (np.isfinite(learn_s) and learn_s > 0):
        raise ModelError(f"{option} must be a positive number of seconds (a known stop), got {learn_s:g}")
    span = float(t[-1] - t[0])
    if learn_s >= span:
        raise DataError(
            f"{option} {learn_s:g} s is not shorter than the whole record {imu_path} ({span:.1f} s): λ0 would be "
            "learned from motion; give the length of the known stop at the start"
        )
    need = 2 * int(window)
    have = int(np.count_nonzero(t < t[0] + learn_s))
    if have < need:
        raise DataError(
            f"{option} {learn_s:g} s holds {have} samples at {rate_hz:.4g} Hz; learning λ0 needs ≥ {need} "
            f"(2 × the {window}-sample window), i.e. ≥ {need / rate_hz:.3g} s"
        )


def check_learn_window_is_stop(ref, t0: float, learn_s: float, speed_threshold: float, ref_path: str) -> list[str]:
    """Refuse a λ0 learning window the reference shows moving (the detector would learn motion as
    stillness); return a warning when the reference does not cover the window."""
    import numpy as np

    speed = np.linalg.norm(ref.vel_ned, axis=1)
    m = (ref.t >= t0) & (ref.t < t0 + learn_s)
    if not m.any():
        return [f"the reference {ref_path} does not cover the --learn-from window; it is assumed to be a stop"]
    k = int(np.argmax(speed[m]))
    if speed[m][k] > speed_threshold:
        raise DataError(
            f"--learn-from {learn_s:g} s is not a stop: the reference {ref_path} moves at {speed[m][k]:.2f} m/s "
            f"at t = {ref.t[m][k]:.2f} s; give the length of the known stop at the start"
        )
    return []
