"""`imunoise select`: autonomous model selection over every sub-model of the complete model
(docs/guide/theory.rst, 'Model selection')."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from imunoise.cli.options import (
    add_criterion,
    add_out,
    add_series_options,
    add_weights,
    load_series,
    out_dir,
    source_extra,
)
from imunoise.errors import ModelError
from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run

EXAMPLES = """examples:
  imunoise select gyro_x.csv --freq 100 --units deg/s --out sel_gx/
  imunoise select static.txt --freq 125 --column 2 --criterion wvic --top 5
  imunoise select imu.npy --freq 200 --column gyro_z --complete "3*AR1+WN+RW"

Fits all 79 non-empty sub-models of 4*AR1+DR+WN+QN+RW on one wavelet variance and one weighting matrix,
ranks them by GOF (paper Eq. 8) or WVIC (−2 log-likelihood of the WV + p·ln n, see imunoise.noise.selection) and
prints the ranking (model, #params, GOF, WVIC, fit time). Writes DIR/ranking.csv (every candidate, skipped
ones with the reason), DIR/model.json (the best model: per-sample and continuous parameters, units, rate)
and DIR/wv_top.png (empirical WV with CI and the top fits). Parameters are per sample at --freq."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "select",
        help="rank all sub-models of the complete model (4*AR1+DR+WN+QN+RW) by GOF or WVIC",
        description="Autonomous stochastic model selection with the GMWM (paper §2.2, Eq. 7-8).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_series_options(p)
    add_criterion(p, "ranking criterion")
    p.add_argument("--top", type=int, default=3, help="fits drawn in the plot and given CIs (default 3)")
    p.add_argument("--complete", default="4*AR1+DR+WN+QN+RW", help="complete model (default the paper's)")
    p.add_argument(
        "--penalty",
        choices=["bic", "optimism"],
        default="bic",
        help="WVIC form: WV likelihood + p ln n (bic, default) or GOF + Stebler's optimism trace",
    )
    add_weights(p)
    p.add_argument("--robust", action="store_true", help="robust (Huber) wavelet variance")
    p.add_argument("--limit", type=int, default=30, help="rows of the printed table (default 30; 0 = all)")
    add_out(p, "select")
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
    from imunoise.noise.plots import plot_wv_fits
    from imunoise.noise.selection import candidates, select_model

    if args.top < 1:
        raise ModelError(f"--top must be ≥ 1, got {args.top}")
    if args.limit < 0:
        raise ModelError(f"--limit must be ≥ 0 (0 = every row), got {args.limit}")
    series = load_series(args)
    final = out_dir(args, "select")
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
    best.extra.update(source_extra(args, series))
    print()
    print(best.summary())
    # the three files appear together when the run completes (Ctrl-C leaves --out as it was)
    with staged_run(final, ("ranking.csv", "model.json", "wv_top.png")) as out:
        with atomic_path(out / "ranking.csv") as tmp:
            ranking.to_csv(str(tmp))
        atomic_write_text(out / "model.json", json.dumps(best.to_dict(), indent=1))
        curves = [(f"#{i + 1} {f.model} (GOF {f.objective:.3g})", f.theoretical_wv)
                  for i, f in enumerate(ranking.top_fits)]
        with atomic_path(out / "wv_top.png") as tmp:
            plot_wv_fits(
                best.wv,
                curves,
                tmp,
                unit=series.unit,
                title=f"{Path(args.data).name} [{series.name}]: top {len(curves)} by {args.criterion.upper()}",
            )
    print(f"\nwrote {final / 'ranking.csv'}, {final / 'model.json'} and {final / 'wv_top.png'}", file=sys.stderr)
    return 0
