"""Options and checks shared by the commands: the same names, choices and defaults for the same thing
everywhere, and one clear error for a bad ``--out`` or input (issue "Trustworthy outputs" §3, §4).

Not a command: it has no ``register`` function, so the sub-command discovery of :mod:`imunoise.cli` skips it.
Light at import (no numpy): ``imunoise --help`` imports every command module, and the option adders here
only build argparse parsers; the readers and checks import what they need when they run.
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

__all__ = [
    "TIME_UNIT_CHOICES",
    "CRITERIA",
    "DEFAULT_CRITERION",
    "WEIGHTS",
    "add_data_argument",
    "add_freq",
    "add_columns",
    "add_units",
    "add_time_unit",
    "add_time_options",
    "add_topic",
    "add_series_options",
    "add_model",
    "add_criterion",
    "add_weights",
    "add_out",
    "add_nav_input_options",
    "parse_units",
    "check_freq",
    "load_series",
    "source_extra",
    "out_dir",
    "resolve_nav_inputs",
    "read_nav_files",
    "prepare_out_dir",
    "read_json_option",
    "print_warnings",
    "check_outage_windows",
    "check_nav_span",
    "check_learn_from",
    "check_learn_window_is_stop",
    "finite_float",
    "positive_float",
    "nonnegative_float",
    "positive_int",
    "int_at_least",
    "finite_floats_everywhere",
    "DeprecatedAlias",
    "add_deprecated_alias",
    "flag_names",
]

TIME_UNIT_CHOICES = ("s", "ms", "us", "µs", "ns")
"""Units of a time column, the same for every command (``us`` and ``µs`` are the same)."""

CRITERIA = ("wvic", "gof")
DEFAULT_CRITERION = "wvic"
"""One default ranking everywhere: WVIC (GOF, the paper's Eq. 8, always prefers the largest nested model)."""

WEIGHTS = ("efficient", "diagonal", "fast", "identity")


# ---------------------------------------------------------------------------------------------------
# parse-time value checks: a bad number is refused by argparse (one "error: argument --x: ..." line, exit 2)
# before any file is read, instead of running and failing deep inside
# ---------------------------------------------------------------------------------------------------
def finite_float(text: str) -> float:
    """``type=`` of every float option: a finite number (``nan``, ``inf`` refused)."""
    import math

    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number {text!r}") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return x


finite_float.__name__ = "float"  # argparse names the type in "invalid float value" messages


def positive_float(text: str) -> float:
    """``type=``: a finite number > 0."""
    x = finite_float(text)
    if not x > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return x


def nonnegative_float(text: str) -> float:
    """``type=``: a finite number ≥ 0."""
    x = finite_float(text)
    if x < 0:
        raise argparse.ArgumentTypeError(f"must be ≥ 0, got {text!r}")
    return x


def int_at_least(low: int) -> Any:
    """``type=``: a whole number ≥ ``low``."""

    def parse(text: str) -> int:
        try:
            x = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid whole number {text!r}") from None
        if x < low:
            raise argparse.ArgumentTypeError(f"must be a whole number ≥ {low}, got {text!r}")
        return x

    parse.__name__ = "int"
    return parse


positive_int = int_at_least(1)
"""``type=``: a whole number ≥ 1 (``--workers``, ``--cov-every``)."""


def _walk(parser: argparse.ArgumentParser) -> Iterable[argparse.ArgumentParser]:
    yield parser
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for sp in dict.fromkeys(a.choices.values()):
                yield from _walk(sp)


def finite_floats_everywhere(parser: argparse.ArgumentParser) -> None:
    """Give every ``type=float`` option of ``parser`` and its sub-parsers the :func:`finite_float` check:
    one validator for all float flags, whoever declared them (``--lever-arm nan``, ``--yaw nan``, ...)."""
    for sp in _walk(parser):
        for a in sp._actions:
            if a.type is float:
                a.type = finite_float


class DeprecatedAlias(argparse.Action):
    """A former option name: does what the new option ``new`` does (same ``dest``, value kind, append or flag)
    and prints one warning naming the new name; hidden from ``--help``."""

    def __init__(self, option_strings, dest, new: str = "", kind: str = "store", **kw):
        self.new, self.kind = new, kind
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"warning: {option_string} is deprecated; use {self.new} (same meaning)", file=sys.stderr)
        if self.kind == "append":
            values = [*(getattr(namespace, self.dest, None) or []), values]
        elif self.kind == "flag":
            values = self.const
        setattr(namespace, self.dest, values)


def add_deprecated_alias(p: argparse.ArgumentParser, old: str, new: str) -> None:
    """Keep ``old`` working as a hidden alias of the option ``new`` of ``p`` (same ``dest`` and value kind),
    warning when used."""
    target = next(a for a in p._actions if new in a.option_strings)
    if isinstance(target, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._StoreConstAction)):
        kw: dict[str, Any] = {"nargs": 0, "const": target.const, "kind": "flag"}
    else:
        kind = "append" if isinstance(target, argparse._AppendAction) else "store"
        kw = {"nargs": target.nargs, "type": target.type, "metavar": target.metavar, "kind": kind}
    p.add_argument(old, dest=target.dest, action=DeprecatedAlias, new=new, **kw)


FLAG_NAMES = {
    "min_static_s": "--min-static",
    "DetectorConfig.window": "--window",
    "learn_lambda0_s": "--learn-from",
    "min_duration_s": "--min-duration",
    "margin_s": "--margin",
    "cov_every": "--cov-every",
}
"""Python field names that reach a message → the flag that sets them (the CLI speaks in flags)."""


def flag_names(message: str) -> str:
    """``message`` with the Python field names of :data:`FLAG_NAMES` replaced by their flags."""
    import re

    for field_name, flag in FLAG_NAMES.items():
        message = re.sub(rf"(?<![\w.-]){re.escape(field_name)}(?![\w])", flag, message)
    return message


# ---------------------------------------------------------------------------------------------------
# option-group adders: each option is declared here once, with one name, help, choice list and default
# ---------------------------------------------------------------------------------------------------
def add_data_argument(p: argparse.ArgumentParser) -> None:
    """The positional ``data`` file of the modelling commands."""
    p.add_argument(
        "data", help="CSV/TXT (header optional, .gz ok), .npy/.npz, or a ROS bag (.bag, .db3, .mcap, folder)"
    )


def add_freq(p: argparse.ArgumentParser) -> None:
    """``--freq`` [Hz]; checked by :func:`check_freq`."""
    p.add_argument(
        "--freq", type=float, help="sample rate in Hz (needed unless the data have time stamps or a .npz freq_hz)"
    )


def add_columns(p: argparse.ArgumentParser, *, one: bool = True, several: bool = False) -> None:
    """``--column`` (one axis) and/or ``--columns`` (several, parsed by
    :func:`imunoise.io.tabular.parse_column_map`)."""
    if one:
        p.add_argument("--column", help="one column name or 0-based index (a bag axis: gyro_x .. accel_z)")
    if several:
        p.add_argument(
            "--columns",
            help="several columns: a,b,c (named as in the file) or axis=column pairs, e.g. gyro_x=gx,accel_x=3 "
            "(default: all but time)",
        )


def add_units(p: argparse.ArgumentParser, *, several: bool = False) -> None:
    """``--units``: one unit, or (``several``) per group/column ``gyro=deg/s,accel=g`` (:func:`parse_units`)."""
    if several:
        text = (
            "unit of the data: one for all (rad/s, deg/s, deg/h, m/s2, g, mg, rad, deg, m/s) or per "
            "group/column: gyro=deg/s,accel=g (converted to SI)"
        )
    else:
        text = "unit of the data: rad/s, deg/s, deg/h, m/s2, g, mg, rad, deg, m/s (of the column; converted to SI)"
    p.add_argument(
        "--units", help=text + "; default: the unit a .npz states, else as is (warned when the values cannot be SI)"
    )


def add_time_unit(p: argparse.ArgumentParser) -> None:
    """``--time-unit`` with the shared choices."""
    p.add_argument("--time-unit", default="s", choices=TIME_UNIT_CHOICES, help="unit of --time-column (default s)")


def add_time_options(p: argparse.ArgumentParser) -> None:
    """``--time-column`` and ``--time-unit``."""
    p.add_argument(
        "--time-column", help="table: time column (name or index); the rate is inferred, jitter and gaps reported"
    )
    add_time_unit(p)


IMU_TOPIC_HELP = "ROS bag: the sensor_msgs/Imu topic (default: the only one; listed when missing or wrong)"


def add_topic(p: argparse.ArgumentParser, help: str = IMU_TOPIC_HELP) -> None:
    """``--imu-topic`` (dest ``topic``): the IMU topic of a ROS bag, the same name in every command (the
    former ``--topic`` of the fitting commands stays as a deprecated alias)."""
    p.add_argument("--imu-topic", dest="topic", help=help)
    add_deprecated_alias(p, "--topic", "--imu-topic")


def add_series_options(p: argparse.ArgumentParser) -> None:
    """One static axis from a table or a ROS bag (select, allan, em, compare); read it with :func:`load_series`."""
    add_data_argument(p)
    add_freq(p)
    add_columns(p)
    add_units(p)
    add_topic(p)
    add_time_options(p)


def add_model(p: argparse.ArgumentParser, *, auto: bool = False, processes: str | None = None) -> None:
    """``--model STRUCTURE`` (required); with ``auto`` exclusive with ``--auto`` (automatic selection among
    the 79 sub-models of the complete model), one of them required. ``processes``: the names a command accepts
    when it takes only some; by default the help points to the registry (the CLI's start-up imports no numpy,
    so it does not load :mod:`imunoise.processes` to list them; a wrong name lists them all)."""
    which = processes or "those of imunoise.processes: AR1, WN, QN, RW, DR, ...; a wrong name lists them"
    text = f'model structure, e.g. "2*AR1+WN+RW" (processes: {which})'
    if not auto:
        p.add_argument("--model", required=True, help=text)
        return
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--model", help=text)
    g.add_argument(
        "--auto",
        action="store_true",
        help="select the model automatically among all 79 sub-models of 4*AR1+DR+WN+QN+RW (per axis)",
    )


def add_criterion(p: argparse.ArgumentParser, what: str = "") -> None:
    """``--criterion wvic|gof`` with the shared default (wvic)."""
    p.add_argument(
        "--criterion",
        choices=CRITERIA,
        default=DEFAULT_CRITERION,
        help="model ranking: wvic (default) or gof (the paper's Eq. 8, which always favours the largest nested "
        f"model){'; ' + what if what else ''}",
    )


def add_weights(p: argparse.ArgumentParser) -> None:
    """``--weights`` (GMWM weighting matrix Ω) with the shared choices."""
    p.add_argument(
        "--weights",
        choices=WEIGHTS,
        default="efficient",
        help="GMWM weighting matrix Ω (default efficient = inverse WV covariance)",
    )


def add_out(p: argparse.ArgumentParser, default_suffix: str | None = None) -> None:
    """``--out DIR``: required, or (``default_suffix``) defaulting to ``<data name>_<suffix>`` (:func:`out_dir`)."""
    if default_suffix is None:
        p.add_argument("--out", required=True, help="output folder")
    else:
        p.add_argument("--out", help=f"output folder (default: <data name>_{default_suffix})")


def add_nav_input_options(p: argparse.ArgumentParser) -> None:
    """The input options every navigation command shares (SPEC §12); resolve them with
    :func:`resolve_nav_inputs`."""
    p.add_argument("--data", help="dataset folder with a dataset.json manifest (SPEC §12; the options override it)")
    p.add_argument(
        "--imu", help="IMU: KF-GINS increments or rate CSV (SI), or a ROS bag (.bag, .db3, .mcap, ROS 2 folder)"
    )
    add_topic(p)
    p.add_argument(
        "--imu-frame",
        choices=("flu", "frd"),
        help="body frame of the IMU data: flu (ROS REP 103) or frd; default flu for a bag, frd for a text file; "
        "checked against the specific force of the first 2 s",
    )
    p.add_argument(
        "--gnss",
        help="GNSS file: KF-GINS text (SOW lat lon h σN σE σD), an RTKLIB .pos solution, or a ROS bag with NavSatFix",
    )
    p.add_argument("--gnss-topic", help="ROS bag: the sensor_msgs/NavSatFix topic (default: the only one)")
    p.add_argument(
        "--min-quality",
        type=int,
        default=6,
        choices=range(1, 7),
        metavar="Q",
        help="RTKLIB .pos: keep epochs with Q ≤ this (1 fix, 2 float, 3 sbas, 4 dgps, 5 single, 6 ppp; "
        "default 6 = all); the skipped ones are counted",
    )
    p.add_argument("--ref", help="reference trajectory (KF-GINS result format) for metrics")
    p.add_argument(
        "--lever-arm",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="GNSS antenna position in body FRD from the IMU [m] (default: the manifest's, else 0 0 0)",
    )
    p.add_argument(
        "--imu-time-offset", type=float, help="seconds added to IMU time stamps (default: dataset.json's value or 0)"
    )
    p.add_argument("--outages", help="outage windows: a file of 'start duration' per line [s]")
    p.add_argument("--outage-runs", action="store_true", help="run each outage window separately")
    p.add_argument(
        "--start",
        type=float,
        help="start time [s, data time base] (default: the manifest's start_sow, else the first GNSS epoch "
        "inside the IMU data)",
    )
    p.add_argument(
        "--static-duration",
        type=positive_float,
        default=30.0,
        help="seconds of still data at the IMU file start for levelling and gyro bias (default 30); checked "
        "still with the static detector's test",
    )
    p.add_argument("--yaw", type=float, help="initial yaw [deg] instead of the GNSS course")
    p.add_argument(
        "--max-imu-gap",
        type=positive_float,
        default=MAX_IMU_GAP_S,
        metavar="S",
        help=f"refuse IMU time gaps longer than S seconds (default {MAX_IMU_GAP_S:g}): the mechanization would "
        "integrate one increment across the gap; raise it to integrate longer gaps as given",
    )


MAX_IMU_GAP_S = 1.0
"""Longest IMU time gap a navigation run integrates without ``--max-imu-gap`` (s)."""


# ---------------------------------------------------------------------------------------------------
# reading what the options name
# ---------------------------------------------------------------------------------------------------
def parse_units(text: str | None) -> str | dict[str, str] | None:
    """``--units`` as given: one unit for all columns, or ``group=unit,column=unit`` pairs as a dict."""
    if text is None or "=" not in text:
        return text
    return {k.strip(): v.strip() for k, v in (item.split("=", 1) for item in text.split(",") if item.strip())}


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
        series = read_imu_source(
            args.data,
            topic=args.topic,
            columns=[args.column] if args.column is not None else None,
            units=args.units,
            time_column=args.time_column,
            time_unit=args.time_unit,
            freq=args.freq,
        )
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
    RTKLIB .pos; :mod:`imunoise.io.navinput`, SPEC §12); each warning of the readers (sorted, duplicated, gaps,
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
        Outage windows (SPEC §8), in the data's time base.
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
