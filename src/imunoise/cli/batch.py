"""`imunoise batch`: model a fleet of static logs on Dask (one model per file and axis)."""

from __future__ import annotations

import argparse
import sys

from imunoise.cli.options import (
    add_columns,
    add_criterion,
    add_freq,
    add_model,
    add_out,
    add_scheduler,
    add_time_options,
    add_topic,
    add_units,
    add_weights,
    check_freq,
    check_scheduler,
    parse_units,
    prepare_out_dir,
)
from imunoise.errors import ModelError

EXAMPLES = """examples:
  imunoise batch "logs/*.csv" --freq 200 --model "WN+RW" --columns gyro_x=gx,gyro_y=gy,gyro_z=gz \\
      --units gyro=deg/s --out fleet/
  imunoise batch "bags/**/*.mcap" --auto --topic /imu0 --out fleet/            # rate from the stamps
  imunoise batch "logs/*.csv" --freq 100 --auto --scheduler tcp://10.0.0.5:8786 --out fleet/

Writes DIR/batch.csv (and DIR/batch.parquet when pyarrow is installed): one row per file and axis with
the model, continuous-time noise density N and bias random walk K_eq (+ units), GOF and fit time; a file
that cannot be read or fitted is one row with status "error" and the reason. One multi-axis model JSON
per file (DIR/<file>.model.json) is the input of `imunoise export` and `imunoise nav --model`.
The outputs appear in DIR together when the run completes (Ctrl-C, workers included, leaves DIR as it was);
the table and models an earlier batch left there are replaced, nothing else is touched."""


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
    add_freq(p)
    add_model(p, auto=True)
    add_criterion(p, "ranking for --auto")
    add_columns(p, one=False, several=True)
    add_units(p, several=True)
    add_time_options(p)
    add_topic(p)
    p.add_argument("--decimate", type=int, default=1, help="block-average K samples first (keeps the noise density)")
    add_weights(p)
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance")
    p.add_argument("--seed", type=int, default=0)
    add_scheduler(p, default="local", what="where the files are modelled")
    add_out(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.batch import expand_paths, run_batch, run_sequential
    from imunoise.io.tabular import parse_column_map

    check_freq(args.freq)
    check_scheduler(args)
    if args.decimate < 1:
        raise ModelError(f"--decimate must be a whole number ≥ 1, got {args.decimate}")
    paths = expand_paths(args.glob)
    prepare_out_dir(args.out)  # an unusable --out fails before the cluster starts
    cfg = {
        "freq": args.freq,
        "model": args.model,
        "auto": args.auto,
        "criterion": args.criterion,
        "columns": parse_column_map(args.columns),
        "units": parse_units(args.units),
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

