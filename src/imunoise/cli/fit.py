"""`imunoise fit`: GMWM model of one static IMU axis from a CSV/TXT/NPY file."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from imunoise.errors import ImunoiseError

EXAMPLES = """examples:
  imunoise fit gyro_x.csv --freq 100 --model "2*AR1+WN+RW" --units deg/s --out fit_gx/
  imunoise fit static.txt --freq 200 --column 3 --units g --model "AR1+WN+RW"
  imunoise fit imu.npy --freq 100 --column gyro_x --auto --criterion wvic

Writes DIR/model.json (model, per-sample and continuous parameters with units, rate, data span, WV)
and DIR/wv.png (empirical WV with CI band, fitted WV, one dashed curve per process), and prints the
summary table. Parameters are per sample at --freq (discrete, like R simts); continuous-time
equivalents (noise density, random walk, correlation times) are listed beside them."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="fit a GMWM error model to one static sensor axis",
        description="Fit a composite stochastic error model to static IMU data with the GMWM (paper Eq. 6).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("data", help="CSV/TXT (header optional, .gz ok) or .npy/.npz file")
    p.add_argument("--freq", type=float, required=True, help="sample rate in Hz")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--model", help='model structure, e.g. "2*AR1+WN+RW" (processes: AR1 WN QN RW DR)')
    g.add_argument(
        "--auto",
        action="store_true",
        help="select the model automatically among all 79 sub-models of 4*AR1+DR+WN+QN+RW",
    )
    p.add_argument(
        "--criterion", choices=["gof", "wvic"], default="wvic", help="ranking for --auto (default wvic)"
    )
    p.add_argument("--column", help="column name or 0-based index (needed when the file has several)")
    p.add_argument(
        "--units",
        help="unit of the data column: rad/s, deg/s, deg/h, m/s2, g, mg (converted to SI); default: as is",
    )
    p.add_argument(
        "--weights",
        choices=["efficient", "diagonal", "fast", "identity"],
        default="efficient",
        help="GMWM weighting matrix Ω (default efficient = inverse WV covariance)",
    )
    p.add_argument(
        "--robust", action="store_true", help="robust (Huber) wavelet variance for contaminated data"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the random starting points")
    p.add_argument("--out", help="output folder (default: <data name>_fit)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.gmwm import gmwm
    from imunoise.io.tabular import read_series
    from imunoise.model import Model
    from imunoise.plots import plot_wv_fit

    if not args.freq > 0:
        raise ImunoiseError(f"--freq must be a positive rate in Hz, got {args.freq}")
    model = Model.parse(args.model) if args.model else None
    series = read_series(args.data, column=args.column, units=args.units)
    out = Path(args.out or f"{Path(args.data).name.split('.')[0]}_fit")
    out.mkdir(parents=True, exist_ok=True)
    extra: dict = {"source": str(args.data), "column": series.name, "source_unit": series.source_unit}
    if args.auto:
        try:
            from imunoise.selection import select_model
        except ImportError as exc:  # pragma: no cover - only before the selection module exists
            raise ImunoiseError("--auto needs imunoise.selection, which is not installed") from exc
        ranking = select_model(
            series.values, freq=args.freq, criterion=args.criterion, robust=args.robust, weights=args.weights
        )
        fit = ranking.best
        fit.unit = series.unit
        print(ranking.table(limit=10))
        print()
        extra["selection"] = {"criterion": args.criterion, "n_candidates": len(ranking.fits)}
    else:
        fit = gmwm(
            model,
            series.values,
            freq=args.freq,
            weights=args.weights,
            robust=args.robust,
            unit=series.unit,
            seed=args.seed,
        )
    fit.extra.update(extra)
    print(fit.summary())
    (out / "model.json").write_text(json.dumps(fit.to_dict(), indent=1))
    plot_wv_fit(fit, out / "wv.png", title=f"{Path(args.data).name} [{series.name}]: {fit.model}")
    print(f"\nwrote {out / 'model.json'} and {out / 'wv.png'}", file=sys.stderr)
    return 0
