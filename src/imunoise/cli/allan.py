"""`imunoise allan`: Allan-variance baseline with an automated IEEE 952/1293 reading
(docs/guide/theory.rst, 'Baselines')."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from imunoise.cli.options import add_out, add_series_options, load_series, out_dir, source_extra

EXAMPLES = """examples:
  imunoise allan gyro_x.csv --freq 100 --units deg/s --out av_gx/
  imunoise allan static.npy --freq 125 --column gyro_z --grid octave

Computes the overlapping Allan deviation (dense log grid from cumulative sums, or the octave grid via
AVAR = 2·WV), reads N (−½ line at τ = 1 s), K (+½ line at τ = 3 s), B = min AD/0.6643 with T_BI, and Q / R
when their slopes exist, and prints them in continuous units with the τ region each line was fitted on.
The equivalent filter model (WN + RW + one Gauss–Markov for B, per sample at --freq) goes to
DIR/model.json; DIR/allan.png shows the AD, the fitted lines and their regions; DIR/allan.csv the points."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "allan",
        help="Allan-variance baseline: automated IEEE reading (N, K, B, Q, R) and equivalent model",
        description="Overlapping Allan variance and its automated IEEE 952/1293 reading (AV baseline).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_series_options(p)
    p.add_argument("--grid", choices=["dense", "octave"], default="dense", help="AV grid (default dense)")
    add_out(p, "allan")
    p.set_defaults(func=run)


def reading_table(fit, unit: str) -> str:
    a = fit.extra["allan"]
    units = fit.extra["allan_units"]
    names = {
        "N": "angle/velocity random walk N (−½ line at 1 s)",
        "K": "rate random walk K (+½ line at 3 s)",
        "B": "bias instability B (min AD / 0.6643)",
        "T_BI": "T_BI (τ at the AD minimum)",
        "Q": "quantisation Q (−1 line)",
        "R": "rate ramp R (+1 line)",
    }
    lines = [f"  {'term':<48}{'value':>14}  unit        fitted on τ [s]"]
    for key, label in names.items():
        v = a[key]
        region = a["regions_s"].get(key if key != "T_BI" else "B")
        reg = f"{region[0]:.3g} – {region[1]:.3g}" if region and key != "T_BI" else ""
        val = f"{v:>14.6g}" if v is not None and math.isfinite(v) else f"{'absent':>14}"
        lines.append(f"  {label:<48}{val}  {units[key]:<10}  {reg}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run
    from imunoise.noise.allan import allan_fit, curve_from_fit, plot_allan, read_allan

    series = load_series(args)
    final = out_dir(args, "allan")
    fit = allan_fit(series.values, freq=args.freq, unit=series.unit, grid=args.grid)
    fit.extra.update(source_extra(args, series))
    print(f"Allan-variance reading of {Path(args.data).name} [{series.name}] at {args.freq:g} Hz")
    print(reading_table(fit, series.unit))
    print()
    print(fit.summary())
    av = curve_from_fit(fit)
    # all three files appear together when the run completes (Ctrl-C leaves --out as it was)
    with staged_run(final, OUTPUTS) as out:
        with atomic_path(out / "allan.png") as tmp:
            plot_allan(
                av,
                tmp,
                reading=read_allan(av),
                models=[(f"AV model: {fit.model}", fit.model)],
                unit=series.unit,
                title=f"{Path(args.data).name} [{series.name}]: Allan deviation",
            )
        rows = [f"tau_s,avar_{series.unit}2,adev_{series.unit},dof\n"]
        rows += [f"{t:.10g},{v:.10g},{math.sqrt(v):.10g},{d:.6g}\n" for t, v, d in zip(av.tau, av.avar, av.dof)]
        atomic_write_text(out / "allan.csv", "".join(rows))
        atomic_write_text(out / "model.json", json.dumps(fit.to_dict(), indent=1))
    print(f"\nwrote {final / 'model.json'}, {final / 'allan.png'} and {final / 'allan.csv'}", file=sys.stderr)
    return 0


OUTPUTS = ("model.json", "allan.png", "allan.csv")
"""Every file `imunoise allan` writes into --out (a rerun removes the ones it did not write again)."""
