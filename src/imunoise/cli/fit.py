"""`imunoise fit`: GMWM model of static IMU data — one axis of a CSV/TXT/NPY file, several columns, or
all six axes of a ROS bag (docs/guide/theory.rst, 'GMWM estimator' and 'Interfaces')."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path
from typing import Any

from imunoise.cli.export_gate import (
    add_force,
    add_update_interval,
    band_checks,
    band_diagnostics,
    force_readings,
    pair_gates,
    refusal,
    write_exports,
)
from imunoise.cli.options import (
    EXPORT_TOOLS,
    add_columns,
    add_criterion,
    add_data_argument,
    add_freq,
    add_model,
    add_out,
    add_time_options,
    add_topic,
    add_units,
    add_weights,
    check_freq,
    imu_source,
    out_dir,
    print_warnings,
)
from imunoise.cli.record_length import add_target, check_target, fit_record_lengths
from imunoise.errors import DataError, FitError, ModelError
from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run

STREAM_ABOVE = 2e7
"""Samples (file rows or bag messages) above which `fit` streams the input: 2e7 rows of 7 float64 columns are
1.1 GB as arrays, and the batch WV holds three more copies of each axis."""

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
would inflate the noise density by sqrt(K) and is refused.

Large logs: an input of more than --stream-above samples (or any with --stream) is read block by block
with a progress bar and its wavelet variance computed in one pass (imunoise.noise.wv_stream.WVStream): the
same WV and fit as the whole-file path, in memory set by --max-scale. The stamps must be in time order
(the whole-file path sorts them); --robust needs the whole series and keeps the whole-file path."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="fit a GMWM error model to static sensor data (one axis, several columns, or a ROS bag)",
        description="Fit a composite stochastic error model to static IMU data with the GMWM (paper Eq. 6).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_data_argument(p)
    add_freq(p)
    add_model(p, auto=True)
    add_criterion(p, "ranking for --auto")
    add_columns(p, several=True)
    add_units(p, several=True)
    add_time_options(p)
    add_topic(p)
    p.add_argument("--stamps", choices=["header", "bag"], default="header", help="bag time source (default header)")
    p.add_argument("--decimate", type=int, default=1, help="block-average K samples first (before fitting)")
    p.add_argument(
        "--decimate-method",
        choices=["average", "drop"],
        default="average",
        help="'average' (keeps the noise density); 'drop' is refused for noise modelling (inflates N by sqrt(K))",
    )
    add_weights(p)
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance for contaminated data")
    p.add_argument("--seed", type=int, default=0, help="random seed (of the random starting points)")
    p.add_argument(
        "--stream",
        action="store_true",
        help="read block by block (the wavelet variance in one pass, bounded memory)",
    )
    p.add_argument(
        "--stream-above",
        type=float,
        default=STREAM_ABOVE,
        metavar="N",
        help=f"stream inputs of more than N samples (rows or messages; default {STREAM_ABOVE:.0e})",
    )
    p.add_argument(
        "--max-scale",
        type=float,
        metavar="S",
        help="longest wavelet scale [s] to compute (J = floor(log2(S·f)) levels; bounds the streaming memory)",
    )
    p.add_argument(
        "--export",
        action="append",
        choices=EXPORT_TOOLS,
        help="also write this export beside the model (repeatable); refused where no (N, K) pair stands for the "
        "data (--force writes the data's own reading)",
    )
    add_force(p)
    add_update_interval(p)
    p.add_argument("--keep-lines", action="store_true",
                   help="fit the data as read: do not remove the narrowband lines found in its spectrum (they are "
                   "still reported)")
    p.add_argument("--sensor", choices=["gyro", "accel"], help="sensor: which one a single-axis fit is (for --export)")
    p.add_argument("--horizon", type=float, metavar="S", help="--export: longest averaging time [s] the pair is "
                   "matched on (default: the data's longest scale); see `imunoise export --help` for the rule")
    add_target(p)
    add_out(p, "fit")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.io.imu_input import read_imu_source
    from imunoise.io.rosbag import is_bag
    from imunoise.io.tabular import parse_column_map

    check_freq(args.freq)
    check_target(args)
    if args.column is not None and args.columns is not None:
        raise ModelError("give --column (one axis) or --columns (several), not both")
    bag = is_bag(args.data)
    multi = args.columns is not None or (bag and args.column is None)
    columns = parse_column_map(args.columns) if args.columns is not None else None
    if not multi and args.column is not None:
        columns = [args.column]
    if args.max_scale is not None and not args.max_scale > 0:
        raise ModelError(f"--max-scale must be a positive time in seconds, got {args.max_scale}")
    if args.stream and args.robust:
        raise ModelError("--stream cannot use --robust: the robust WV needs every coefficient of a level at once")
    source = imu_source(args, args.data, columns=columns)
    series = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.stream or not args.robust:
            series = _streamed(args, source)
        if series is None:
            series = read_imu_source(source, decimate_by=args.decimate, decimate_method=args.decimate_method)
    # one readable line per handled data problem (sorted, duplicates, gaps, doubtful units), kept in the output
    series.meta["warnings"] = print_warnings(caught)
    if not multi and len(series.axes) != 1:
        raise DataError(
            f"{args.data} has {len(series.axes)} data columns ({', '.join(series.axes)}); choose one with "
            "--column NAME|INDEX or fit several with --columns"
        )
    if series.report is not None or bag:
        print(series.describe(), file=sys.stderr)
    final = out_dir(args, "fit")
    # every file of this fit appears at once when it completes (Ctrl-C leaves --out as it was), and the files
    # an earlier fit left there (another axis set's plots, an export not asked for again) are removed then
    refused: list[FitError] = []  # an export refused by the fit check: the model and its plots are still written
    with staged_run(final, fit_outputs()) as out:
        if multi:
            written = _run_multi(args, series, out, final, refused)
        else:
            written = _run_single(args, series, out, final, refused)
    if refused:
        raise refused[0]
    print(f"\nwrote {', '.join(str(w) for w in written)}", file=sys.stderr)
    return 0


def fit_outputs() -> tuple[str, ...]:
    """Every file `imunoise fit` can write into --out (glob patterns): a rerun removes the ones it did not
    write again, so that no file of an earlier fit is read as part of this one."""
    from imunoise.export import DEFAULT_FILENAMES

    return ("model.json", "wv.png", "imu_model.json", "wv_*.png", *sorted(set(DEFAULT_FILENAMES.values())))


def _streamed(args: argparse.Namespace, source: Any):
    """The input's WV per axis in one pass (:func:`imunoise.noise.wv_log.stream_wavelet_variance`) when it is
    forced (--stream) or the input holds more than --stream-above samples; else None (whole-file path)."""
    from tqdm import tqdm

    from imunoise.io.imu_stream import StreamOrderError, open_imu_blocks
    from imunoise.noise.wv_log import stream_wavelet_variance

    try:
        with warnings.catch_warnings(record=True) as early:
            warnings.simplefilter("always")
            blocks = open_imu_blocks(source)
    except (DataError, OSError):
        if args.stream:
            raise
        return None  # the whole-file reader says what is wrong, in its own words
    if not args.stream and blocks.n_estimate <= args.stream_above:
        return None
    for w in early:  # only now: the whole-file path would warn about the same header again
        warnings.warn(w.message, w.category, stacklevel=2)
    if not args.stream:
        print(
            f"{args.data}: about {blocks.n_estimate:.3g} samples > --stream-above {args.stream_above:.3g}: "
            "streaming the wavelet variance",
            file=sys.stderr,
        )
    with tqdm(
        total=blocks.size,
        unit=blocks.size_unit,
        unit_scale=True,
        desc="wavelet variance",
        disable=not sys.stderr.isatty(),
    ) as bar:
        try:
            return stream_wavelet_variance(
                blocks,
                freq=args.freq,
                decimate_by=args.decimate,
                decimate_method=args.decimate_method,
                max_scale_s=args.max_scale,
                progress=bar.update,
            )
        except StreamOrderError as exc:
            if args.stream:
                raise
            print(f"{exc}; reading the whole file instead", file=sys.stderr)
            return None


def _base_extra(args: argparse.Namespace, series, axis: str) -> dict:
    extra: dict = {"source": str(args.data), "column": axis, "source_unit": series.source_unit[axis]}
    if series.meta.get("topic"):
        extra["topic"] = series.meta["topic"]
    if series.report is not None:
        extra["timing"] = series.report.to_dict()
    if series.meta.get("decimated"):
        extra["decimated"] = series.meta["decimated"]
    if series.meta.get("warnings"):
        extra["warnings"] = list(series.meta["warnings"])
    if series.meta.get("units_from_file"):
        extra["units_from_file"] = True
    return extra


def _fit_one(args: argparse.Namespace, series, axis: str, quiet: bool = False):
    from imunoise.noise.imu_model import fit_axis, fit_axis_wv
    from imunoise.noise.wv_log import StreamedImu

    common = {
        "model": args.model,
        "auto": args.auto,
        "criterion": args.criterion,
        "weights": args.weights,
        "unit": series.unit[axis],
        "seed": args.seed,
    }
    found: list = []
    if isinstance(series, StreamedImu):
        fit, ranking = fit_axis_wv(series.wv[axis], n_samples=series.n_samples, **common)
        fit.extra["streamed"] = {"levels": len(series.wv[axis]), "max_scale_s": args.max_scale}
    elif args.max_scale is not None:
        from imunoise.noise.wv import wavelet_variance
        from imunoise.noise.wv_stream import WVStream

        x, found = _without_lines(args, series, axis)
        levels = WVStream(max_scale_s=args.max_scale, freq=series.freq).levels
        wv = wavelet_variance(x, levels=levels, robust=args.robust, freq=series.freq)
        fit, ranking = fit_axis_wv(wv, n_samples=x.size, values=x, **common)
    else:
        x, found = _without_lines(args, series, axis)
        fit, ranking = fit_axis(x, freq=series.freq, robust=args.robust, **common)
    extra = _base_extra(args, series, axis)
    if not isinstance(series, StreamedImu):
        extra["lines"] = {"removed": not args.keep_lines, "found": [ln.to_dict() for ln in found]}
    if ranking is not None:  # re-estimated as gmwm does, a richer candidate where it leaves its WV band
        from imunoise.noise.fitting.quality import within_band

        settled = within_band(ranking, fit)
        fit, extra["fit_check"] = settled.fit, settled.to_dict()
        if settled.note:
            print(f"{axis}: {settled.note}", file=sys.stderr)
        if not quiet:
            print(ranking.table(limit=10))
            print()
        extra["selection"] = {"criterion": args.criterion, "n_candidates": len(ranking.fits)}
    fit.extra.update(extra)
    return fit


def _without_lines(args: argparse.Namespace, series, axis: str):
    """The axis's data with its narrowband lines suppressed (:mod:`imunoise.lines`; as read with
    ``--keep-lines``), and the lines found; each is printed (stderr)."""
    from imunoise.lines import lines_text, remove_lines

    x = series.data[axis]
    y, found = remove_lines(x, series.freq, unit=series.unit[axis])
    for t in lines_text(axis, found):
        print(t if not args.keep_lines else t.replace("removed before fitting", "kept (--keep-lines)"),
              file=sys.stderr)
    return (x if args.keep_lines else y), found


def _run_single(args: argparse.Namespace, series, out: Path, final: Path, refused: list) -> list[Path]:
    """One axis: files written into ``out`` (the staging folder); the paths named are those under ``final``."""
    from imunoise.noise.plots import plot_wv_fit

    axis = series.axes[0]
    if args.sensor is None and set(args.export or ()) - {"json"}:  # before fitting: nothing written on refusal
        raise ModelError(f"--export {','.join(args.export)} of one axis ({axis}): Kalibr, OpenVINS and ORB-SLAM3 "
                         "need both sensors' keys; add --sensor gyro|accel to write that block alone, or --export json")
    fit = _fit_one(args, series, axis)
    print(fit.summary())
    gates = _gates(args, {axis: fit})
    atomic_write_text(out / "model.json", json.dumps(fit.to_dict(), indent=1))
    with atomic_path(out / "wv.png") as tmp:
        plot_wv_fit(fit, tmp, title=f"{Path(args.data).name} [{axis}]: {fit.model}")
    written = [out / "model.json", out / "wv.png"]
    if args.export:
        from imunoise.export import infer_sensor

        sensor = args.sensor or infer_sensor(fit)
        if sensor is None:
            raise ModelError("--export of a single axis needs --sensor gyro|accel (its unit and name do not say)")
        try:
            forced = _refusal(args, {axis: fit}, gates, str(final / "wv.png"))
        except FitError as exc:
            refused.append(exc)
            return written
        _export_report(fit, args, sensor)
        written += write_exports(fit, args.export, out, forced, fits={axis: fit}, sensor=sensor,
                                 source=str(final / "model.json"), horizon_s=args.horizon,
                                 partial=args.sensor is not None)
    return [final / w.relative_to(out) for w in written]


def _run_multi(args: argparse.Namespace, series, out: Path, final: Path, refused: list) -> list[Path]:
    """Several axes: files written into ``out`` (the staging folder); the paths named are those under ``final``."""
    from tqdm import tqdm

    from imunoise.noise.imu_model import ImuModel
    from imunoise.noise.plots import plot_wv_fit

    fits = {}
    axes = list(series.axes)
    for axis in tqdm(axes, desc="axes", unit="axis", disable=not sys.stderr.isatty()):
        fit = _fit_one(args, series, axis, quiet=True)
        fits[axis] = fit
        print(f"== {axis} ==")
        print(fit.summary())
        print()
        with atomic_path(out / f"wv_{axis}.png") as tmp:
            plot_wv_fit(fit, tmp, title=f"{Path(args.data).name} [{axis}]: {fit.model}")
    gates = _gates(args, fits)
    source = {"file": str(args.data), "freq_hz": series.freq}
    for k in ("topic", "frame_id", "frame", "format", "warnings", "units_from_file"):
        if series.meta.get(k):
            source[k] = series.meta[k]
    model = ImuModel.from_fits(fits, source=source)
    path = out / "imu_model.json"
    with atomic_path(path) as tmp:
        model.save(tmp)
    print(_continuous_table(model, args.horizon))
    written = [path]
    if args.export:
        try:
            forced = _refusal(args, fits, gates, str(final / "wv_<axis>.png"))
        except FitError as exc:
            refused.append(exc)
            return written
        if forced:  # the data's readings in place of the refused pairs (the model file keeps the fit)
            model = ImuModel.from_fits(fits, source=source)
        _export_report(model, args, None)
        written += write_exports(model, args.export, out, forced, fits=fits, source=str(final / path.name),
                                 horizon_s=args.horizon)
    return [final / w.relative_to(out) for w in written] + [final / "wv_<axis>.png"]


def _gates(args: argparse.Namespace, fits: dict) -> dict:
    """The pair gate per axis (into each fit's extra, so the model file holds it), printed (stdout)."""
    gates = pair_gates(fits, horizon_s=args.horizon, update_interval_s=args.update_interval)
    for axis, (_, g) in gates.items():
        print(f"{axis}: {'REFUSED ' if g.refused else ''}{g.text()}")
    fit_record_lengths(fits, args)  # how long to record, per axis (stdout and the model file)
    return gates


def _refusal(args: argparse.Namespace, fits: dict, gates: dict, where: str) -> list[str]:
    """The gate's refusal (:func:`refusal`), the WV band check as a diagnostic, and with ``--force`` the data's
    reading in place of each refused pair."""
    for line in band_diagnostics(band_checks(fits)):
        print(f"band check: {line}", file=sys.stderr)
    forced = refusal(gates, args.force, where=where)
    if args.force:
        force_readings(fits, gates)
    return forced


def _export_report(model, args: argparse.Namespace, sensor: str | None) -> None:
    """Before writing the exports: per axis which process went where, notes and AV-ratio warnings (stderr)."""
    from imunoise.cli.export import report
    from imunoise.export import model_sensors

    if args.horizon is not None and not args.horizon > 0:
        raise ModelError(f"--horizon must be a positive time in seconds, got {args.horizon}")
    report(model_sensors(model, sensor, "max", None, args.horizon).values())


def _continuous_table(model, horizon_s: float | None = None) -> str:
    """Per-axis continuous-time values as exported (docs/guide/theory.rst, 'Latent processes' and 'Interfaces'), with
    the discrete per-sample equivalents."""
    import math

    from imunoise.export import axis_noise

    f = model.freq_hz
    lines = [
        f"continuous-time noise per axis (what Kalibr / OpenVINS / ORB-SLAM3 take; discrete = per sample at {f:g} Hz)",
        f"  {'axis':<9}{'model':<22}{'N white (continuous)':>22}  {'K bias RW (continuous)':>27}  "
        f"{'σ per sample (discrete)':>24}  worst AV ratio pair/model",
    ]
    for axis, d in model.axes.items():
        u = d.get("unit", "u")
        try:
            a = axis_noise(d, axis, horizon_s=horizon_s)
        except ModelError as exc:
            lines.append(f"  {axis:<9}{d.get('model', ''):<22}no (N, K) pair: {exc}")
            continue
        lines.append(
            f"  {axis:<9}{a.model:<22}{a.N:>12.4e} {u}/√Hz  {a.K:>14.4e} {u}/s/√Hz  {a.N * math.sqrt(f):>14.4e} {u}"
            f"  {a.worst_ratio:>8.3g}"
        )
    return "\n".join(lines)
