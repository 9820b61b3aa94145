"""`imunoise export`: a model JSON to Kalibr / OpenVINS / ORB-SLAM3 noise parameters (SPEC §12)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imunoise.cli.options import add_topic

EXAMPLES = """examples:
  imunoise export fit/imu_model.json --to kalibr                     # -> fit/imu.yaml
  imunoise export fit/imu_model.json --to openvins --inflate white=2,rw=10
  imunoise export fit/imu_model.json --to orbslam3 --out - | less
  imunoise export fit_gz/model.json --to kalibr                       # a single-axis fit (sensor from its unit)
  imunoise export fit/imu_model.json --horizon 60                     # match up to 60 s only

Values written are continuous-time densities (the format's convention) [rad/s/sqrt(Hz), rad/s^2/sqrt(Hz);
m/s^2/sqrt(Hz), m/s^3/sqrt(Hz)]. The fitted model is mapped to the pair (N, K) by what the filter will
see: the white-noise + random-walk pair whose Allan variance best matches the model's, in log-variance
least squares over averaging times from the update period 1/f to the horizon (default: the longest scale
of the data the model was fitted on; --horizon S), with each line at or below the model's AV as in an
IEEE Allan reading (K over the whole range, N where the model falls like white noise). Exact closed
forms: WN -> N = sigma*sqrt(dt); RW -> K = gamma/sqrt(dt); QN -> white with per-sample variance 2Q^2;
an AR1 faster than one update -> white sigma/(1-phi)*sqrt(dt) (-> sigma_GM*sqrt(2*T_c)); a drift -> the
random walk with the same AV at the horizon.
A Gauss-Markov term is white on scales >> T_c and a random walk on scales << T_c: slow ones go to K,
fast ones to N, one in between is neither (its Allan bump is what the pair cannot follow). K is never the
Allan-variance minimum. Beside each pair: the tau range matched on and the worst AV ratio between the
written pair and each axis's model; a warning on stderr when it exceeds 2. Per axis, stderr says which
process went where. A zero density is never written: unidentified white noise takes the largest white
line under the model's AV (exit 2 when the model has nothing white-like); an unidentified random walk
takes half the largest one under it (noted). Three axes are combined by their maximum (--combine rms for
the root mean square). Every value has its unit and discrete per-sample equivalent in a comment."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="write Kalibr / OpenVINS / ORB-SLAM3 IMU noise parameters from a model JSON",
        description="Export a fitted model (multi-axis imu_model.json or a single-axis model.json) to the "
        "IMU noise parameters of VIO/INS stacks.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("model", help="imu_model.json (six axes) or model.json (one axis)")
    p.add_argument("--to", choices=["kalibr", "openvins", "orbslam3", "json"], default="kalibr", dest="fmt")
    p.add_argument(
        "--sensor",
        choices=["gyro", "accel"],
        help="sensor: export only this one; for a single-axis fit, which sensor it is when its unit/column do not say",
    )
    p.add_argument("--combine", choices=["max", "rms"], default="max", help="how to combine x/y/z (default max)")
    p.add_argument("--inflate", help="inflation factors applied visibly, e.g. white=2,rw=10")
    p.add_argument(
        "--horizon",
        type=float,
        metavar="S",
        help="longest averaging time [s] the pair is matched on (default: the longest scale of the fitted data)",
    )
    add_topic(p, "the sensor_msgs/Imu topic (written in the file; default: the model's bag topic, else /imu0)")
    p.add_argument("--out", help="output file ('-' for stdout; default: the format's file name beside MODEL)")
    p.set_defaults(func=run)


def load_for_export(path: str | Path):
    """The model of ``path`` as :func:`imunoise.imu_model.load_model` reads it; an incomplete file becomes a
    one-line :class:`ModelError` instead of a traceback."""
    from imunoise.errors import ModelError
    from imunoise.imu_model import ImuModel, load_model

    try:
        model = load_model(path)
        if isinstance(model, ImuModel):
            for axis in model.axes:
                model.fit(axis)  # every axis must read back as a fit
        return model
    except KeyError as exc:
        raise ModelError(f"{path} is an incomplete imunoise model file (missing {exc.args[0]!r}); refit it") from exc
    except (TypeError, ValueError, AttributeError) as exc:
        raise ModelError(f"{path} is not a readable imunoise model file: {exc}") from exc


def report(sensors, file=None) -> None:
    """Per axis: the pair, its τ range, worst AV ratio and which process went where; notes and warnings."""
    from imunoise.export import axis_lines

    file = file or sys.stderr
    for sn in sensors:
        for a in sn.axes:
            for line in axis_lines(a):
                print(line, file=file)
        for n in sn.notes:
            print(f"note: {n}", file=file)
        for w in sn.warnings:
            print(f"warning: {w}", file=file)


def run(args: argparse.Namespace) -> int:
    from imunoise.errors import ModelError
    from imunoise.export import DEFAULT_FILENAMES, export_text, model_sensors, parse_inflate
    from imunoise.imu_model import ImuModel

    if args.horizon is not None and not args.horizon > 0:
        raise ModelError(f"--horizon must be a positive time in seconds, got {args.horizon}")
    model = load_for_export(args.model)
    out = None
    if args.out != "-":
        out = Path(args.out) if args.out else Path(args.model).parent / DEFAULT_FILENAMES[args.fmt]
        if out.resolve() == Path(args.model).resolve():
            raise ModelError(f"--out {out} is the input model file; it would be overwritten: choose another path")
    inflate = parse_inflate(args.inflate)
    text = export_text(
        model,
        args.fmt,
        sensor=args.sensor,
        topic=args.topic,
        combine=args.combine,
        inflate=inflate,
        source=str(args.model),
        horizon_s=args.horizon,
    )
    sensors = model_sensors(model, args.sensor, args.combine, inflate, args.horizon)
    if isinstance(model, ImuModel):
        for s in ("gyro", "accel"):
            if args.sensor in (None, s) and not model.sensor_axes(s):
                print(f"note: no {s} axes in {args.model}; its keys are commented out", file=sys.stderr)
    report(sensors.values())
    if out is None:
        sys.stdout.write(text)
        return 0
    out.write_text(text)
    print(f"wrote {out}", file=sys.stderr)
    return 0
