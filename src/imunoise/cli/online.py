"""`imunoise online`: the online GMWM INS/GNSS navigator over recorded files
(docs/guide/theory.rst, 'Online engine' and 'Interfaces')."""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from pathlib import Path

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
    add_criterion,
    add_deprecated_alias,
    add_nav_input_options,
    check_learn_from,
    check_learn_window_is_stop,
    check_nav_span,
    check_outage_windows,
    nonnegative_float,
    positive_float,
)
from imunoise.errors import ModelError
from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run

EXAMPLES = """examples:
  imunoise online --data data/drive_0708 --out out/online
  imunoise online --data data/drive_0708 --outages data/drive_0708/outages_60s.txt --outage-runs --out out/on
  imunoise online --imu imu.txt --gnss gnss.txt --ref ref.nav --lever-arm 0 -0.05 0 --zupt --out out/on
  imunoise online --data sim/ --criterion wvic --latency 0 --out out/sim_online
  imunoise online --data sim/ --gnss-vel --out out/sim_online_vel   # + the manifest's GNSS velocity
  imunoise online --imu drive.bag --gnss rtk.pos --lever-arm 0 -0.05 0 --out out/bag_online   # ROS bag + RTKLIB
  imunoise online --imu next.bag --gnss next.pos --earlier-static out/bag_online/static.npz --out out/next

Writes DIR/trajectory.nav (KF-GINS result format, IMU point), DIR/metrics.json
(docs/guide/theory.rst, 'Navigation filter' keys, errors of
the GNSS antenna at the reference epochs, m and m/s; plus the modelling timing), DIR/events.jsonl (stops,
identification per axis with structure/GOF/time, refits, model swaps, gate open/close, rejected fits) and
DIR/model.json (the last GMWM fit of every axis, per-sample SI parameters and continuous equivalents) and
DIR/static.npz (the static pieces the model was fitted on: --earlier-static of the next drive of this IMU).
The static detector learns λ0 from the first --learn-from s of the IMU file, which must be a stop.
The inputs are checked as in `imunoise nav`; the outputs appear in DIR together when the run completes
(Ctrl-C leaves DIR as it was) and files an earlier online run left there (model.json, static.npz) are removed."""

log = logging.getLogger("imunoise.online")


EXPERIMENTAL_LIKELIHOOD = ("--motion-noise-statistic likelihood is experimental research code: not frozen nor "
                           "reported on fresh seeds (docs/evidence/in_motion_likelihood.md); do not use it for results")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "online",
        help="online GMWM: detect stops, model the IMU while driving, hot-swap the model into the EKF",
        description="Run the online GMWM navigator (docs/guide/theory.rst, 'Online engine') on IMU + GNSS files.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_nav_input_options(p)
    add_mount_option(p)
    p.add_argument("--imu-model", help="IMU error models: model JSON the run starts with (default: the plain "
                   "default WN+RW+GM)")
    add_criterion(p)
    p.add_argument("--min-static", type=positive_float, default=20.0,
                   help="static data [s] before the structure identification (default 20)")
    p.add_argument("--latency", type=nonnegative_float,
                   help="fixed delay [s] from a stop's end to its model in the filter (default: the measured compute "
                   "time)")
    p.add_argument("--worker", choices=("inline", "thread"), default="inline",
                   help="inline = deterministic replay (default); thread = background thread, never blocks")
    p.add_argument("--zupt", action="store_true", help="zero-velocity updates at detected stops (ZUPT/ZARU)")
    add_aiding_options(p)
    p.add_argument("--no-rate-gate", action="store_true",
                   help="do not use the 30 °/s angular-rate gate of the static detector's noise model")
    add_deprecated_alias(p, "--no-gate", "--no-rate-gate")
    add_deprecated_alias(p, "--model", "--imu-model")
    p.add_argument("--scale-factors", action="store_true",
                   help="add gyro and accel scale-factor states (to the EKF: KF-GINS' 21-state filter)")
    p.add_argument("--no-floor", action="store_true", help="no plain-default floor on the filter noise")
    p.add_argument("--learn-motion-noise", action="store_true",
                   help="learn in-motion gyro noise while driving: shadow filters rehearse GNSS outages on the data "
                        "seen and the live filter takes what drifts least (the gmwm_dyn method; "
                        "imunoise.online.motion_noise)")
    p.add_argument("--motion-noise-prior", metavar="METRICS_JSON",
                   help="start the in-motion noise learner with what it learned on an earlier drive of the same IMU "
                        "in the same vehicle: that run's metrics.json (implies --learn-motion-noise)")
    p.add_argument("--motion-noise-statistic", default="drift", metavar="STAT",
                   help="the learner's evidence: drift (rehearsed-outage drift, paired t tests; the reported default) "
                        "or likelihood (EXPERIMENTAL research code, not reported: likelihood-ratio tests on the GNSS "
                        "innovations; warns and records the warning in metrics.json)")
    p.add_argument("--earlier-static", nargs="+", metavar="STATIC_NPZ",
                   help="pool the stops of earlier drives of the same IMU with this drive's: the static.npz those "
                        "runs wrote (the last of a chain holds all before it); the model of the earlier stops runs "
                        "from the first sample")
    p.add_argument("--learn-from", type=positive_float, default=10.0, metavar="S",
                   help="learn λ0 from the first S seconds (of the IMU file: a known stop; default 10)")
    p.add_argument("--lambda0", type=positive_float, help="detector threshold λ0 [m/s²] (fixed, instead of learning "
                   "it)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from imunoise.detect import DetectorConfig
    from imunoise.imu import AXES
    from imunoise.io.jsonutil import json_default
    from imunoise.io.static_npz import load_static_pieces, save_static_pieces
    from imunoise.nav.align import coarse_align
    from imunoise.nav.defaults import EkfConfig, load_axis_models
    from imunoise.noise.imu_model import ImuModel
    from imunoise.online import MotionNoiseConfig, MotionNoisePrior, OnlineConfig, OnlineNavigator
    from imunoise.online.learner.candidates import LIKELIHOOD_FAMILIES
    from imunoise.online.learner.config import STATISTICS

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.lambda0 is not None and not (math.isfinite(args.lambda0) and args.lambda0 > 0):
        raise ModelError(f"--lambda0 must be a positive threshold in m/s², got {args.lambda0:g}")
    if args.motion_noise_statistic not in STATISTICS:
        raise ModelError(f"--motion-noise-statistic must be one of {', '.join(STATISTICS)}, got "
                         f"{args.motion_noise_statistic!r}")
    motion = None  # the learner's prior is read first: a bad file fails before anything is made
    if args.learn_motion_noise or args.motion_noise_prior:
        prior = MotionNoisePrior.load(args.motion_noise_prior) if args.motion_noise_prior else None
        lik = args.motion_noise_statistic == "likelihood"
        motion = MotionNoiseConfig(prior=prior, **({"statistic": "likelihood", "families": LIKELIHOOD_FAMILIES}
                                                   if lik else {}))
    inp = read_nav_inputs(args, log)
    imu, gnss, ref, notes, windows, lever = inp.imu, inp.gnss, inp.ref, inp.notes, inp.windows, inp.lever
    earlier = load_static_pieces(args.earlier_static, imu.rate_hz) if args.earlier_static else None
    t0, start_from = nav_start(args, inp)
    check_nav_span(imu, gnss, ref, t0, None, args.static_duration, inp.imu_path, start_from, inp.gnss_path)
    n_read = len(notes)
    notes += check_outage_windows(windows, t0, float(imu.t[-1]), inp.outages_path)
    if args.lambda0 is None:  # λ0 is learned from the first --learn-from s of the IMU file: a known stop
        check_learn_from(args.learn_from, imu.t, DetectorConfig().window, imu.rate_hz, inp.imu_path)
        if ref is not None:
            notes += check_learn_window_is_stop(ref, float(imu.t[0]), args.learn_from, 0.2, inp.ref_path)
    yaw = None if args.yaw is None else math.radians(args.yaw)
    init = coarse_align(imu, gnss, t0, static_duration=args.static_duration, yaw=yaw, lever_arm=lever,
                        check_still=True)
    notes += gyro_unit_notes(imu, gnss, init, args.static_duration, inp.imu_path)
    notes += mounting_notes(args, inp, log)
    if motion is not None and motion.statistic == "likelihood":
        notes.append(EXPERIMENTAL_LIKELIHOOD)
    for n in notes[n_read:]:
        log.warning("%s", n)
    aiding = read_aiding(args, inp, log)  # GNSS velocity, ...: (source, epochs) each
    status: dict = {}  # the last run's status per epoch, by kind
    rate = imu.rate_hz
    models = load_axis_models(args.imu_model, rate) if args.imu_model else None
    in_motion = _in_motion(args, imu, models, rate)  # (part, static models, moving flag) or None
    if in_motion is not None:
        from imunoise.online.in_motion import initial_models

        models = initial_models(in_motion[0], in_motion[1], rate)
    detector = DetectorConfig(lambda0=args.lambda0) if args.lambda0 is not None else None
    config = OnlineConfig(
        ekf=EkfConfig(lever_arm=tuple(lever), scale_factors=args.scale_factors),
        detector=detector, learn_lambda0_s=args.learn_from,
        min_static_s=args.min_static, criterion=args.criterion, latency=args.latency, worker=args.worker,
        gate=not args.no_rate_gate, zupt=args.zupt, floor="none" if args.no_floor else "default",
        motion_noise=motion,
    )
    out = Path(args.out)
    duration = float(imu.t[-1] - t0)

    def one(g, desc):
        bar = tqdm(total=len(imu.t), desc=desc, unit="sample", unit_scale=True, disable=not sys.stderr.isatty(),
                   leave=False)

        def prog(k, n):
            bar.n = k
            bar.refresh()

        nav = OnlineNavigator(config, init, imu_rate_hz=rate, initial_models=models, earlier_static=earlier)
        if aiding:
            nav.add_streams(*(e for _, e in aiding))
        if in_motion is not None:  # the in-motion noise while moving, the static part at stops
            from imunoise.online.in_motion import attach_in_motion

            attach_in_motion(nav, *in_motion)
        r = nav.run(imu, g, progress=prog)
        status.update(nav.state.streams.status() if aiding else {})
        bar.close()
        return r

    # every output of this run appears at once when it completes (Ctrl-C leaves --out as it was); the files an
    # earlier online run left (model.json, static.npz of a run that had them) are removed then
    with staged_run(out, OUTPUTS) as stage:
        base = gnss if args.outage_runs else gnss.without(windows)
        cpu0 = time.process_time()
        res = one(base, "online")
        cpu_s = time.process_time() - cpu0  # the whole process (every thread) during the run
        write_trajectory(stage / "trajectory.nav", res, ref)
        with atomic_path(stage / "events.jsonl") as tmp:
            res.write_events(tmp)
        metrics: dict = {"start": float(res.t[0]) if res.t.size else t0, "duration_s": duration,
                         "lambda0_m_s2": res.lambda0, "static_s": float(sum(s.duration for s in res.segments)),
                         "earlier_static_s": float(sum(p.shape[0] for p in earlier or ()) / rate),
                         "timing": res.timing, "config": {"criterion": config.criterion, "zupt": config.zupt,
                                                           "floor": config.floor, "latency": config.latency,
                                                           "learn_motion_noise": motion is not None,
                                                           "motion_noise_prior": args.motion_noise_prior,
                                                           **({"motion_noise_statistic": "likelihood"} if motion
                                                              and motion.statistic == "likelihood" else {})}}
        metrics.update(run_metrics(res, ref, lever, [] if args.outage_runs else windows, duration)[0])
        metrics.update(aiding_metrics(status, aiding, [] if args.outage_runs else windows))
        metrics["cpu_s"] = cpu_s
        metrics["cpu_realtime_factor"] = duration / cpu_s if cpu_s > 0 else None
        if args.outage_runs and windows:
            outs = []
            for k, w in enumerate(windows):
                r = one(gnss.without([w]), f"outage {k + 1}/{len(windows)}")
                mk, e = run_metrics(r, ref, lever, [w], duration)
                if e is not None:
                    for src, ep in aiding:
                        mk["outages"][0][src.key] = epoch_counts(status[src.kind], ep, [w])["in_outages"]
                    outs.append(mk["outages"][0])
            metrics.update(outage_summary(outs))
        end = [e for e in res.events if e["event"] == "motion_noise_end"]
        if end:
            metrics["motion_noise"] = {"sigma_dph": end[-1]["sigma_dph"], "tc_s": end[-1]["tc_s"],
                                       "axes": ["x", "y", "z"],
                                       "rehearsal_rounds": end[-1]["n_rehearsals"],
                                       "carried_rounds": end[-1]["n_prior"], "evidence": end[-1]["evidence"]}
        metrics["warnings"] = notes
        metrics["mounting"] = mounting_metrics(args, res)
        atomic_write_text(stage / "metrics.json", json.dumps(metrics, indent=1, default=json_default))
        fits = {ax: f.to_dict() for ax, f in zip(AXES, res.fits, strict=True) if f is not None}
        if fits:
            ImuModel(float(rate), fits).save(stage / "model.json")
        wrote = [out / "trajectory.nav", out / "metrics.json", out / "events.jsonl"]
        wrote += [out / "model.json"] if fits else []
        wrote += [out / "static.npz"] if res.static_pieces else []
        if res.static_pieces:
            save_static_pieces(stage / "static.npz", res.static_pieces, rate)
    _print(metrics, res)
    print(f"wrote {', '.join(str(w) for w in wrote)}", file=sys.stderr)
    return 0


OUTPUTS = ("trajectory.nav", "metrics.json", "events.jsonl", "model.json", "static.npz")
"""Every file `imunoise online` writes into --out (a rerun removes the ones it did not write again)."""


def _learned(e: dict, nothing: str) -> str:
    """The in-motion processes of a ``motion_noise``/``motion_noise_end`` event, or ``nothing``."""
    return ", ".join(f"{a} {sg:g} °/h (T_c {tc:g} s)" for a, sg, tc in zip("xyz", e["sigma_dph"], e["tc_s"])
                     if sg > 0) or nothing


def _print(m: dict, res) -> None:
    for e in res.events:
        if e["event"] == "earlier_static":
            print(f"pooled {e['static_s']:.1f} s of static data in {e['pieces']} pieces from earlier drives")
        if e["event"] in ("identified", "refit"):
            axes = "; ".join(f"{a}: {v['structure']}" for a, v in e.get("axes", {}).items())
            print(f"{e['event']} at {e['t']:.1f} s with {e['static_total_s']:.1f} s static data in "
                  f"{e['elapsed_s']:.3f} s: {axes}")
        elif e["event"] == "motion_noise":
            carried = f" ({e['n_prior']} of them carried from earlier drives)" if e.get("n_prior") else ""
            print(f"in-motion gyro noise at {e['t']:.1f} s after {e['n_rehearsals']} rehearsal rounds{carried}: "
                  f"{_learned(e, 'nothing')}")
        elif e["event"] == "motion_noise_end":
            carried = f" and {e['n_prior']} carried from earlier drives" if e.get("n_prior") else ""
            print(f"in-motion gyro noise learned over {e['n_rehearsals']} rehearsal rounds{carried}: "
                  f"{_learned(e, 'nothing (no candidate beat the static model)')}")
        elif e["event"] == "rejected":
            print(f"rejected at {e['t']:.1f} s: {e.get('axis', '')} {e['reason']}")
        elif e["event"] == "warm_up":
            print(f"warm-up of the fitting kernels: {e['error']}" if "error" in e else
                  f"warm-up of the fitting kernels: {e['time_s']:.2f} s ({e['compiled']} compiled, "
                  f"{e['loaded']} loaded from numba's cache)")
    if "horizontal_rms_m" in m:
        print(f"horizontal RMS / p95 / max: {m['horizontal_rms_m']:.3f} / {m['horizontal_p95_m']:.3f} / "
              f"{m['horizontal_max_m']:.3f} m; vertical RMS {m['vertical_rms_m']:.3f} m")
    for o in m.get("outages", []):
        if o.get("end_horizontal_m") is not None:
            print(f"outage {o['start']:.1f} + {o['duration']:.0f} s: end drift horizontal "
                  f"{o['end_horizontal_m']:.1f} m, vertical {o['end_vertical_m']:.1f} m")
    if m.get("mean_outage_end_horizontal_m") is not None:
        print(f"mean end-of-outage horizontal drift: {m['mean_outage_end_horizontal_m']:.1f} m")
    # two clocks: the wall clock is what the user waits (it counts whatever else the machine runs), the CPU time
    # of the process is what the engine costs (BENCHMARKS.md's figure, there after a first run that loads kernels)
    cpu = (f", CPU {m['cpu_s']:.2f} s ({m['cpu_realtime_factor']:.0f}× real time by CPU time)"
           if m.get("cpu_realtime_factor") else "")
    print(f"online run: wall clock {m['elapsed_s']:.2f} s ({m['realtime_factor']:.0f}× real time){cpu}")


def _in_motion(args: argparse.Namespace, imu, models, rate: float):
    """(in-motion part, static models, moving flag per IMU sample) of a model file with an in-motion part, else
    None. The moving flag is ``nav``'s (:func:`imunoise.inuse.stops.moving_flag`)."""
    if not args.imu_model:
        return None
    from imunoise.noise.imu_model import read_model_json
    from imunoise.noise.in_motion import InMotionPart

    d = read_model_json(args.imu_model)
    if not isinstance(d, dict) or d.get("in_motion") is None:
        return None
    from imunoise.inuse.stops import moving_flag

    log.info("in-motion part of %s: used while moving, the static part at stops", args.imu_model)
    return InMotionPart.from_dict(d["in_motion"]), models, moving_flag(imu, args.static_duration)
