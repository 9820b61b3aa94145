"""`imunoise em`: constrained-EM baseline (Stebler et al. 2011) for a state-space error model
(docs/guide/theory.rst, 'Baselines')."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from imunoise.cli.options import add_model, add_out, add_series_options, load_series, out_dir, source_extra
from imunoise.errors import DataError

EXAMPLES = """examples:
  imunoise em gyro_x.csv --freq 100 --units deg/s --model "AR1+WN+RW" --out em_gx/
  imunoise em static.npy --freq 125 --column gyro_z --model "2*AR1+WN" --init fit_gz/model.json

Kalman/RTS-smoother E-step and closed-form M-steps on the state-space form (AR1s, RW, WN, optional DR;
QN has no state form here). Starts from the Allan-variance model by default (as the paper does) or from
a model JSON (--init). Prints the parameters, iterations, log-likelihood and time; writes DIR/model.json
and DIR/wv.png. EM is slow on long series (about 0.1 s per iteration per 10^6 samples and state)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "em",
        help="EM baseline: maximum likelihood of a state-space error model (Kalman smoother E-step)",
        description="Constrained EM estimate of a state-space stochastic error model (EM baseline).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_series_options(p)
    add_model(p, processes="AR1 WN RW DR")
    p.add_argument("--init", default="av", help="'av' (default) or a model/fit JSON file to start from")
    p.add_argument("--max-iter", type=int, default=500, help="maximum EM iterations (default 500)")
    p.add_argument("--tol", type=float, default=1e-8, help="relative log-likelihood change to stop (1e-8)")
    add_out(p, "em")
    p.set_defaults(func=run)


def load_init(spec: str):
    if spec == "av":
        return "av"
    from imunoise.errors import ModelError
    from imunoise.noise.imu_model import ImuModel, parse_model, read_model_json

    path = Path(spec)
    if not path.exists():
        raise DataError(f"--init {spec!r} is neither 'av' nor an existing file; give 'av' or the model.json of a fit")
    d = read_model_json(path, "--init")  # binary or malformed file -> one error naming it
    init = parse_model(d, f"--init {path}")  # a one-axis fit or a bare model dict
    if isinstance(init, ImuModel):
        raise ModelError(f"--init {path} is a multi-axis IMU model; give the model.json of one axis' fit")
    return init


def run(args: argparse.Namespace) -> int:
    import math

    from imunoise.errors import ModelError
    from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run
    from imunoise.noise.em import em_fit
    from imunoise.noise.plots import plot_wv_fit

    if args.max_iter < 1:
        raise ModelError(f"--max-iter must be ≥ 1 iteration, got {args.max_iter}")
    if not (math.isfinite(args.tol) and args.tol > 0):
        raise ModelError(f"--tol must be a finite relative change > 0 (default 1e-8), got {args.tol}")
    init = load_init(args.init)  # before the data: a bad --init fails fast
    series = load_series(args)
    final = out_dir(args, "em")
    fit = em_fit(
        args.model,
        series.values,
        freq=args.freq,
        init=init,
        max_iter=args.max_iter,
        tol=args.tol,
        unit=series.unit,
    )
    fit.extra.update(source_extra(args, series))
    print(fit.summary())
    ex = fit.extra
    flags = " (diverged: best iterate kept)" if ex["diverged"] else ""
    print(
        f"\n  EM: {ex['iterations']} iterations, converged = {ex['converged']}{flags}, "
        f"log-likelihood = {ex['loglik']:.10g}, time = {ex['time_s']:.2f} s"
    )
    with staged_run(final, ("model.json", "wv.png")) as out:  # published together when complete
        atomic_write_text(out / "model.json", json.dumps(fit.to_dict(), indent=1))
        with atomic_path(out / "wv.png") as tmp:
            plot_wv_fit(fit, tmp, title=f"{Path(args.data).name} [{series.name}]: EM {fit.model}")
    print(f"\nwrote {final / 'model.json'} and {final / 'wv.png'}", file=sys.stderr)
    return 0
