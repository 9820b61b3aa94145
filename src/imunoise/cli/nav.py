"""`imunoise nav`: loosely coupled INS/GNSS EKF over recorded files, with metrics and plots
(docs/guide/theory.rst, 'Navigation filter' and 'Interfaces')."""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from imunoise.cli.aiding_options import add_aiding_options, aiding_metrics, epoch_counts, read_aiding
from imunoise.cli.navrun import (
    add_mount_option,
    gyro_unit_notes,
    mounting_metrics,
    mounting_notes,
    nav_start,
    outage_summary,
    read_nav_inputs,
    run_metrics,
    write_trajectory,
)
from imunoise.cli.options import (
    add_deprecated_alias,
    add_nav_input_options,
    check_nav_span,
    check_outage_windows,
    positive_int,
)
from imunoise.io.atomic import atomic_savefig, atomic_write_text, staged_run

if TYPE_CHECKING:
    import numpy as np

    from imunoise.detect.results import Detection
    from imunoise.nav.filter_model import InMotionFilter

EXAMPLES = """examples:
  imunoise nav --data data/drive_0708 --out out/nav_full
  imunoise nav --data data/drive_0708 --outage-runs --out out/nav_out
  imunoise nav --imu imu.txt --gnss gnss.txt --ref ref.nav --lever-arm 0 -0.05 0 --imu-model model.json \
      --out out/
  imunoise nav --data sim/ --outages sim/outages.txt --default --out out/sim
  imunoise nav --data sim/ --outages sim/outages.txt --nhc --odometer --out out/odo   # + the wheel speed
  imunoise nav --data data/drive_0708 --outage-runs --gnss-vel --out out/nav_vel      # + GNSS velocity
  imunoise nav --imu drive.mcap --imu-topic /imu --gnss drive.mcap --gnss-topic /fix --lever-arm 0 -0.05 0 \
      --out out/b
  imunoise nav --imu imu.txt --gnss rtk.pos --min-quality 2 --out out/pos      # RTKLIB solution, fix + float

Inputs: KF-GINS text (body FRD, GPS seconds of week), ROS bags (.bag, .db3, .mcap: sensor_msgs/Imu rates in
FLU → increments rate·Δt_k, NavSatFix without NO_FIX, σ from position_covariance; Unix stamps → GPS seconds
of week) and RTKLIB .pos (GPST/UTC/JST → GPST, deg or d m s, sdn/sde/sdu σ, Q ≤ --min-quality). --imu-frame
(default flu for a bag, frd for text) is checked against gravity in the first 2 s.

Writes DIR/trajectory.nav (KF-GINS result format: week, SOW, lat, lon [deg], h [m], vN, vE, vD [m/s],
roll, pitch, yaw [deg]; the IMU point), DIR/metrics.json (docs/guide/theory.rst, 'Navigation filter' keys: errors at the
reference epochs of the GNSS antenna, in m and m/s), DIR/trajectory.png, DIR/errors.png and DIR/biases.png. With
--outage-runs every window of --outages is run separately from the same start (DIR/outage_<k>/...) and
metrics.json lists the drift at the end of each window; without it all windows are removed in one run.
Initialisation: position from GNSS, roll/pitch from static levelling over --static-duration s of the
IMU file's beginning, yaw from the first GNSS course faster than 3 m/s propagated back (or --yaw),
gyro bias = static mean. Start: --start, else the manifest's start_sow, else the first GNSS epoch (as online).

Refused with the fix: GNSS latitude/longitude in radians or beyond ±90°, IMU gaps longer than --max-imu-gap,
a levelling window the static detector or the GNSS shows moving, IMU and GNSS stamps in different time bases.
Gyros turning ≈ 57× the GNSS track (deg/s read as rad/s) are warned and the warning kept in metrics.json.
The outputs of a run appear in DIR together when it completes (Ctrl-C leaves DIR as it was); files an
earlier nav run left there (outage_<k>/ of more windows, plots) are removed, nothing else is touched."""

log = logging.getLogger("imunoise.nav")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "nav",
        help="loosely coupled INS/GNSS EKF with augmented IMU error states",
        description="Run the loosely coupled error-state EKF (docs/guide/theory.rst, 'Navigation filter') on IMU + "
                    "GNSS files.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_nav_input_options(p)
    add_mount_option(p)
    m = p.add_mutually_exclusive_group()
    m.add_argument("--imu-model", help="IMU error models: model JSON ({'gyro': fit, 'accel': fit} or per axis, from "
                   "`imunoise fit` or `calibrate`)")
    m.add_argument("--default", action="store_true", help="plain default model WN+RW+GM (the default)")
    m.add_argument("--kfgins", action="store_true", help="KF-GINS' loose settings of the shared drive (WN+GM)")
    p.add_argument("--end", type=float, help="end time [s]; default: end of the IMU data")
    p.add_argument("--cov-every", type=positive_int, help="covariance propagation every N IMU samples (default 5)")
    p.add_argument(
        "--zupt",
        action="store_true",
        help="zero-velocity updates at detected stops (the docs/guide/theory.rst, 'Static detection' static detector, "
             "λ0 learned from the static "
        "window)",
    )
    p.add_argument("--nhc", action="store_true",
                   help="non-holonomic constraints: zero lateral and vertical body velocity while driving (gated in "
                        "turns and skids; imunoise.nav.measurements.nhc)")
    add_aiding_options(p)
    p.add_argument("--no-chi2-gate", action="store_true", help="disable the χ² innovation gate of the GNSS updates")
    add_deprecated_alias(p, "--no-gate", "--no-chi2-gate")
    add_deprecated_alias(p, "--model", "--imu-model")
    p.add_argument("--scale-factors", action="store_true",
                   help="add gyro and accel scale-factor states (to the EKF: KF-GINS' 21-state filter; 1000 ppm, "
                   "GM 1 h)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.cli.scipy_defer import defer_scipy_linalg

    defer_scipy_linalg()  # before the first kernel: numba's BLAS check would run all of scipy.linalg's imports
    import numpy as np

    from imunoise.nav.align import coarse_align
    from imunoise.nav.defaults import EkfConfig, default_axis_models, kfgins_loose, load_axis_models

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    inp = read_nav_inputs(args, log)
    imu, gnss, ref, notes, windows, lever = inp.imu, inp.gnss, inp.ref, inp.notes, inp.windows, inp.lever
    rate = imu.rate_hz
    if args.imu_model:
        models = load_axis_models(args.imu_model, rate)
        model_name = args.imu_model
    elif args.kfgins:
        models, model_name = default_axis_models(rate, kfgins_loose()), "kfgins_loose"
    else:
        models, model_name = default_axis_models(rate), "plain_default"
    kw = {"lever_arm": tuple(lever)}
    if args.cov_every:
        kw["cov_every"] = int(args.cov_every)
    if args.no_chi2_gate:
        kw["chi2_gate"] = 0.0
    if args.scale_factors:
        kw["scale_factors"] = True
    if args.nhc:
        from imunoise.nav.measurements.nhc import NhcConfig

        kw["aiding"] = (NhcConfig(),)
    if args.zupt:
        kw["zupt_every"] = 1  # the mask of zupt_mask holds the due samples of the one ZUPT rule, phase included
    config = EkfConfig(**kw)

    t0, start_from = nav_start(args, inp)
    check_nav_span(imu, gnss, ref, t0, args.end, args.static_duration, inp.imu_path, start_from, inp.gnss_path)
    new = check_outage_windows(windows, t0, float(imu.t[-1]) if args.end is None else args.end, inp.outages_path)
    yaw = None if args.yaw is None else math.radians(args.yaw)
    init = coarse_align(
        imu, gnss, t0, static_duration=args.static_duration, yaw=yaw, lever_arm=lever, check_still=True
    )
    new += gyro_unit_notes(imu, gnss, init, args.static_duration, inp.imu_path)
    new += mounting_notes(args, inp, log)
    for n in new:
        log.warning("%s", n)
    notes += new
    log.info(
        "start %.3f: roll %.2f° pitch %.2f° yaw %.2f°; gyro bias %s °/h",
        t0,
        *np.degrees(init.euler),
        np.round(np.degrees(init.gyro_bias) * 3600, 1),
    )

    imf = in_motion_part(args.imu_model, models)
    # the drive's stops, detected once for both the ZUPTs and the in-motion part's moving flag
    stops = drive_stops(imu, args.static_duration) if args.zupt or imf is not None else None
    zupt = zupt_mask(stops) if args.zupt else None
    args.aiding = read_aiding(args, inp, log)  # GNSS velocity, ...: (source, epochs) each
    args.in_motion_kw = in_motion_kw(imf, stops)
    out = Path(args.out)
    # every output of this run appears at once when it completes (Ctrl-C leaves --out as it was); the files
    # an earlier nav run left (outage_<k>/ of more windows, plots of a run with plots) are removed then
    with staged_run(out, OUTPUTS) as stage:
        _run_and_write(stage, args, imu, gnss, ref, init, config, models, model_name, zupt, notes, windows, lever)
    print(
        f"wrote {out / 'trajectory.nav'}, {out / 'metrics.json'}" + ("" if args.no_plots else " and plots"),
        file=sys.stderr,
    )
    return 0


OUTPUTS = (
    "trajectory.nav",
    "metrics.json",
    "trajectory.png",
    "errors.png",
    "biases.png",
    "outage_*/trajectory.nav",
    "outage_*/metrics.json",
)
"""Every file `imunoise nav` writes into --out (a rerun removes the ones it did not write again)."""


def _run_and_write(out, args, imu, gnss, ref, init, config, models, model_name, zupt, notes, windows, lever) -> None:
    import numpy as np

    from imunoise.nav.ekf import run_ekf

    base_gnss = gnss if args.outage_runs else gnss.without(windows)
    streams = [e for _, e in args.aiding]
    im = getattr(args, "in_motion_kw", {})
    res = run_ekf(imu, base_gnss, init, config, models, t_end=args.end, zupt=zupt, streams=streams, **im)
    duration = float(res.t[-1] - res.t[0])
    write_trajectory(out / "trajectory.nav", res, ref)
    metrics: dict = {"model": model_name, "start": float(res.t[0]), "duration_s": duration, "zupt": bool(args.zupt),
                     "nhc": bool(args.nhc), "in_motion": bool(im)}
    run, err = run_metrics(res, ref, lever, [] if args.outage_runs else windows, duration)
    metrics.update(run)
    metrics["warnings"] = notes
    metrics["mounting"] = mounting_metrics(args, res)
    metrics["gnss_rejected"] = int(np.sum(res.gnss_status == 0))
    metrics["gnss_forced"] = int(np.sum(res.gnss_status == 2))
    metrics.update(aiding_metrics(res.stream_status, args.aiding, [] if args.outage_runs else windows))
    if res.scale_factors is not None:  # --scale-factors: final ŝ, gyro x,y,z then accel x,y,z
        metrics["scale_factors_ppm"] = [float(x) * 1e6 for x in res.scale_factors[-1]]

    runs = []
    if args.outage_runs and windows:
        from tqdm import tqdm

        outs = []
        for k, w in enumerate(tqdm(windows, desc="outage runs", disable=not sys.stderr.isatty())):
            r = run_ekf(imu, gnss.without([w]), init, config, models, t_end=args.end, zupt=zupt, streams=streams,
                        **im)
            sub = out / f"outage_{k + 1}"
            sub.mkdir(exist_ok=True)
            write_trajectory(sub / "trajectory.nav", r, ref)
            mk, e = run_metrics(r, ref, lever, [w], duration)
            if e is not None:
                for src, ep in args.aiding:
                    mk[src.key] = epoch_counts(r.stream_status[src.kind], ep, [w])
                    mk["outages"][0][src.key] = mk[src.key]["in_outages"]
            if e is not None:
                atomic_write_text(sub / "metrics.json", json.dumps(mk, indent=1))
                outs.append(mk["outages"][0])
                runs.append((w, e))
        metrics.update(outage_summary(outs))
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=1))
    if not args.no_plots:
        _plots(out, res, ref, err, windows, runs, lever)
    _print_summary(metrics)


def in_motion_part(model_path: str | None, models: list) -> InMotionFilter | None:
    """The in-motion filter of a model file with an in-motion part (:func:`imunoise.nav.filter_model.in_motion_of`
    on the static ``models``), None without one (the run is then exactly the static model's)."""
    if not model_path:
        return None
    from imunoise.nav.filter_model import in_motion_of

    return in_motion_of(model_path, models)


def drive_stops(imu, static_duration: float) -> Detection:
    """The drive's stops (:func:`imunoise.detect.stop_mask.detect_drive_stops`: the static detector of
    docs/guide/theory.rst, 'Static detection', λ0 learned from the first ``static_duration`` s, a stop), logged."""
    from imunoise.detect.stop_mask import detect_drive_stops

    gyro, accel = imu.rates()
    det = detect_drive_stops(imu.t, accel, gyro, static_duration)
    log.info(
        "stops: λ0 = %.3f m/s², %d stops: %s",
        det.config.lambda0,
        len(det.segments),
        ", ".join(f"{s.t0:.1f}+{s.duration:.1f}s" for s in det.segments),
    )
    return det


def in_motion_kw(imf: InMotionFilter | None, stops: Detection | None) -> dict:
    """``run_ekf``'s in-motion arguments for in-motion filter ``imf`` (:func:`in_motion_part`): the in-motion
    noise while the static detector sees the car moving, the static part at its ``stops`` (:func:`drive_stops`;
    the moving flag of :func:`imunoise.inuse.stops.moving_of`, the stop logic ``online`` shares); {} when ``imf``
    is None (the run is exactly the static model's)."""
    if imf is None:
        return {}
    from imunoise.inuse.stops import moving_of

    moving = moving_of(stops)
    log.info("in-motion part: white factors %s while moving (%.0f %% of the samples), static part at stops",
             [round(w ** 0.5, 2) for w in imf.white], 100.0 * float(moving.mean()))
    return {"in_motion": imf, "moving": moving}


def zupt_mask(stops: Detection) -> np.ndarray:
    """The samples where a ZUPT is due by the one rule of the batch filter and the online engine
    (:func:`imunoise.nav.zupt_policy.zupt_due`) at the drive's ``stops`` (:func:`drive_stops`): a boolean mask over
    the IMU epochs, applied by :func:`~imunoise.nav.ekf.run_ekf` with ``zupt_every = 1``."""
    from imunoise.nav.zupt_policy import ZUPT_AFTER, ZUPT_EVERY, zupt_due

    return zupt_due(stops.static, every=ZUPT_EVERY, after=ZUPT_AFTER)


def _print_summary(m: dict) -> None:
    if "horizontal_rms_m" in m:
        print(
            f"horizontal RMS / p95 / max: {m['horizontal_rms_m']:.3f} / {m['horizontal_p95_m']:.3f} / "
            f"{m['horizontal_max_m']:.3f} m; vertical RMS {m['vertical_rms_m']:.3f} m"
        )
        v = m["velocity_rms_mps"]
        print(f"velocity RMS N/E/D: {v[0]:.3f} / {v[1]:.3f} / {v[2]:.3f} m/s")
    for o in m.get("outages", []):
        if o["end_horizontal_m"] is not None:
            print(
                f"outage {o['start']:.1f} + {o['duration']:.0f} s: end drift horizontal "
                f"{o['end_horizontal_m']:.1f} m, vertical {o['end_vertical_m']:.1f} m"
            )
    if m.get("mean_outage_end_horizontal_m") is not None:
        print(f"mean end-of-outage horizontal drift: {m['mean_outage_end_horizontal_m']:.1f} m")
    print(f"filter time {m['elapsed_s']:.3f} s ({m['realtime_factor']:.0f}× real time)")


def _plots(out: Path, res, ref, err, windows, runs, lever) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from imunoise.nav.earth import llh_to_ned

    origin = res.llh[0]
    est = llh_to_ned(res.antenna_llh(lever), origin)
    fig, ax = plt.subplots(figsize=(7, 7))
    if ref is not None:
        rn = llh_to_ned(ref.llh, origin)
        ax.plot(rn[:, 1], rn[:, 0], "-", color="0.6", lw=3, label="reference")
        for k, (s, d) in enumerate(windows):
            mw = (ref.t >= s) & (ref.t < s + d)
            ax.plot(
                rn[mw, 1],
                rn[mw, 0],
                "-",
                color="tab:orange",
                lw=4,
                alpha=0.6,
                label="outage windows" if k == 0 else None,
            )
    ax.plot(est[:, 1], est[:, 0], "-", color="tab:blue", lw=1, label="EKF")
    for k, ((s, d), _) in enumerate(runs):
        sub = out / f"outage_{k + 1}" / "trajectory.nav"
        if sub.exists():
            from imunoise.io.kfgins import read_reference

            r = read_reference(sub)
            mw = (r.t >= s) & (r.t < s + d)
            rr = llh_to_ned(r.llh[mw], origin)
            ax.plot(rr[:, 1], rr[:, 0], "-", color="tab:red", lw=1, label="EKF in outage" if k == 0 else None)
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("trajectory (GNSS antenna)")
    fig.tight_layout()
    atomic_savefig(fig, out / "trajectory.png", dpi=120)
    plt.close(fig)

    if err is not None:
        fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
        for i, lab in enumerate(("north", "east", "down")):
            axs[i].plot(err.t - err.t[0], err.ned[:, i], lw=0.8, label="full run")
            for (s, d), e in runs:
                mw = (e.t >= s) & (e.t < s + d)
                axs[i].plot(e.t[mw] - err.t[0], e.ned[mw, i], lw=0.8, color="tab:red")
            for s, d in windows:
                axs[i].axvspan(s - err.t[0], s + d - err.t[0], color="tab:orange", alpha=0.15)
            axs[i].set_ylabel(f"{lab} error [m]")
            axs[i].grid(alpha=0.3)
        axs[-1].set_xlabel(f"time since {err.t[0]:.1f} s [s]")
        axs[0].set_title("position error vs reference (shaded: outage windows; red: per-window runs)")
        fig.tight_layout()
        atomic_savefig(fig, out / "errors.png", dpi=120)
        plt.close(fig)

    fig, axs = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    tt = res.t - res.t[0]
    for i, lab in enumerate("xyz"):
        axs[0].plot(tt, np.degrees(res.gyro_error[:, i]) * 3600, lw=0.8, label=f"gyro {lab}")
        axs[1].plot(tt, res.accel_error[:, i] / 1e-5, lw=0.8, label=f"accel {lab}")
    axs[0].set_ylabel("gyro error estimate [°/h]")
    axs[1].set_ylabel("accel error estimate [mGal]")
    axs[1].set_xlabel(f"time since {res.t[0]:.1f} s [s]")
    for a in axs:
        a.grid(alpha=0.3)
        a.legend(ncol=3)
    axs[0].set_title("estimated sensor errors (bias + augmented states)")
    fig.tight_layout()
    atomic_savefig(fig, out / "biases.png", dpi=120)
    plt.close(fig)
