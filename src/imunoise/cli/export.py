"""`imunoise export`: a model JSON to Kalibr / OpenVINS / ORB-SLAM3 noise parameters (SPEC §12)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXAMPLES = """examples:
  imunoise export fit/imu_model.json --to kalibr                     # -> fit/imu.yaml
  imunoise export fit/imu_model.json --to openvins --inflate white=2,rw=10
  imunoise export fit/imu_model.json --to orbslam3 --out - | less
  imunoise export fit_gz/model.json --sensor gyro --to kalibr        # a single-axis fit

Values written are continuous-time densities (the format's convention):
  noise density  N    = sqrt((sigma_WN^2 + 2 Q^2) dt)               [rad/s/sqrt(Hz), m/s^2/sqrt(Hz)]
  random walk    K_eq = sqrt(gamma^2 f + sum_i 2 sigma_GM,i^2/T_c,i) [rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)]
K_eq folds the Gauss-Markov terms (no slot in these formats) into the random walk; it is never the
Allan-variance minimum. Three axes are combined by their maximum (--combine rms for the root mean square).
Every value has its unit and discrete per-sample equivalent in a comment."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="write Kalibr / OpenVINS / ORB-SLAM3 IMU noise parameters from a model JSON",
        description="Export a fitted model (multi-axis imu_model.json or a single-axis model.json) to the "
        "IMU noise parameters of VIO/INS stacks.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("model", help="imu_model.json (six axes) or model.json (one axis, then --sensor)")
    p.add_argument("--to", choices=["kalibr", "openvins", "orbslam3", "json"], default="kalibr", dest="fmt")
    p.add_argument("--sensor", choices=["gyro", "accel"], help="which sensor a single-axis fit is (or export only one)")
    p.add_argument("--combine", choices=["max", "rms"], default="max", help="how to combine x/y/z (default max)")
    p.add_argument("--inflate", help="inflation factors applied visibly, e.g. white=2,rw=10")
    p.add_argument("--topic", help="rostopic written in the file (default: the bag topic of the model, else /imu0)")
    p.add_argument("--out", help="output file ('-' for stdout; default: the format's file name beside MODEL)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.export import DEFAULT_FILENAMES, export_text, parse_inflate, sensor_noise
    from imunoise.imu_model import ImuModel, load_model

    model = load_model(args.model)
    text = export_text(
        model,
        args.fmt,
        sensor=args.sensor,
        topic=args.topic,
        combine=args.combine,
        inflate=parse_inflate(args.inflate),
        source=str(args.model),
    )
    if args.out == "-":
        sys.stdout.write(text)
        return 0
    out = Path(args.out) if args.out else Path(args.model).parent / DEFAULT_FILENAMES[args.fmt]
    out.write_text(text)
    sensors = ["gyro", "accel"] if isinstance(model, ImuModel) and args.sensor is None else [args.sensor]
    for s in sensors:
        if isinstance(model, ImuModel) and not model.sensor_axes(s):
            print(f"note: no {s} axes in {args.model}; its keys are commented out", file=sys.stderr)
            continue
        sn = sensor_noise(model, s, combine=args.combine, inflate=parse_inflate(args.inflate))
        for n in sn.notes:
            print(f"note: {n}", file=sys.stderr)
    print(f"wrote {out}", file=sys.stderr)
    return 0
