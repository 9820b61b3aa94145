"""`imunoise em`: constrained-EM baseline (Stebler et al. 2011) for a state-space error model (SPEC §6)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from imunoise.errors import ImunoiseError

EXAMPLES = """examples:
  imunoise em gyro_x.csv --freq 100 --units deg/s --model "AR1+WN+RW" --out em_gx/
  imunoise em static.npy --freq 125 --column gyro_z --model "2*AR1+WN" --init fit_gz/model.json

Kalman/RTS-smoother E-step and closed-form M-steps on the state-space form (AR1s, RW, WN, optional DR;
QN has no state form here). Starts from the Allan-variance model by default (as the paper does) or from
a model JSON (--init). Prints the parameters, iterations, log-likelihood and time; writes DIR/model.json
and DIR/wv.png. EM is slow on long series (about 0.1 s per iteration per 10^6 samples and state)."""


def register(sub: argparse._SubParsersAction) -> None:
    from imunoise.cli.select import add_data_options

    p = sub.add_parser(
        "em",
        help="EM baseline: maximum likelihood of a state-space error model (Kalman smoother E-step)",
        description="Constrained EM estimate of a state-space stochastic error model (EM baseline).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_data_options(p)
    p.add_argument("--model", required=True, help='structure, e.g. "AR1+WN+RW" (AR1, WN, RW, DR)')
    p.add_argument("--init", default="av", help="'av' (default) or a model/fit JSON file to start from")
    p.add_argument("--max-iter", type=int, default=500, help="maximum EM iterations (default 500)")
    p.add_argument("--tol", type=float, default=1e-8, help="relative log-likelihood change to stop (1e-8)")
    p.add_argument("--out", help="output folder (default: <data name>_em)")
    p.set_defaults(func=run)


def load_init(spec: str):
    if spec == "av":
        return "av"
    from imunoise.gmwm import GMWMFit
    from imunoise.model import Model

    path = Path(spec)
    if not path.exists():
        raise ImunoiseError(f"--init {spec!r}: not 'av' and no such file")
    d = json.loads(path.read_text())
    return GMWMFit.from_dict(d) if d.get("kind") == "imunoise.fit" else Model.from_dict(d)


def run(args: argparse.Namespace) -> int:
    from imunoise.cli.select import load_series, out_dir
    from imunoise.em import em_fit
    from imunoise.plots import plot_wv_fit

    series = load_series(args)
    out = out_dir(args, "em")
    fit = em_fit(
        series.values,
        freq=args.freq,
        model=args.model,
        init=load_init(args.init),
        max_iter=args.max_iter,
        tol=args.tol,
        unit=series.unit,
    )
    fit.extra.update({"source": str(args.data), "column": series.name, "source_unit": series.source_unit})
    print(fit.summary())
    ex = fit.extra
    flags = " (diverged: best iterate kept)" if ex["diverged"] else ""
    print(
        f"\n  EM: {ex['iterations']} iterations, converged = {ex['converged']}{flags}, "
        f"log-likelihood = {ex['loglik']:.10g}, time = {ex['time_s']:.2f} s"
    )
    (out / "model.json").write_text(json.dumps(fit.to_dict(), indent=1))
    plot_wv_fit(fit, out / "wv.png", title=f"{Path(args.data).name} [{series.name}]: EM {fit.model}")
    print(f"\nwrote {out / 'model.json'} and {out / 'wv.png'}", file=sys.stderr)
    return 0
