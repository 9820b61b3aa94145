"""`imunoise fit`: GMWM model of static IMU data — one axis of a CSV/TXT/NPY file, several columns, or
all six axes of a ROS bag (SPEC §4, §12)."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

from imunoise.errors import DataError, ImunoiseError

EXAMPLES = """examples:
  imunoise fit gyro_x.csv --freq 100 --model "2*AR1+WN+RW" --units deg/s --out fit_gx/
  imunoise fit static.txt --freq 200 --column 3 --units g --model "AR1+WN+RW"
  imunoise fit imu.npy --freq 100 --column gyro_x --auto --criterion wvic
  imunoise fit static.bag --topic /imu0 --auto --export kalibr --out calib/      # bag -> Kalibr imu.yaml
  imunoise fit log.csv --columns gyro_x=gx,gyro_y=gy,gyro_z=gz,accel_x=ax,accel_y=ay,accel_z=az \\
      --units gyro=deg/s,accel=g --time-column t --time-unit ns --auto --out fit/
  imunoise fit static.mcap --column gyro_z --model "WN+RW" --decimate 4          # block average 4 samples

One axis (a file column, or --column AXIS of a bag) writes DIR/model.json (model, per-sample and
continuous parameters with units, rate, data span, WV) and DIR/wv.png. Several axes (a bag without
--column, or --columns) write DIR/imu_model.json (one fit per axis, the input of `imunoise export` and
`imunoise nav --model`) and DIR/wv_<axis>.png. Parameters are per sample at the data rate (discrete,
like R simts); continuous-time equivalents (noise density, random walk, correlation times) are listed
beside them. Units: --units converts to SI (rad/s, m/s²); increments (rad, deg, m/s) are divided by the
nominal step. The rate comes from --freq, or the bag's header stamps / --time-column (checked against
--freq when both are given). --decimate K block-averages (keeps the noise density); dropping samples
would inflate the noise density by sqrt(K) and is refused."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="fit a GMWM error model to static sensor data (one axis, several columns, or a ROS bag)",
        description="Fit a composite stochastic error model to static IMU data with the GMWM (paper Eq. 6).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "data", help="CSV/TXT (header optional, .gz ok), .npy/.npz, or a ROS bag (.bag, .db3, .mcap, folder)"
    )
    p.add_argument("--freq", type=float, help="sample rate in Hz (needed unless the data have time stamps)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--model", help='model structure, e.g. "2*AR1+WN+RW" (processes: AR1 WN QN RW DR)')
    g.add_argument(
        "--auto",
        action="store_true",
        help="select the model automatically among all 79 sub-models of 4*AR1+DR+WN+QN+RW",
    )
    p.add_argument("--criterion", choices=["gof", "wvic"], default="wvic", help="ranking for --auto (default wvic)")
    p.add_argument("--column", help="one column name or 0-based index (a bag axis: gyro_x .. accel_z)")
    p.add_argument(
        "--columns",
        help="several columns: a,b,c (named as in the file) or axis=column pairs, e.g. gyro_x=gx,accel_x=3",
    )
    p.add_argument(
        "--units",
        help="unit of the data: one for all (rad/s, deg/s, deg/h, m/s2, g, mg, rad, deg, m/s) or per "
        "group/column: gyro=deg/s,accel=g (converted to SI); default: as is",
    )
    p.add_argument("--time-column", help="time column name or index (rate inferred, jitter and gaps reported)")
    p.add_argument("--time-unit", default="s", choices=["s", "ms", "us", "µs", "ns"], help="unit of the time column")
    p.add_argument("--topic", help="sensor_msgs/Imu topic of a ROS bag (listed when missing or wrong)")
    p.add_argument("--stamps", choices=["header", "bag"], default="header", help="bag time source (default header)")
    p.add_argument("--decimate", type=int, default=1, help="block-average K samples before fitting")
    p.add_argument(
        "--decimate-method",
        choices=["average", "drop"],
        default="average",
        help="'average' (keeps the noise density); 'drop' is refused for noise modelling (inflates N by sqrt(K))",
    )
    p.add_argument(
        "--weights",
        choices=["efficient", "diagonal", "fast", "identity"],
        default="efficient",
        help="GMWM weighting matrix Ω (default efficient = inverse WV covariance)",
    )
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance for contaminated data")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starting points")
    p.add_argument(
        "--export",
        action="append",
        choices=["kalibr", "openvins", "orbslam3", "json"],
        help="also write this export beside the model (repeatable)",
    )
    p.add_argument("--sensor", choices=["gyro", "accel"], help="sensor of a single-axis fit (for --export)")
    p.add_argument("--out", help="output folder (default: <data name>_fit)")
    p.set_defaults(func=run)


def _units(text: str | None):
    if text is None or "=" not in text:
        return text
    return {k.strip(): v.strip() for k, v in (item.split("=", 1) for item in text.split(",") if item.strip())}


def run(args: argparse.Namespace) -> int:
    from imunoise.io.imu_input import read_imu_source
    from imunoise.io.rosbag import is_bag
    from imunoise.io.tabular import parse_column_map

    if args.freq is not None and not args.freq > 0:
        raise ImunoiseError(f"--freq must be a positive rate in Hz, got {args.freq}")
    if args.column is not None and args.columns is not None:
        raise ImunoiseError("give --column (one axis) or --columns (several), not both")
    bag = is_bag(args.data)
    if not bag and args.freq is None and args.time_column is None:
        raise ImunoiseError("give the sample rate with --freq HZ (or a time column with --time-column)")
    multi = args.columns is not None or (bag and args.column is None)
    columns = parse_column_map(args.columns) if args.columns is not None else None
    if not multi and args.column is not None:
        columns = [args.column]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        series = read_imu_source(
            args.data,
            topic=args.topic,
            columns=columns,
            units=_units(args.units),
            time_column=args.time_column,
            time_unit=args.time_unit,
            freq=args.freq,
            decimate_by=args.decimate,
            decimate_method=args.decimate_method,
            stamps=args.stamps,
        )
    for w in caught:  # one readable line per handled data problem (sorted, duplicates, gaps)
        print(f"warning: {w.message}", file=sys.stderr)
    if not multi and len(series.data) != 1:
        raise DataError(
            f"{args.data} has {len(series.data)} data columns ({', '.join(series.data)}); choose one with "
            "--column NAME|INDEX or fit several with --columns"
        )
    if series.report is not None or bag:
        print(series.describe(), file=sys.stderr)
    out = Path(args.out or f"{Path(args.data).name.split('.')[0]}_fit")
    out.mkdir(parents=True, exist_ok=True)
    if multi:
        return _run_multi(args, series, out)
    return _run_single(args, series, out)


def _base_extra(args: argparse.Namespace, series, axis: str) -> dict:
    extra: dict = {"source": str(args.data), "column": axis, "source_unit": series.source_unit[axis]}
    if series.meta.get("topic"):
        extra["topic"] = series.meta["topic"]
    if series.report is not None:
        extra["timing"] = series.report.to_dict()
    if series.meta.get("decimated"):
        extra["decimated"] = series.meta["decimated"]
    return extra


def _fit_one(args: argparse.Namespace, series, axis: str, quiet: bool = False):
    from imunoise.imu_model import fit_axis

    fit, ranking = fit_axis(
        series.data[axis],
        freq=series.freq,
        model=args.model,
        auto=args.auto,
        criterion=args.criterion,
        weights=args.weights,
        robust=args.robust,
        unit=series.unit[axis],
        seed=args.seed,
    )
    extra = _base_extra(args, series, axis)
    if ranking is not None:
        if not quiet:
            print(ranking.table(limit=10))
            print()
        extra["selection"] = {"criterion": args.criterion, "n_candidates": len(ranking.fits)}
    fit.extra.update(extra)
    return fit


def _run_single(args: argparse.Namespace, series, out: Path) -> int:
    from imunoise.plots import plot_wv_fit

    axis = next(iter(series.data))
    fit = _fit_one(args, series, axis)
    print(fit.summary())
    (out / "model.json").write_text(json.dumps(fit.to_dict(), indent=1))
    plot_wv_fit(fit, out / "wv.png", title=f"{Path(args.data).name} [{axis}]: {fit.model}")
    written = [out / "model.json", out / "wv.png"]
    if args.export:
        from imunoise.io.imu_input import sensor_of

        sensor = args.sensor or sensor_of(axis, fit.unit)
        if sensor is None:
            raise ImunoiseError("--export of a single axis needs --sensor gyro|accel")
        for fmt in args.export:
            written.append(_export(fit, fmt, out, sensor=sensor, source=str(out / "model.json")))
    print(f"\nwrote {', '.join(str(w) for w in written)}", file=sys.stderr)
    return 0


def _run_multi(args: argparse.Namespace, series, out: Path) -> int:
    from tqdm import tqdm

    from imunoise.imu_model import ImuModel
    from imunoise.plots import plot_wv_fit

    fits = {}
    axes = list(series.data)
    for axis in tqdm(axes, desc="axes", unit="axis", disable=not sys.stderr.isatty()):
        fit = _fit_one(args, series, axis, quiet=True)
        fits[axis] = fit
        print(f"== {axis} ==")
        print(fit.summary())
        print()
        plot_wv_fit(fit, out / f"wv_{axis}.png", title=f"{Path(args.data).name} [{axis}]: {fit.model}")
    source = {"file": str(args.data), "freq_hz": series.freq}
    for k in ("topic", "frame_id", "frame", "format"):
        if series.meta.get(k):
            source[k] = series.meta[k]
    model = ImuModel.from_fits(fits, source=source)
    path = model.save(out / "imu_model.json")
    print(_continuous_table(model))
    written = [path]
    for fmt in args.export or []:
        written.append(_export(model, fmt, out, source=str(path)))
    print(f"\nwrote {', '.join(str(w) for w in written)} and wv_<axis>.png", file=sys.stderr)
    return 0


def _export(model, fmt: str, out: Path, **kwargs) -> Path:
    from imunoise.export import DEFAULT_FILENAMES, write_export

    return write_export(model, fmt, out / DEFAULT_FILENAMES[fmt], **kwargs)


def _continuous_table(model) -> str:
    """Per-axis continuous-time values as exported (SPEC §2), with the discrete per-sample equivalents."""
    import math

    from imunoise.export import axis_noise

    f = model.freq_hz
    lines = [
        f"continuous-time noise per axis (what Kalibr / OpenVINS / ORB-SLAM3 take; discrete = per sample at {f:g} Hz)",
        f"  {'axis':<9}{'model':<22}{'N white (continuous)':>22}  {'K_eq bias RW (continuous)':>27}  "
        f"{'σ per sample (discrete)':>24}",
    ]
    for axis, d in model.axes.items():
        a = axis_noise(d, axis)
        u = d.get("unit", "u")
        lines.append(
            f"  {axis:<9}{a.model:<22}{a.N:>12.4e} {u}/√Hz  {a.K_eq:>14.4e} {u}/s/√Hz  {a.N * math.sqrt(f):>14.4e} {u}"
        )
    return "\n".join(lines)
