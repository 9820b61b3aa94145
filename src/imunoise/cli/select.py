"""`imunoise select`: autonomous model selection over every sub-model of the complete model (SPEC §5)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from imunoise.errors import ImunoiseError

EXAMPLES = """examples:
  imunoise select gyro_x.csv --freq 100 --units deg/s --out sel_gx/
  imunoise select static.txt --freq 125 --column 2 --criterion wvic --top 5
  imunoise select imu.npy --freq 200 --column gyro_z --complete "3*AR1+WN+RW"

Fits all 79 non-empty sub-models of 4*AR1+DR+WN+QN+RW on one wavelet variance and one weighting matrix,
ranks them by GOF (paper Eq. 8) or WVIC (−2 log-likelihood of the WV + p·ln n, see imunoise.selection) and
prints the ranking (model, #params, GOF, WVIC, fit time). Writes DIR/ranking.csv (every candidate, skipped
ones with the reason), DIR/model.json (the best model: per-sample and continuous parameters, units, rate)
and DIR/wv_top.png (empirical WV with CI and the top fits). Parameters are per sample at --freq."""


def add_data_options(p: argparse.ArgumentParser) -> None:
    """Options shared by select, allan, em and compare: one static axis from a table or a ROS bag."""
    p.add_argument("data", help="CSV/TXT (header optional, .gz ok), .npy/.npz, or a ROS bag (.bag/.db3/.mcap)")
    p.add_argument("--freq", type=float, help="sample rate in Hz (needed unless the data have time stamps)")
    p.add_argument("--column", help="column name or 0-based index; for a bag gyro_x..accel_z")
    p.add_argument(
        "--units",
        help="unit of the data column: rad/s, deg/s, deg/h, m/s2, g, mg (converted to SI); default: as is",
    )
    p.add_argument("--topic", help="ROS bag: the sensor_msgs/Imu topic (listed when missing or wrong)")
    p.add_argument("--time-column", help="table: time column (name or index); the rate is inferred from it")
    p.add_argument("--time-unit", default="s", choices=["s", "ms", "us", "ns"], help="unit of --time-column")


def load_series(args: argparse.Namespace) -> Any:
    """Read the one axis the options name, in SI; sets ``args.freq`` from the stamps when not given."""
    from imunoise.io.imu_input import read_imu_source
    from imunoise.io.rosbag import is_bag
    from imunoise.io.tabular import Series

    if args.freq is not None and not args.freq > 0:
        raise ImunoiseError(f"--freq must be a positive rate in Hz, got {args.freq}")
    bag = is_bag(args.data)
    if bag and args.column is None:
        raise ImunoiseError("a bag holds six axes: choose one with --column gyro_x|gyro_y|gyro_z|accel_x|...")
    if not bag and args.freq is None and args.time_column is None:
        raise ImunoiseError("give the sample rate with --freq HZ (or a time column with --time-column)")
    series = read_imu_source(
        args.data,
        topic=args.topic,
        columns=[args.column] if args.column is not None else None,
        units=args.units,
        time_column=args.time_column,
        time_unit=args.time_unit,
        freq=args.freq,
    )
    if len(series.data) != 1:
        raise ImunoiseError(
            f"{args.data} has {len(series.data)} data columns ({', '.join(series.data)}); choose one with --column"
        )
    (axis,) = series.data
    args.freq = series.freq
    return Series(series.data[axis], series.unit[axis], axis, series.source_unit[axis])


def out_dir(args: argparse.Namespace, suffix: str) -> Path:
    out = Path(args.out or f"{Path(args.data).name.split('.')[0]}_{suffix}")
    out.mkdir(parents=True, exist_ok=True)
    return out


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "select",
        help="rank all sub-models of the complete model (4*AR1+DR+WN+QN+RW) by GOF or WVIC",
        description="Autonomous stochastic model selection with the GMWM (paper §2.2, Eq. 7-8).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_data_options(p)
    p.add_argument(
        "--criterion",
        choices=["gof", "wvic"],
        default="wvic",
        help="ranking criterion (default wvic; gof = paper Eq. 8, which always favours the largest nested model)",
    )
    p.add_argument("--top", type=int, default=3, help="fits drawn in the plot and given CIs (default 3)")
    p.add_argument("--complete", default="4*AR1+DR+WN+QN+RW", help="complete model (default the paper's)")
    p.add_argument(
        "--penalty",
        choices=["bic", "optimism"],
        default="bic",
        help="WVIC form: WV likelihood + p ln n (bic, default) or GOF + Stebler's optimism trace",
    )
    p.add_argument(
        "--weights",
        choices=["efficient", "diagonal", "fast", "identity"],
        default="efficient",
        help="GMWM weighting matrix Ω (default efficient)",
    )
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance")
    p.add_argument("--limit", type=int, default=30, help="rows of the printed table (default 30; 0 = all)")
    p.add_argument("--out", help="output folder (default: <data name>_select)")
    p.set_defaults(func=run)


def progress_bar(total: int, desc: str) -> Any:
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="model", disable=not sys.stderr.isatty(), leave=False)

    def update(done: int, _total: int, label: str) -> None:
        bar.set_postfix_str(label, refresh=False)
        bar.update(done - bar.n)
        if done >= _total:
            bar.close()

    return update


def run(args: argparse.Namespace) -> int:
    from imunoise.plots import plot_wv_fits
    from imunoise.selection import candidates, select_model

    if args.top < 1:
        raise ImunoiseError(f"--top must be ≥ 1, got {args.top}")
    series = load_series(args)
    out = out_dir(args, "select")
    n_cand = len(candidates(args.complete))
    ranking = select_model(
        series.values,
        freq=args.freq,
        complete=args.complete,
        criterion=args.criterion,
        top=args.top,
        weights=args.weights,
        robust=args.robust,
        unit=series.unit,
        penalty=args.penalty,
        progress=progress_bar(n_cand, "select"),
    )
    print(ranking.table(limit=args.limit or None))
    best = ranking.best
    best.extra.update({"source": str(args.data), "column": series.name, "source_unit": series.source_unit})
    print()
    print(best.summary())
    ranking.to_csv(str(out / "ranking.csv"))
    (out / "model.json").write_text(json.dumps(best.to_dict(), indent=1))
    curves = [(f"#{i + 1} {f.model} (GOF {f.objective:.3g})", f.theoretical_wv) for i, f in enumerate(ranking.top_fits)]
    plot_wv_fits(
        best.wv,
        curves,
        out / "wv_top.png",
        unit=series.unit,
        title=f"{Path(args.data).name} [{series.name}]: top {len(curves)} by {args.criterion.upper()}",
    )
    print(f"\nwrote {out / 'ranking.csv'}, {out / 'model.json'} and {out / 'wv_top.png'}", file=sys.stderr)
    return 0
