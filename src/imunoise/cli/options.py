"""Options and checks shared by the commands: the same names, choices and defaults for the same thing
everywhere, and one clear error for a bad ``--out`` or input (issue "Trustworthy outputs" §3, §4).

Not a command: it has no ``register`` function, so the sub-command discovery of :mod:`imunoise.cli` skips it.
Light at import (no numpy): ``imunoise --help`` imports every command module, and the option adders here
only build argparse parsers; the readers and checks (:mod:`imunoise.cli.option_checks`, re-exported here)
import what they need when they run.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from typing import Any

from imunoise.cli.option_checks import MIN_NAV_GNSS_EPOCHS as MIN_NAV_GNSS_EPOCHS
from imunoise.cli.option_checks import (
    check_freq,
    check_learn_from,
    check_learn_window_is_stop,
    check_nav_span,
    check_outage_windows,
    imu_source,
    load_series,
    out_dir,
    parse_units,
    prepare_out_dir,
    print_warnings,
    read_json_option,
    read_nav_files,
    resolve_nav_inputs,
    source_extra,
)

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
    "add_scheduler",
    "check_scheduler",
    "parse_units",
    "imu_source",
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
    "sigma_triple",
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


def sigma_triple(text: str) -> tuple[float, float, float]:
    """``type=``: three σ > 0 ``N,E,D`` [m] of a position fix (the replay scripts' ``--rtk-sigma``,
    ``--meter-sigma``)."""
    v = tuple(float(x) for x in text.split(","))
    if len(v) != 3 or min(v) <= 0:
        raise argparse.ArgumentTypeError(f"need three σ > 0 (N,E,D in m), got {text!r}")
    return v  # type: ignore[return-value]


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
    so it does not load :mod:`imunoise.noise.processes` to list them; a wrong name lists them all)."""
    which = processes or "those of imunoise.noise.processes: AR1, WN, QN, RW, DR, ...; a wrong name lists them"
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
    """The input options every navigation command shares (docs/guide/theory.rst, 'Interfaces'); resolve them with
    :func:`resolve_nav_inputs`."""
    p.add_argument("--data", help="dataset folder with a dataset.json manifest (docs/guide/theory.rst, 'Interfaces'; "
                                  "the options override it)")
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

EXPORT_TOOLS = ("kalibr", "openvins", "orbslam3", "vins", "lio-sam", "fast-lio", "json")
"""The ``--export``/``--to`` choices of ``fit``, ``calibrate`` and ``export`` (the formats of
:mod:`imunoise.export.formats`; tests/export checks they agree)."""


def add_scheduler(p: argparse.ArgumentParser, *, default: str, what: str) -> None:
    """``--scheduler`` and ``--workers``: where ``what`` runs on Dask (:func:`imunoise.io.dask_client.dask_client`;
    ``batch``'s files, ``calibrate --in-motion``'s drives); checked by :func:`check_scheduler`."""
    p.add_argument("--scheduler", default=default,
                   help=f"Dask scheduler ({what}): 'local' (LocalCluster of --workers processes), 'sequential' "
                   f"(plain loop) or a scheduler address tcp://HOST:PORT (default {default})")
    p.add_argument("--workers", type=int, help="local worker processes (default: one per core)")


def check_scheduler(args: argparse.Namespace) -> None:
    """``--workers``: at least one worker process."""
    if args.workers is not None and args.workers < 1:
        from imunoise.errors import ModelError

        raise ModelError(f"--workers must be ≥ 1 worker process, got {args.workers} (omit it for one per core)")
