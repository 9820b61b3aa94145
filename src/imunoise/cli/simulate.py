"""`imunoise simulate`: write a simulated urban drive (or a long static recording) with known truth."""

from __future__ import annotations

import argparse
import gzip
import io
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

from imunoise.cli.options import int_at_least, positive_float, prepare_out_dir
from imunoise.errors import ModelError
from imunoise.io.atomic import staged_dir

if TYPE_CHECKING:
    import numpy as np

EXAMPLES = """examples:
  imunoise simulate --duration 600 --stops 3 --imu-model "3*AR1+WN+RW" --seed 1 --out out/sim/drive1
  imunoise simulate --duration 900 --stops 5 --imu-model mems --gnss-rate 1 --outages outages.txt --out out/sim/d2
  imunoise simulate --imu-model models.json --clean --out out/sim/noisefree
  imunoise simulate --static --duration 7200 --imu-model mems --seed 3 --out out/sim/static2h
  imunoise simulate --motion-noise none --seed 1 --out out/sim/static_law   # moving errors = static model

--imu-model accepts a preset name (mems, tactical: 3*AR1+WN+RW with consumer/tactical values; paper: the gyros
of paper Table 4 with mems accelerometers), a structure
string (parameters from the mems preset, up to 4 AR1 plus WN, QN, RW, DR), a JSON file with per-axis
models ({"gx": {"model": "2*AR1 + WN", "params": {...}}, ..., or "gyro"/"accel" groups}), or "none".
Model parameters are per sample at the IMU rate (rad/s for gyros, m/s² for accelerometers).
Outage files hold "start duration" per line in s from the start of the drive (or GPS SOW when the start
is at or after --start-sow).

written files: imu.txt (KF-GINS increments with errors), imu_true.txt, gnss.txt, ref.nav (the GNSS antenna
point, like the shared real drive's reference: position and velocity of the antenna, body attitude),
outages.txt, truth.json (models, moving-regime models under the motion law, turn-on biases, stops, turns,
speed profile), dataset.json (docs/guide/theory.rst, 'Interfaces'), and one file per measurement source of
imunoise.nav.aiding_sources, named in dataset.json (gnss_vel.txt: antenna velocity, 5 cm/s noise; seeded).
--static writes imu.txt, imu_rate.csv (sow,gx,gy,gz,ax,ay,az) and truth.json."""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="simulate an urban drive (IMU, GNSS, reference, truth) or a static recording",
        description="Simulate an urban drive with known truth (docs/guide/theory.rst, 'Simulator') and write KF-GINS "
                    "files.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--duration", type=positive_float, default=600.0,
                   help="length of the simulated recording [s] (default 600)")
    p.add_argument("--stops", type=int_at_least(0), default=4,
                   help="traffic-light stops of the simulated drive (default 4)")
    p.add_argument(
        "--stop-range",
        type=float,
        nargs=2,
        default=(5.0, 90.0),
        metavar=("MIN", "MAX"),
        help="stop duration range, s (default 5 90)",
    )
    p.add_argument("--static-start", type=float, default=60.0, help="static period at the start, s (default 60)")
    p.add_argument("--imu-model", default="mems",
                   help="IMU error models: preset (mems, tactical, paper), structure, model JSON or "
                   "'none' (default mems)")
    p.add_argument(
        "--motion-noise",
        default=None,
        metavar="LAW|FILE.json",
        help="motion law of the IMU errors (imunoise.sim.motion): drive0708 (default: white noise and gyro y/z "
        "bias wander grow with speed, calibrated on the real drive; replaces the vibration term), none "
        "(errors while moving = the static model; the default with --clean), another shipped law "
        "(gyro_departure_step, gyro_moving_gm, accel_moving_gm, warmup) or a law file FILE.json",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--imu-rate", type=positive_float, default=100.0, help="IMU rate, Hz (default 100)")
    p.add_argument("--gnss-rate", type=positive_float, default=1.0, help="GNSS rate, Hz (default 1)")
    p.add_argument("--ref-rate", type=float, default=10.0, help="reference rate, Hz; 0 = IMU rate (default 10)")
    p.add_argument(
        "--gnss-sigma",
        type=float,
        nargs=3,
        default=(1.0, 1.0, 2.0),
        metavar=("N", "E", "D"),
        help="GNSS position σ, m (default 1 1 2)",
    )
    p.add_argument(
        "--gnss-tau",
        type=float,
        default=0.0,
        help="GNSS noise correlation time, s (urban multipath; default 0 = white)",
    )
    p.add_argument("--outlier-rate", type=float, default=0.0, help="fraction of GNSS epochs with a gross error")
    p.add_argument("--outages", type=Path, help="outage windows: a file of 'start duration' per line [s]")
    p.add_argument("--remove-outages", action="store_true", help="also drop the outage epochs from gnss.txt")
    p.add_argument(
        "--lever-arm",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("X", "Y", "Z"),
        help="GNSS antenna position in body FRD from the IMU [m] (default 0 0 0)",
    )
    p.add_argument(
        "--start-llh",
        type=float,
        nargs=3,
        default=(40.0966, -105.147, 1601.0),
        metavar=("LAT", "LON", "H"),
        help="start position: lat, lon [deg], ellipsoidal height [m] (default 40.0966 -105.147 1601)",
    )
    p.add_argument("--start-sow", type=float, default=100000.0, help="GPS SOW of the first sample")
    p.add_argument("--clean", action="store_true", help="no turn-on bias, vibration, motion noise or outliers")
    p.add_argument("--gzip", action="store_true", help="gzip imu.txt, imu_true.txt and ref.nav")
    p.add_argument("--static", action="store_true", help="a static recording instead of a drive")
    p.add_argument(
        "--out", type=Path, default=Path("out/simulate"), help="output folder (default out/simulate, git-ignored)"
    )
    p.set_defaults(func=run)


def check_start_llh(llh) -> None:
    """Refuse a ``--start-llh`` that is no place on Earth (latitude beyond ±90°, longitude outside
    [−180°, 360°), height below −1000 km or above 100 km of the ellipsoid)."""
    lat, lon, h = (float(x) for x in llh)
    if not -90.0 <= lat <= 90.0:
        raise ModelError(f"--start-llh: latitude {lat:g}° is not within ±90° (the order is LAT LON H, degrees)")
    if not -180.0 <= lon < 360.0:
        raise ModelError(f"--start-llh: longitude {lon:g}° is not within [−180°, 360°) (the order is LAT LON H)")
    if not -1.0e6 < h < 1.0e5:
        raise ModelError(f"--start-llh: height {h:g} m is not an ellipsoidal height near the Earth's surface [m]")


def _models_arg(text: str):
    return None if text.lower() in ("none", "clean", "") else text


def run(args: argparse.Namespace) -> int:
    from imunoise.io.kfgins import read_outages, write_imu
    from imunoise.sim import DriveConfig, simulate_drive, simulate_static
    from imunoise.sim.motion import DEFAULT_MOTION, motion_arg

    t0 = time.perf_counter()
    check_start_llh(args.start_llh)
    models = _models_arg(args.imu_model)
    # a bad preset fails before anything is written
    motion = motion_arg(args.motion_noise or ("none" if args.clean else DEFAULT_MOTION))
    prepare_out_dir(args.out)  # an unusable --out fails before the simulation
    if args.static:
        rec = simulate_static(models, args.duration, args.imu_rate, args.seed, start_sow=args.start_sow)
        suffix = ".gz" if args.gzip else ""
        # the files only make sense together: written into a staging folder, moved in when all are done
        with staged_dir(args.out) as stage:
            write_imu(stage / f"imu.txt{suffix}", rec.imu)
            _write_rate_csv(stage / f"imu_rate.csv{suffix}", rec.t, rec.rates)
            (stage / "truth.json").write_text(json.dumps(rec.truth, indent=1))
        print(
            f"static recording: {len(rec.t)} samples at {args.imu_rate:g} Hz ({args.duration:g} s) "
            f"-> {args.out} in {time.perf_counter() - t0:.1f} s"
        )
        return 0

    outages: list[tuple[float, float]] = []
    if args.outages is not None:
        for s, d in read_outages(args.outages):
            outages.append((s - args.start_sow if s >= args.start_sow else s, d))
    kw = dict(
        duration_s=args.duration,
        n_stops=args.stops,
        stop_range_s=tuple(args.stop_range),
        static_s=args.static_start,
        imu_rate_hz=args.imu_rate,
        gnss_rate_hz=args.gnss_rate,
        ref_rate_hz=None if args.ref_rate <= 0 else args.ref_rate,
        gnss_sigma_m=tuple(args.gnss_sigma),
        outlier_rate=args.outlier_rate,
        gnss_noise_tau_s=args.gnss_tau,
        outages=outages,
        remove_outages=args.remove_outages,
        lever_arm_m=tuple(args.lever_arm),
        start_sow=args.start_sow,
        start_llh=tuple(args.start_llh),
        seed=args.seed,
        motion_noise=motion,
    )
    cfg = DriveConfig.noise_free(**kw) if args.clean else DriveConfig(**kw)
    if outages and max(s + d for s, d in outages) > cfg.duration_s:
        raise ModelError("an outage window ends after the drive; give outage starts in s from the start or SOW")
    drive = simulate_drive(cfg, models, args.seed)
    from imunoise.nav.aiding_sources import write_simulated
    # IMU, GNSS, reference and truth only make sense together: an interrupted run leaves none of them
    with staged_dir(args.out) as stage:
        drive.write(stage, compress=args.gzip)
        write_simulated(drive, stage, args.seed)  # GNSS velocity, ...: one file each, named in dataset.json
    out = args.out
    tr = drive.truth
    stops = ", ".join(f"{b - a:.0f}" for a, b in tr["stops"]) or "none"
    print(
        f"simulated drive: {cfg.duration_s:g} s, {tr['distance_m'] / 1000:.2f} km, max speed "
        f"{tr['max_speed_mps']:.1f} m/s, max turn rate {tr['max_turn_rate_deg_s']:.0f} °/s, "
        f"stops [s]: {stops}; IMU model: {_describe(drive.imu_models)}, motion noise {motion} -> {out} "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0


def _describe(models: dict) -> str:
    kinds = {str(m) for m in models.values()}
    return "none" if not kinds else " | ".join(sorted(kinds))


def _write_rate_csv(path: Path, t: np.ndarray, rates: np.ndarray) -> None:
    """Rates as CSV with the header ``sow,gx,gy,gz,ax,ay,az`` (rad/s, m/s²), gzip by suffix."""
    import numpy as np

    buf = io.StringIO()
    buf.write("sow,gx,gy,gz,ax,ay,az\n")
    np.savetxt(buf, np.column_stack([t, rates]), fmt=["%.9f"] + ["%.12e"] * 6, delimiter=",")
    if path.suffix == ".gz":
        with gzip.open(path, "wt", encoding="utf-8") as fh:
            fh.write(buf.getvalue())
    else:
        path.write_text(buf.getvalue(), encoding="utf-8")
