"""`imunoise batch`: model a fleet of static logs on Dask (one model per file and axis)."""

from __future__ import annotations

import argparse
import sys

from imunoise.errors import ImunoiseError

EXAMPLES = """examples:
  imunoise batch "logs/*.csv" --freq 200 --model "WN+RW" --columns gyro_x=gx,gyro_y=gy,gyro_z=gz \\
      --units gyro=deg/s --out fleet/
  imunoise batch "bags/**/*.mcap" --auto --topic /imu0 --out fleet/            # rate from the stamps
  imunoise batch "logs/*.csv" --freq 100 --auto --scheduler tcp://10.0.0.5:8786 --out fleet/

Writes DIR/batch.csv (and DIR/batch.parquet when pyarrow is installed): one row per file and axis with
the model, continuous-time noise density N and bias random walk K_eq (+ units), GOF and fit time; a file
that cannot be read or fitted is one row with status "error" and the reason. One multi-axis model JSON
per file (DIR/<file>.model.json) is the input of `imunoise export` and `imunoise nav --model`."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "batch",
        help="fit many static logs in parallel on Dask and tabulate the models",
        description="Model every file matching GLOB (CSV/TXT/NPY or ROS bags), one GMWM model per axis, "
        "on a Dask cluster (local worker processes by default).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("glob", nargs="+", help="file pattern(s), quoted so the shell does not expand them")
    p.add_argument("--freq", type=float, help="sample rate in Hz (default: from the time stamps)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--model", help='model structure for every axis, e.g. "WN+RW" or "2*AR1+WN+RW"')
    g.add_argument("--auto", action="store_true", help="automatic model selection per axis")
    p.add_argument("--criterion", choices=["gof", "wvic"], default="wvic", help="ranking for --auto")
    p.add_argument("--columns", help="columns to fit: a,b,c or axis=column pairs (default: all but time)")
    p.add_argument("--units", help="unit for all columns, or per group/column: gyro=deg/s,accel=g")
    p.add_argument("--time-column", help="time column name or index")
    p.add_argument("--time-unit", default="s", choices=["s", "ms", "us", "µs", "ns"], help="unit of the time column")
    p.add_argument("--topic", help="IMU topic for ROS bags")
    p.add_argument("--decimate", type=int, default=1, help="block-average K samples first (keeps the noise density)")
    p.add_argument("--weights", choices=["efficient", "diagonal", "fast", "identity"], default="efficient")
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--scheduler",
        default="local",
        help="'local' (LocalCluster of processes, default), 'sequential' (plain loop) or a scheduler address",
    )
    p.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.batch import expand_paths, run_batch, run_sequential
    from imunoise.io.tabular import parse_column_map

    if args.freq is not None and not args.freq > 0:
        raise ImunoiseError(f"--freq must be a positive rate in Hz, got {args.freq}")
    paths = expand_paths(args.glob)
    cfg = {
        "freq": args.freq,
        "model": args.model,
        "auto": args.auto,
        "criterion": args.criterion,
        "columns": parse_column_map(args.columns),
        "units": _units(args.units),
        "time_column": args.time_column,
        "time_unit": args.time_unit,
        "topic": args.topic,
        "decimate": args.decimate,
        "weights": args.weights,
        "robust": args.robust,
        "seed": args.seed,
    }
    progress = sys.stderr.isatty()
    print(f"{len(paths)} files; scheduler {args.scheduler}", file=sys.stderr)
    if args.scheduler == "sequential":
        res = run_sequential(paths, cfg, args.out, progress=progress)
    else:
        res = run_batch(paths, cfg, args.out, scheduler=args.scheduler, n_workers=args.workers, progress=progress)
    ok = res.n_files - len(res.failed)
    print(f"modelled {ok}/{res.n_files} files in {res.wall_s:.1f} s ({res.scheduler})")
    for r in res.rows:
        if r["status"] != "ok":
            print(f"  FAILED {r['file']}: {r['error']}")
    print(f"wrote {', '.join(str(p) for p in res.tables)} and one <file>.model.json per file", file=sys.stderr)
    return 0 if not res.failed else 1


def _units(text: str | None):
    if text is None or "=" not in text:
        return text
    return {k.strip(): v.strip() for k, v in (item.split("=", 1) for item in text.split(",") if item.strip())}
