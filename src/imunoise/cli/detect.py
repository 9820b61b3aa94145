"""`imunoise detect`: static detection on an IMU record (docs/guide/theory.rst, 'Static detection', paper §2.3 and Fig.
8)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
from pathlib import Path

from imunoise.cli.options import (
    check_learn_from,
    check_learn_window_is_stop,
    int_at_least,
    nonnegative_float,
    positive_float,
    prepare_out_dir,
)
from imunoise.errors import DataError, ModelError
from imunoise.io.atomic import atomic_savefig, atomic_write_text, staged_run

EXAMPLES = """examples:
  imunoise detect --data data/drive_0708 --learn-from 10 --out out/detect
  imunoise detect --imu imu.txt.gz --ref ref.nav.gz --lambda0 0.1 --min-duration 3 --out out/detect

λ0 (m/s²): --lambda0 sets it; --learn-from S learns it from the first S seconds of the record, which
must be a known stop: λ0 = 2 × median of the Eq. 9 statistic there (imunoise.detect.learn_lambda0).
The paper's 0.02 m/s² suits a quiet IMU only; on a vibrating car learn it.
With a reference (KF-GINS format), precision/recall of the static epochs are scored against
reference speed < --speed-threshold (interpolated to IMU epochs inside the reference span)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "detect",
        help="detect static segments (moving std + adaptive threshold) and plot them like paper Fig. 8",
        description="Static detection: Eq. 9 moving std of accel x/y, adaptive threshold "
                    "(docs/guide/theory.rst, 'Static detection'), "
        "segments with minimum duration and end trimming, angular-rate gate.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--imu", help="IMU: KF-GINS increments or rate CSV (sow,gx,gy,gz,ax,ay,az)")
    p.add_argument("--ref", help="reference trajectory (KF-GINS result format: week t lat lon h vN vE vD roll pitch "
                   "yaw) for the scores")
    p.add_argument("--data",
                   help="dataset folder with a dataset.json manifest (docs/guide/theory.rst, 'Interfaces'; --imu/--ref "
                        "override it)")
    p.add_argument("--out", required=True, help="output folder (segments.csv, detection.png, summary.json)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--lambda0", type=positive_float, default=None,
                   help="detector threshold λ0 [m/s²] (initial; default 0.02)")
    g.add_argument("--learn-from", type=positive_float, default=None, metavar="S",
                   help="learn λ0 from the first S seconds (of the record: a known stop)")
    p.add_argument("--window", type=int_at_least(2), default=100,
                   help="window N [samples] of the detector (Eq. 9; default 100)")
    p.add_argument("--min-duration", type=nonnegative_float, default=2.0,
                   help="shortest stop kept [s] (default 2)")
    p.add_argument("--margin", type=nonnegative_float, default=0.5,
                   help="trimmed at each stop end [s] (default 0.5)")
    p.add_argument("--fixed-threshold", action="store_true", help="use λ0 as a fixed threshold (no Eq. 10)")
    p.add_argument("--speed-threshold", type=positive_float, default=0.2,
                   help="reference speed [m/s] below which an epoch counts as static (default 0.2)")
    p.add_argument("--imu-time-offset", type=float, default=None,
                   help="seconds added to IMU time stamps (default: dataset.json's value or 0)")
    p.set_defaults(func=run)


STATIC_SHARE_WARN = 0.9
"""A detection that calls more than this share of the record static is warned about (λ0 too high)."""


def _json_safe(obj):
    """NaN (undefined precision, ...) → null, so that summary.json is strict JSON."""
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _plot(det, t_ref_speed, speed, out: Path, speed_threshold: float, t0: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = det.t - t0
    T = det.statistic
    fig, axes = plt.subplots(2, 2, figsize=(15, 7.5), gridspec_kw={"width_ratios": [3, 1]}, squeeze=False)
    # zoom: around the end of the longest segment (threshold rising while still, reset on motion)
    zoom = None
    if det.segments:
        s = max(det.segments, key=lambda s: s.duration)
        zoom = (s.t1 - t0 - 10.0, s.t1 - t0 + 5.0)
    for row, axis in enumerate("xy"):
        for col in (0, 1):
            ax = axes[row, col]
            if col == 1 and zoom is None:
                ax.set_visible(False)
                continue
            ax.semilogy(t, T[:, row], lw=0.6, color="tab:blue", label=f"T (accel {axis}), Eq. 9")
            ax.semilogy(t, det.threshold, lw=1.0, color="darkred", label="adaptive threshold λ")
            raw = det.static_raw
            ax.plot(t[raw], T[raw, row], ".", ms=1.5, color="red", label="static epochs (raw)")
            for s in det.segments:
                ax.axvspan(s.t0 - t0, s.t1 - t0, color="red", alpha=0.15, lw=0)
            ax.set_ylabel("moving std [m/s²]")
            if col == 1:
                ax.set_xlim(*zoom)
            if speed is not None:
                a2 = ax.twinx()
                a2.plot(t_ref_speed - t0, speed, color="0.4", lw=0.8, label="reference speed")
                a2.axhline(speed_threshold, color="0.4", ls=":", lw=0.8)
                a2.set_ylabel("speed [m/s]")
                if row == 0 and col == 0:
                    a2.legend(loc="upper right", fontsize=8)
            if row == 0 and col == 0:
                ax.legend(loc="upper left", fontsize=8)
    axes[1, 0].set_xlabel(f"time [s] since {t0:.3f} s (GPS seconds of week)")
    if zoom is not None:
        axes[1, 1].set_xlabel("zoom: end of the longest segment [s]")
    fig.suptitle(
        f"Static detection (shaded: {len(det.segments)} kept segments, trimmed, "
        f"≥ {det.config.min_duration_s:g} s; λ0 = {det.config.lambda0:.4g} m/s²)"
    )
    fig.tight_layout()
    atomic_savefig(fig, out, dpi=110)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from imunoise.detect import (
        DetectorConfig,
        detect_static,
        learn_lambda0,
        static_metrics,
        static_truth_from_speed,
    )
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_imu, read_reference

    imu_path, ref_path, offset = args.imu, args.ref, args.imu_time_offset
    if args.data:
        ds = read_dataset(args.data, required=("imu",))  # detection needs no GNSS
        imu_path = imu_path or str(ds.imu)
        ref_path = ref_path or (str(ds.ref) if ds.ref else None)
        if offset is None:
            offset = ds.imu_time_offset_s
    if not imu_path:
        raise DataError("give --imu FILE or --data DIR")
    if args.lambda0 is not None and not (np.isfinite(args.lambda0) and args.lambda0 > 0):
        raise ModelError(f"--lambda0 must be a positive threshold in m/s², got {args.lambda0:g}")
    final = prepare_out_dir(args.out)  # before the work: an unusable --out fails fast
    imu = read_imu(imu_path, time_offset=float(offset or 0.0))
    gyro, accel = imu.rates()
    t = imu.t

    lambda0 = 0.02 if args.lambda0 is None else args.lambda0
    lambda0_source = "default (paper)" if args.lambda0 is None else "--lambda0"
    ref = read_reference(ref_path) if ref_path else None
    if ref is not None and not ((t >= ref.t[0]) & (t <= ref.t[-1])).any():
        raise DataError(f"reference {ref_path} does not overlap the IMU time span; check the time stamps / offset")
    warn: list[str] = []
    if args.learn_from is not None:
        check_learn_from(args.learn_from, t, args.window, imu.rate_hz, str(imu_path))
        if ref is not None:
            warn += check_learn_window_is_stop(ref, float(t[0]), args.learn_from, args.speed_threshold, str(ref_path))
        m = t < t[0] + args.learn_from
        lambda0 = learn_lambda0(accel[m], window=args.window)
        lambda0_source = f"learned from the first {args.learn_from:g} s (2 × median moving std)"
    config = DetectorConfig(
        window=args.window,
        lambda0=lambda0,
        min_duration_s=args.min_duration,
        margin_s=args.margin,
        adaptive=not args.fixed_threshold,
    )
    det = detect_static(t, accel, gyro, config, rate_hz=imu.rate_hz)

    span = float(t[-1] - t[0])
    if span > 0 and det.static_time_s > STATIC_SHARE_WARN * span:
        warn.append(
            f"{det.static_time_s:.0f} s of the {span:.0f} s record are called static: λ0 = {lambda0:.4g} m/s² "
            "is probably too high (learned from motion?); check --learn-from / --lambda0"
        )
    for msg in warn:
        print(f"warning: {msg}", file=sys.stderr)
    # the three files appear together when the run completes (Ctrl-C leaves --out as it was)
    with staged_run(final, ("segments.csv", "detection.png", "summary.json")) as out:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["t0", "t1", "duration_s", "i0", "i1"])
        for s in det.segments:
            w.writerow([f"{s.t0:.6f}", f"{s.t1:.6f}", f"{s.duration:.3f}", s.i0, s.i1])
        atomic_write_text(out / "segments.csv", buf.getvalue())

        summary: dict = {
            "imu": str(imu_path),
            "n_samples": int(t.size),
            "duration_s": float(t[-1] - t[0]),
            "lambda0_m_s2": float(lambda0),
            "lambda0_source": lambda0_source,
            "config": {k: getattr(config, k) for k in config.__dataclass_fields__},
            "n_segments": len(det.segments),
            "static_time_s": det.static_time_s,
            "gate_open_fraction": float(det.gate_open.mean()),
            "segments": [{"t0": s.t0, "t1": s.t1, "duration_s": s.duration} for s in det.segments],
            "warnings": warn,
        }
        speed = t_ref = None
        if ref is not None:
            t_ref = ref.t
            speed = np.linalg.norm(ref.vel_ned, axis=1)
            inside = (t >= t_ref[0]) & (t <= t_ref[-1])
            if not inside.any():
                raise DataError(
                    f"reference {ref_path} does not overlap the IMU time span; check the time stamps / offset"
                )
            truth = static_truth_from_speed(t, t_ref, speed, args.speed_threshold)
            summary["reference"] = {
                "file": str(ref_path),
                "speed_threshold_m_s": args.speed_threshold,
                "epochs_scored": int(inside.sum()),
                "segments": static_metrics(det.static[inside], truth[inside]),
                "raw": static_metrics(det.static_raw[inside], truth[inside]),
            }
        _plot(det, t_ref, speed, out / "detection.png", args.speed_threshold, float(t[0]))
        atomic_write_text(out / "summary.json", json.dumps(_json_safe(summary), indent=2))

    print(f"IMU {imu_path}: {t.size} samples, {t[-1] - t[0]:.1f} s at {imu.rate_hz:.1f} Hz")
    print(f"λ0 = {lambda0:.4g} m/s² ({lambda0_source}); window {config.window} samples; "
          f"{'adaptive' if config.adaptive else 'fixed'} threshold")
    print(f"{len(det.segments)} static segments, {det.static_time_s:.1f} s static in total; "
          f"angular-rate gate open {100 * det.gate_open.mean():.2f} % of epochs (|ω| > 30 °/s)")
    for s in det.segments:
        print(f"  {s.t0:.3f} – {s.t1:.3f} s  ({s.duration:.1f} s)")
    if "reference" in summary:
        r = summary["reference"]
        for key, label in (("segments", "segments (trimmed)"), ("raw", "raw per-epoch test")):
            m = r[key]
            print(
                f"vs reference speed < {args.speed_threshold:g} m/s, {label}: "
                f"precision {m['precision']:.4f}, recall {m['recall']:.4f}, F1 {m['f1']:.4f} "
                f"({m['n_pred']} predicted, {m['n_true']} true epochs)"
            )
    print(f"wrote {final / 'segments.csv'}, {final / 'detection.png'}, {final / 'summary.json'}")
    return 0
