"""`imunoise calibrate`: an IMU noise model from the stops of moving logs (:mod:`imunoise.calibrate`)."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path
from typing import Any

from imunoise.cli.calibrate_in_motion import add_in_motion_options, check_in_motion, in_motion_stage
from imunoise.cli.export import add_noise
from imunoise.cli.export_gate import add_force, refusal, write_exports
from imunoise.cli.fit import STREAM_ABOVE
from imunoise.cli.options import (
    EXPORT_TOOLS,
    add_criterion,
    add_time_options,
    add_topic,
    add_units,
    check_freq,
    imu_source,
    prepare_out_dir,
    print_warnings,
)
from imunoise.cli.record_length import add_target, calibrate_record_lengths, check_target, record_length_figure
from imunoise.errors import DataError, ImunoiseError, ModelError
from imunoise.io.atomic import atomic_path, atomic_savefig, atomic_write_text, staged_run

EXAMPLES = """examples:
  imunoise calibrate data/drive_0708 --export kalibr --out calib/            # dataset folder (IMU + reference)
  imunoise calibrate drive1.bag drive2.bag --topic /imu --export openvins --out calib/   # two logs pooled
  imunoise calibrate walk.csv --columns accel_x=0,accel_y=1,accel_z=2,gyro_x=3,gyro_y=4,gyro_z=5 \\
      --units gyro=deg/s,accel=g --time-column 6 --time-unit ms --out calib/
  imunoise calibrate imu_inc.txt --ref ref.nav --lambda0 0.05 --out calib/   # KF-GINS increments, fixed λ0
  imunoise calibrate drive.bag --gnss drive.pos --in-motion --export kalibr --out calib/   # + in-use values
  imunoise calibrate van1/ van2/ van3/ --in-motion --scheduler local --workers 3 --export vins --noise static \\
      --out calib/                                 # the drives' filter runs on Dask; the stops' values exported

Each log: λ0 learned on its quietest 10 s (--learn-s; --learn-from S: the first S s are a stop; --lambda0:
fixed), the static detector run forward and time-reversed (a stop keeps no second of its departure), the
angular-rate gate and, with a speed (--ref, --gnss or a dataset's reference), the online engine's stop check
looking 3 s past each stop's ends. Without a speed, more than --max-stop-rate stops per minute (>= 10) is
refused as cruising taken for stops: give --gnss or --ref. The readers' time-stamp warnings (sorted,
repeated stamps, gaps) are printed and kept in imu_model.json and calibration.json, as `fit` keeps them.
The stops of all logs are pooled per axis (bias removed per
stop), the model selected (WVIC by default), and the horizon stated: the longest averaging time the pooled
stops support. N is a value; K is a value only where the random walk rises above the white noise inside
the horizon, else a bound that holds for any model. Writes DIR/imu_model.json, DIR/calibration.json,
DIR/report.html (detection over time, WV fits with the horizon, stops, values) and the --export files.
A bag's topic (the one read) goes into the model and every export. Each fit is checked against the data:
where it leaves the pooled WV's 95 % band over a range of scales (>= 3 consecutive scales or >= 25 % of
them, each more than 10 % off) the next richer candidate of the selection is tried; if none stays inside,
--export is refused (exit 2, after the model and the report are written) unless --force, which writes the
warning into each file and into imu_model.json / calibration.json. The same log given twice is refused.

Large logs: a bag or table of more than --stream-above samples (or any with --stream) is read block by
block, twice, with a progress bar (imunoise.calibrate.stream_stops): a first pass keeps the stamps and
accel x, y (and the gyros' moving std) to find the rate and λ0 by the same rules, the second holds only
the open candidate stop and the stops kept. Same stops, pooled WV and model as the whole-log path. The
stamps must be in time order. KF-GINS files and dataset folders are always read whole."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="noise model of an IMU from the stops of moving logs (bags, tables, KF-GINS, datasets); pooled",
        description="Detect the stops of moving IMU logs, pool them per axis, identify the model and state the "
        "horizon (which parameters the stops determine, which only as a bound).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("logs", nargs="+", metavar="LOG",
                   help="ROS bag, dataset folder, KF-GINS IMU file, or CSV/TXT/.npz with --columns")
    p.add_argument("--columns", help="table: several columns: gyro_x=COL,...,accel_z=COL (names or 0-based indices)")
    add_units(p, several=True)
    add_time_options(p)
    p.add_argument("--freq", type=float, help="sample rate in Hz (of a table without a time column)")
    add_topic(p)
    p.add_argument("--ref", help="reference trajectory (KF-GINS) of a single log: speed for the stop check and plot")
    p.add_argument("--gnss", help="GNSS file (KF-GINS, RTKLIB .pos, bag) of a single log: speed from positions")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--lambda0", type=float, help="detector threshold λ0 [m/s²] (fixed; default: learned per log)")
    g.add_argument("--learn-from", type=float, metavar="S", help="learn λ0 from the first S seconds (of each log)")
    p.add_argument("--learn-s", type=float, default=10.0, metavar="S",
                   help="learn λ0 on the quietest S seconds of each log (default 10)")
    p.add_argument("--max-stop-rate", type=float, default=1.0, metavar="PER_MIN",
                   help="a log without --gnss/--ref with more stops per minute (and >= 10) is refused as steady "
                   "cruising taken for stops (default 1; inf: off)")
    p.add_argument("--stream", action="store_true",
                   help="read block by block (bags and tables; two passes, bounded by the stops; see below)")
    p.add_argument("--stream-above", type=float, default=STREAM_ABOVE, metavar="N",
                   help=f"stream inputs of more than N samples (bags and tables; default {STREAM_ABOVE:.0e})")
    p.add_argument("--window", type=int, default=100, help="window N [samples] of the detector (default 100)")
    p.add_argument("--min-duration", type=float, default=2.0, help="shortest stop kept [s] (default 2)")
    p.add_argument("--margin", type=float, default=0.5, help="trimmed at each stop end [s] (default 0.5)")
    add_criterion(p, "model selection")
    p.add_argument("--complete", help="complete model (the largest structure searched; default 4*AR1+DR+WN+QN+RW)")
    p.add_argument("--seed", type=int, default=0, help="random seed (of the random starting points)")
    p.add_argument("--export", action="append", choices=EXPORT_TOOLS,
                   help="also write this export beside the model (repeatable); refused where no (N, K) pair stands "
                   "for the data (see --force)")
    add_noise(p)
    add_force(p)
    add_target(p)
    p.add_argument("--out", help="output folder (default <first log name>_calib)")
    add_in_motion_options(p)
    p.set_defaults(func=run)


def _tqdm_wrap(it, desc):
    from tqdm import tqdm

    return tqdm(it, desc=desc, disable=not sys.stderr.isatty(), leave=False)


def _bar(desc: str, total: int, unit: str):
    from tqdm import tqdm

    return tqdm(total=total, unit=unit, unit_scale=True, desc=desc, disable=not sys.stderr.isatty(), leave=False)


def _should_stream(args: argparse.Namespace, source: Any) -> bool:
    """Stream a bag or table (an :class:`~imunoise.io.imu_source.ImuSource`) when forced (--stream) or when it
    holds more than --stream-above samples."""
    from imunoise.io.imu_stream import open_imu_blocks
    from imunoise.io.rosbag import is_bag

    path = source.path
    p = Path(path)
    streamable = not (p.is_dir() and (p / "dataset.json").exists()) and (
        is_bag(p) or args.columns is not None or p.suffix.lower() in (".npz", ".npy"))
    if not streamable:
        if args.stream:
            raise DataError(f"{path}: --stream reads bags and tables (--columns); a KF-GINS file or dataset folder "
                            "is read whole: drop --stream")
        return False
    if args.stream:
        return True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the reader that runs says it again
            n = open_imu_blocks(source).n_estimate
    except (DataError, OSError):
        return False  # the whole-log reader says what is wrong, in its own words
    if n > args.stream_above:
        print(f"{path}: about {n:.3g} samples > --stream-above {args.stream_above:.3g}: streaming", file=sys.stderr)
        return True
    return False


def run(args: argparse.Namespace) -> int:
    from imunoise.calibrate import calibrate, read_log, stream_stops
    from imunoise.detect import DetectorConfig
    from imunoise.io.tabular import parse_column_map

    check_freq(args.freq)
    if (args.ref or args.gnss) and len(args.logs) > 1:
        raise ModelError("--ref/--gnss belong to one log; give one log, or use dataset folders with a reference")
    if not args.max_stop_rate > 0:
        raise ModelError(f"--max-stop-rate must be a positive number of stops per minute (inf: off), got "
                         f"{args.max_stop_rate:g}")
    if args.learn_s is not None and not args.learn_s > 0:
        raise ModelError(f"--learn-s must be a positive number of seconds, got {args.learn_s:g}")
    _refuse_repeated_paths(args.logs)
    check_target(args)
    check_in_motion(args)
    if args.noise == "static" and not args.export:
        raise ModelError("--noise static chooses the values of the --export files: add --export TOOL (imu_model.json "
                         "keeps the static and the in-motion part either way)")
    final = prepare_out_dir(args.out or f"{Path(args.logs[0]).name.split('.')[0]}_calib")
    cfg = DetectorConfig(window=args.window, min_duration_s=args.min_duration, margin_s=args.margin)
    columns = parse_column_map(args.columns) if args.columns else None
    logs = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for path in _tqdm_wrap(args.logs, "reading"):
            source = imu_source(args, path, columns=columns)
            if _should_stream(args, source):
                logs.append(stream_stops(source, cfg, lambda0=args.lambda0, learn_from_s=args.learn_from,
                                         learn_s=args.learn_s, ref=args.ref, gnss=args.gnss, progress=_bar))
            else:
                logs.append(read_log(source, ref=args.ref, gnss=args.gnss))
    # the readers' warnings (sorted or repeated stamps, gaps, doubtful units; the same checks as `fit`), which
    # each log keeps in its metadata: one line each here, and kept in imu_model.json and calibration.json
    read_warnings = print_warnings(caught)
    for item in logs:
        for msg in getattr(item, "log", item).meta.get("warnings", []):
            if msg not in read_warnings:
                read_warnings.append(msg)
                print(f"warning: {msg}", file=sys.stderr)
    for item in logs:
        log = getattr(item, "log", item)
        n = log.meta["streamed"]["n_samples"] if log.meta.get("streamed") else log.t.size
        print(f"{log.name}: {n} samples, {log.duration_s:.1f} s at {log.rate_hz:.4g} Hz"
              + (" (streamed)" if log.meta.get("streamed") else "")
              + (f"; speed from {log.meta['speed_from']}" if log.meta.get("speed_from") else ""), file=sys.stderr)
    res = calibrate(logs, detector=cfg, lambda0=args.lambda0, learn_from_s=args.learn_from, learn_s=args.learn_s,
                    criterion=args.criterion, complete=args.complete, seed=args.seed, progress=_tqdm_wrap,
                    max_stops_per_min=args.max_stop_rate)
    print(res.summary())
    calibrate_record_lengths(res, args)  # how long to record (stdout, imu_model.json, calibration.json, report)
    if args.in_motion:  # the noise while moving, from the whole GNSS-aided drive(s), on top of the static model
        in_motion_stage(args, res.model)
    if read_warnings:
        res.model.source["warnings"] = read_warnings
    checks = {ax: (a.model, a.gate) for ax, a in res.axes.items()}
    res.model.source["fit_check"] = {ax: a.band.to_dict() for ax, a in res.axes.items()}
    try:
        forced = refusal(checks, args.force, where=str(final / "report.html")) if args.export else []
    except ImunoiseError:
        with staged_run(final, calibrate_outputs()) as out:
            _write_outputs(res, out, out / "imu_model.json", [])  # the model and the report say why; no export
        raise
    # every file of the calibration appears at once when it is complete (Ctrl-C leaves --out as it was); the
    # files an earlier calibration left there (more logs' detection plots, an export not asked again) go then
    with staged_run(final, calibrate_outputs()) as out:
        written = _write_outputs(res, out, out / "imu_model.json", forced)
        if forced:  # the data's Allan reading in place of each refused pair (the model file keeps the fit)
            from imunoise.cli.export_gate import force_readings
            from imunoise.noise.imu_model import ImuModel

            force_readings(res.fits, checks)
            in_motion = res.model.in_motion
            res.model = ImuModel.from_fits(res.fits, source=res.model.source)
            res.model.in_motion = in_motion
        if args.export:
            from imunoise.cli.export import report
            from imunoise.export import model_sensors

            report(model_sensors(res.model, None, "max", None, None, args.noise).values())
            written[2:2] = write_exports(res.model, args.export, out, forced, source=str(final / "imu_model.json"),
                                         noise=args.noise)
        written = [final / w.relative_to(out) for w in written]
    print(f"\nwrote {', '.join(str(w) for w in written)}", file=sys.stderr)
    return 0


def calibrate_outputs() -> tuple[str, ...]:
    """Every file `imunoise calibrate` writes into --out (a rerun removes the ones it did not write again)."""
    from imunoise.export import DEFAULT_FILENAMES

    return ("imu_model.json", "calibration.json", "report.html", "report.md", "detection_*.png", "wv_*.png",
            "record_length.png",
            "in_motion.png",
            *sorted(set(DEFAULT_FILENAMES.values())))


def _refuse_repeated_paths(logs: list[str]) -> None:
    """The same file given twice would be pooled twice: one line naming it (copies under another name are
    caught by their samples, :func:`imunoise.calibrate.calibrate`)."""
    seen: dict[Path, str] = {}
    for name in logs:
        key = Path(name).resolve()
        if key in seen:
            raise DataError(f"{name} is given twice (also as {seen[key]}): a log is pooled once; drop the repeat")
        seen[key] = name


def _write_outputs(res, out: Path, path: Path, forced: list[str]) -> list[Path]:
    """imu_model.json, calibration.json and report.html; ``forced``: the warnings of an export forced past the
    fit check, kept in both JSON files."""
    if forced:
        res.model.source["export_warnings"] = list(forced)
    with atomic_path(path) as tmp:
        res.model.save(tmp)
    summary = res.to_dict()
    if res.model.in_motion is not None:
        summary["in_motion"] = res.model.in_motion
    if res.model.source.get("warnings"):
        summary["warnings"] = list(res.model.source["warnings"])
    if forced:
        summary["export_warnings"] = list(forced)
    summary["record_length"] = res.model.source.get("record_length", {})
    atomic_write_text(out / "calibration.json", json.dumps(_json_safe(summary), indent=1))
    return [path, out / "calibration.json", write_report(res, out)]


def _json_safe(obj):
    import math

    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _plot_detection(ls, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    det, log = ls.detection, ls.log
    t0 = float(log.t[0])
    t = log.t - t0
    fig, ax = plt.subplots(figsize=(12, 4.2), layout="constrained")
    T = np.fmax(det.statistic[:, 0], det.statistic[:, 1])
    ax.semilogy(t, T, lw=0.5, color="tab:blue", label="moving std of accel x/y (Eq. 9, max)")
    ax.semilogy(t, det.threshold, lw=0.8, color="darkred", label=f"threshold λ (λ0 = {ls.lambda0:.3g} m/s²)")
    for k, s in enumerate(det.segments):
        ax.axvspan(s.t0 - t0, s.t1 - t0, color="0.6", alpha=0.25, lw=0, label="detected" if k == 0 else None)
    for k, s in enumerate(ls.stops):
        ax.axvspan(s.t0 - t0, s.t1 - t0, color="tab:green", alpha=0.3, lw=0, label="modelled stop" if k == 0 else None)
    ax.set_xlabel(f"time [s] since {t0:.3f} s")
    ax.set_ylabel("[m/s²]")
    if log.speed is not None:
        a2 = ax.twinx()
        a2.plot(log.speed[0] - t0, log.speed[1], color="0.3", lw=0.8, label="speed")
        a2.set_ylabel("speed [m/s]")
        a2.set_xlim(t[0], t[-1])
        a2.legend(loc="upper right", fontsize=8)
    ax.set_xlim(t[0], t[-1])
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"{Path(log.name).name}: {len(ls.stops)} stops modelled, {ls.static_s:.1f} s")
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)


def write_report(res, out: Path) -> Path:
    """report.html: detection per log, WV fits with the horizon, stop list, values with units and CIs."""
    import math

    from imunoise.noise.plots import plot_wv_fit
    from imunoise.report import Report

    rep = Report("IMU calibration from moving logs")
    rep.paragraph(f"{len(res.logs)} log(s), {res.n_stops} stops, {res.static_s:.1f} s static pooled "
                  f"(longest stop {res.longest_stop_s:.1f} s) at {res.freq_hz:g} Hz; model selection by "
                  f"{res.criterion.upper()}. Horizon: averaging times up to {res.horizon_s:.3g} s are supported "
                  "by the pooled stops; a random walk or a slow Gauss–Markov term beyond it is reported as a bound.")
    rep.heading("Detection")
    for i, ls in enumerate(res.logs):
        fig = out / f"detection_{i}.png"
        _plot_detection(ls, fig)
        rep.figure(fig, f"{ls.log.name}: λ0 = {ls.lambda0:.4g} m/s² ({ls.lambda0_source})")
        if ls.dropped:
            rep.log([f"dropped: {d}" for d in ls.dropped])
    rep.heading("Values")
    rows = []
    for ax, a in res.axes.items():
        nci = f"{a.N_ci[0]:.3e} – {a.N_ci[1]:.3e}" if math.isfinite(a.N_ci[0]) else "—"
        if a.K_status == "value":
            k = f"{a.K_fit:.3e} ({a.K_ci[0]:.2e} – {a.K_ci[1]:.2e})"
        else:
            k = f"≤ {a.K_bound:.3e}"
        tr = f"{a.tau_range_s[0]:.3g} – {a.tau_range_s[1]:.3g}" if a.tau_range_s else "—"
        pd = f"{a.pair_data.worst_ratio:.3g}" if a.pair_data is not None else "—"
        rows.append([ax, a.model, f"{a.N:.4e}", nci, k, f"{a.K:.3e}", f"{a.unit}/√Hz, {a.unit}/s/√Hz",
                     f"{a.horizon_s:.3g}", tr, pd, f"{a.worst_ratio:.3g}"])
    rep.table(["axis", "model", "N", "N 95% CI", "K (value with 95% CI, or bound)", "K exported", "units",
               "horizon [s]", "τ range [s]", "worst AV ratio pair/data", "worst AV ratio pair/model"], rows,
              caption="N white-noise density, K bias random-walk density (continuous time); AV ratios of the "
              "exported pair against the pooled stops' Allan variance (data) and against the fitted model")
    for ax, a in res.axes.items():
        for u in a.undetermined:
            rep.paragraph(f"{ax}: not determined: {u}")
    rep.heading("Fit against the data")
    rep.paragraph("Each fit's WV against the pooled WV's 95 % band: outside at ≥ 3 consecutive scales or ≥ 25 % of "
                  "them, the export is refused unless --force (then the warning is written into the file).")
    rep.table(["axis", "model", "export", "WV band", "exported pair vs the data's AV", "retry"],
              [[ax, a.model, "refused" if a.refused else "ok", a.band.text() if a.band is not None else "—",
                a.pair_data.text() if a.pair_data is not None else "—", a.retry or "—"]
               for ax, a in res.axes.items()])
    rep.heading("Wavelet variance fits")
    for ax, fit in res.fits.items():
        fig = out / f"wv_{ax}.png"
        tau_h = float(fit.wv.scales[-1] / fit.freq)
        with atomic_path(fig) as tmp:
            plot_wv_fit(fit, tmp, title=f"{ax}: {fit.model}",
                        marks=[(tau_h, f"horizon τ = {tau_h:.3g} s (averaging time {tau_h / 2:.3g} s)")])
        rep.figure(fig, f"{ax}: pooled WV of the stops, its 95% band, the {fit.model} fit and the horizon")
    record_length_figure(rep, res.model.source.get("record_length", {}), out)
    rep.heading("Stops")
    rep.table(["log", "start [s]", "end [s]", "duration [s]"],
              [[Path(ls.log.name).name, f"{s.t0:.2f}", f"{s.t1:.2f}", f"{s.duration:.2f}"]
               for ls in res.logs for s in ls.stops])
    if res.model.in_motion is not None:  # calibrate --in-motion
        from imunoise.cli.calibrate_in_motion import plot_factors
        from imunoise.inuse import InMotionPart, summary_lines

        part = InMotionPart.from_dict(res.model.in_motion)
        rep.heading("In motion")
        rep.figure(plot_factors(part, out / "in_motion.png"), "in-use / static white factor per axis, 95 % interval")
        rep.log(summary_lines(part))
    html_path, _ = rep.write(out, "report")
    return html_path


__all__ = ["register", "run", "write_report"]
