"""`imunoise export`: a model JSON to Kalibr / OpenVINS / ORB-SLAM3 noise parameters
(docs/guide/theory.rst, 'Interfaces')."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imunoise.cli.export_gate import add_force, pair_gates, refusal, with_warnings
from imunoise.cli.options import EXPORT_TOOLS, add_topic

EXAMPLES = """examples:
  imunoise export fit/imu_model.json --to kalibr                     # -> fit/imu.yaml
  imunoise export fit/imu_model.json --to openvins --inflate white=2,rw=10
  imunoise export fit/imu_model.json --to orbslam3 --into ORB_SLAM3/Examples/Monocular-Inertial/EuRoC.yaml
  imunoise export fit/imu_model.json --to openvins --into config/my_rig/kalibr_imu_chain.yaml
  imunoise export fit/imu_model.json --to kalibr --into kalibr/imu.yaml
  imunoise export fit/imu_model.json --to vins --into VINS-Fusion/config/euroc/euroc_stereo_imu_config.yaml
  imunoise export fit/imu_model.json --to lio-sam --into LIO-SAM/config/params.yaml
  imunoise export fit/imu_model.json --to fast-lio --into FAST_LIO/config/avia.yaml
  imunoise export fit/imu_model.json --to orbslam3 --out - | less
  imunoise export fit_gz/model.json --to kalibr --sensor gyro         # the gyro block alone (one-sensor fit)
  imunoise export fit_gz/model.json --to json                         # a single-axis fit (sensor from its unit)
  imunoise export fit/imu_model.json --horizon 60                     # match up to 60 s only
  imunoise export calib/imu_model.json --to openvins --noise static   # the stops' values of an in-use model

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
the root mean square). Every value has its unit and discrete per-sample equivalent in a comment.

VINS, LIO-SAM and FAST-LIO take other conventions, each from its source: VINS acc_n = N*sqrt(2f) and
acc_w = K*sqrt(f) (discrete standard deviations per sample), LIO-SAM imuAccNoise = N and imuAccBiasN = K
(continuous, as Kalibr), FAST-LIO acc_cov = N^2*f and b_acc_cov = K^2*f (discrete variances per sample);
the file says which beside every value.

--into FILE updates the IMU keys of an existing ORB-SLAM3 settings file, OpenVINS kalibr_imu_chain.yaml,
Kalibr imu.yaml, VINS config, LIO-SAM params.yaml (lio_sam block) or FAST-LIO config (mapping block) in place:
every other line stays byte for byte, a key found is rewritten on its line (a
duplicate left by an earlier `>> settings.yaml` is removed), a key absent is added after the file's IMU keys,
the original is kept as FILE.bak (FILE.bak.1, ... when taken), and the file is replaced atomically. A file of
another kind, or one that would still miss a key the tool requires, is refused (exit 2). ORB-SLAM3 settings
without File.version: "1.0" are read by its legacy reader, which needs IMU.Frequency as an integer: detected,
or forced with --legacy. OpenVINS: the intrinsics >= v2.7 requires (Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg,
model) are added as identity/zero when absent and never overwritten.
A model with one sensor (gyro-only or accel-only) has no values for the other sensor's keys, which Kalibr,
OpenVINS and ORB-SLAM3 all require: such an export is refused unless --sensor asks for that block alone,
--into merges it into a file that has the other keys, or --to json.

A model with an in-motion part (calibrate --in-motion) writes the IN-USE values by default: per axis the static
pair times the in-use/static factor estimated from whole GNSS-aided drives, combined as above; each key's comment
gives the factor with its 95 % CI and the static value. An axis whose in-use value the drives bound but do not
identify keeps its static value, and the comment gives the bound and its reason. --noise static writes the
static values; a model without the part writes its static values either way, exactly as before."""


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
    p.add_argument(
        "--to",
        choices=EXPORT_TOOLS,
        default="kalibr",
        dest="fmt",
        help="target tool: kalibr (imu.yaml), openvins (kalibr_imu_chain.yaml, OpenVINS v2.6 and >= v2.7), "
        "orbslam3 (IMU.* settings keys), vins (VINS-Mono/Fusion acc_n, gyr_n, acc_w, gyr_w: discrete), lio-sam "
        "(imuAccNoise, imuGyrNoise, imuAccBiasN, imuGyrBiasN: continuous), fast-lio (acc_cov, gyr_cov, b_acc_cov, "
        "b_gyr_cov: discrete variances), json (everything, per axis); default kalibr",
    )
    p.add_argument(
        "--sensor",
        choices=["gyro", "accel"],
        help="sensor: export only this one's block (a file the tool reads after merging, e.g. with --into); for a "
        "single-axis fit, which sensor it is when its unit/column do not say",
    )
    p.add_argument("--combine", choices=["max", "rms"], default="max", help="how to combine x/y/z (default max)")
    p.add_argument("--inflate", help="inflation factors applied visibly, e.g. white=2,rw=10")
    p.add_argument(
        "--horizon",
        type=float,
        metavar="S",
        help="longest averaging time [s] the pair is matched on (default: the longest scale of the fitted data)",
    )
    add_topic(p, "the sensor_msgs/Imu topic (written in the file; default: the model's bag topic, else the file's "
              "own with --into, else /imu0)")
    p.add_argument("--out", help="output file ('-' for stdout; default: the format's file name beside MODEL)")
    p.add_argument(
        "--into",
        metavar="FILE",
        help="update the IMU keys of this existing ORB-SLAM3 settings / OpenVINS chain / Kalibr imu.yaml / VINS "
        "config / LIO-SAM params.yaml / FAST-LIO config in place "
        "(other lines kept byte for byte, backup FILE.bak, atomic write); instead of --out",
    )
    p.add_argument(
        "--legacy",
        action="store_true",
        help="ORB-SLAM3: write IMU.Frequency as an integer, as legacy settings (no File.version, ORB-SLAM3 <= 0.4) "
        "need; --into detects such files by itself",
    )
    add_noise(p)
    add_force(p)
    p.set_defaults(func=run)


NOISE_CHOICES = ("in-use", "static")
"""The ``--noise`` choices of ``export`` and ``calibrate --export`` (those of :mod:`imunoise.export.in_use`;
tests/export checks they agree)."""


def add_noise(p: argparse.ArgumentParser) -> None:
    """``--noise in-use|static``: which pair the written files carry (``export``, ``calibrate --export``)."""
    p.add_argument("--noise", choices=NOISE_CHOICES, default="in-use",
                   help="in-use (default): the values while moving where the model has an in-motion part (calibrate "
                   "--in-motion; each key's comment gives the in-use/static factor with its 95 %% CI and the static "
                   "value); static: the stops' values. A model without the part writes its static values either way")


def load_for_export(path: str | Path):
    """The model of ``path`` as :func:`imunoise.noise.imu_model.load_model` reads it; an incomplete file becomes a
    one-line :class:`ModelError` instead of a traceback."""
    from imunoise.errors import ModelError
    from imunoise.noise.imu_model import ImuModel, load_model

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


def gate(model, sensor: str | None, force: bool, where: str) -> list[str]:
    """The fit-quality gate of ``calibrate``/``fit --export`` applied again when a saved model is exported: the
    exported pair of every axis is checked against its data (:func:`imunoise.cli.export_gate.pair_gates`),
    so a model that needed ``--force`` there needs it here too, and its warnings go into the file."""
    from imunoise.noise.imu_model import ImuModel

    if isinstance(model, ImuModel):
        axes = model.sensor_axes(sensor) if sensor else list(model.axes)
        fits = {ax: model.fit(ax) for ax in axes}
    else:
        fits = {str(model.extra.get("column") or "axis"): model}
    return refusal(pair_gates(fits), force, where=where)


def report(sensors, file=None) -> None:
    """Per axis: the pair, its τ range, worst AV ratio and which process went where; notes and warnings."""
    from imunoise.export import axis_lines
    from imunoise.export.in_use import in_use_comment

    file = file or sys.stderr
    for sn in sensors:
        for a in sn.axes:
            for line in axis_lines(a):
                print(line, file=file)
        for n in sn.notes:
            print(f"note: {n}", file=file)
        for w in sn.warnings:
            print(f"warning: {w}", file=file)
        n_txt, k_txt = in_use_comment(sn, "N"), in_use_comment(sn, "K")
        if n_txt:  # an in-use pair (imunoise.export.in_use); "" for a static one
            print(f"{sn.sensor}: in-use pair written: N = {sn.noise_density:.4g} ({n_txt[2:]}); "
                  f"K = {sn.random_walk:.4g} ({k_txt[2:]})", file=file)


def run(args: argparse.Namespace) -> int:
    from imunoise.errors import ModelError
    from imunoise.export import DEFAULT_FILENAMES, export_text, model_sensors, parse_inflate
    from imunoise.io.atomic import atomic_write_text
    from imunoise.noise.imu_model import ImuModel

    if args.horizon is not None and not args.horizon > 0:
        raise ModelError(f"--horizon must be a positive time in seconds, got {args.horizon}")
    if args.into is not None and args.out is not None:
        raise ModelError(f"--into {args.into} updates that file in place and --out {args.out} writes a new one: "
                         "give one of them")
    if args.into is not None and args.fmt == "json":
        raise ModelError("--into works with a tool's --to (orbslam3, openvins, kalibr, vins, lio-sam, fast-lio); json "
                         "has no settings file to update")
    if args.legacy and args.fmt != "orbslam3":
        raise ModelError(f"--legacy is for --to orbslam3 (legacy ORB-SLAM3 settings), not --to {args.fmt}")
    if args.topic and args.fmt in ("vins", "lio-sam", "fast-lio"):
        raise ModelError(f"--imu-topic is written for kalibr, openvins and json only; --to {args.fmt} writes the four "
                         "noise keys and leaves the tool's own IMU topic key as it is: drop --imu-topic")
    model = load_for_export(args.model)
    forced = gate(model, args.sensor, args.force, str(args.model))
    for w in forced:
        print(f"warning: exported with --force: {w}", file=sys.stderr)
    if args.into is not None:
        return _run_into(args, model)
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
        partial=args.sensor is not None,
        legacy=args.legacy,
        noise=args.noise,
    )
    sensors = model_sensors(model, args.sensor, args.combine, inflate, args.horizon, args.noise)
    if isinstance(model, ImuModel):
        for s in ("gyro", "accel"):
            if args.sensor in (None, s) and not model.sensor_axes(s):
                print(f"note: no {s} axes in {args.model}; its keys are commented out", file=sys.stderr)
    report(sensors.values())
    text = with_warnings(text, args.fmt, forced)
    if out is None:
        sys.stdout.write(text)
        return 0
    atomic_write_text(out, text)
    print(f"wrote {out}", file=sys.stderr)
    return 0


def _run_into(args: argparse.Namespace, model) -> int:
    """``--into``: the IMU keys of an existing tool file updated in place (imunoise.io.tool_settings)."""
    from imunoise.export import model_sensors, parse_inflate, update_into

    inflate = parse_inflate(args.inflate)
    res = update_into(model, args.fmt, args.into, sensor=args.sensor, topic=args.topic, combine=args.combine,
                      inflate=inflate, horizon_s=args.horizon, legacy=True if args.legacy else None,
                      noise=args.noise)
    report(model_sensors(model, args.sensor, args.combine, inflate, args.horizon, args.noise).values())
    for n in res.notes:
        print(f"note: {n}", file=sys.stderr)
    if res.duplicates_removed:
        print(f"note: removed duplicate keys {', '.join(res.duplicates_removed)} (OpenCV reads the first of "
              "duplicates, OpenCV 3.4 refuses them)", file=sys.stderr)
    what = [f"updated {', '.join(res.updated)}" if res.updated else "",
            f"added {', '.join(res.appended + res.blocks_added)}" if res.appended or res.blocks_added else ""]
    legacy = " (legacy ORB-SLAM3 settings: integer IMU.Frequency)" if res.legacy else ""
    print(f"wrote {res.path}: {'; '.join(w for w in what if w)}{legacy}; backup {res.backup}", file=sys.stderr)
    return 0
