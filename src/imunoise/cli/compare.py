"""`imunoise compare`: GMWM (selected) vs Allan-variance vs EM models of one static axis (paper §3)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from imunoise.cli.options import add_criterion, add_out, add_series_options, load_series, out_dir, source_extra

EXAMPLES = """examples:
  imunoise compare gyro_x.csv --freq 100 --units deg/s --out cmp_gx/
  imunoise compare static.npy --freq 125 --column gyro_z --criterion wvic --em-model "2*AR1+WN+RW"

Runs the three modellers on the same data: GMWM with autonomous selection (imunoise select), the
automated Allan-variance reading (imunoise allan) and constrained EM started from the AV model
(imunoise em; structure = the AV model's unless --em-model). Prints one parameter table (continuous
units) and the GOF (paper Eq. 8) of each model on the SAME wavelet variance and weighting matrix.
Writes DIR/compare_wv.png (empirical WV with CI and the three implied WVs, like paper Figs. 5/9),
DIR/compare_allan.png (Allan deviation, IEEE lines and the three models' AD), DIR/compare.json and
DIR/compare.md (the tables, like paper Tables 2–4)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare",
        help="GMWM (selected) vs Allan variance vs EM on the same static data",
        description="Compare the GMWM, AV and EM modellers side by side (paper Tables 2-4, Figs. 5/9).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_series_options(p)
    add_criterion(p, "GMWM ranking")
    p.add_argument("--em-model", help="EM structure (default: the AV model's structure)")
    p.add_argument("--em-max-iter", type=int, default=300, help="EM iteration cap (default 300)")
    add_out(p, "compare")
    p.set_defaults(func=run)


def compare_fits(
    values: Any, freq: float, unit: str, criterion: str = "wvic", em_model: str | None = None, em_max_iter: int = 300
) -> dict[str, Any]:
    """Run the three modellers; return {"gmwm": fit, "av": fit, "em": fit or None, "em_error": str}."""
    from imunoise.errors import ImunoiseError
    from imunoise.noise.allan import allan_fit
    from imunoise.noise.em import em_fit
    from imunoise.noise.model import Model
    from imunoise.noise.selection import select_model

    ranking = select_model(values, freq=freq, criterion=criterion, unit=unit)
    ranking.best.extra["selection_s"] = ranking.elapsed_s
    av = allan_fit(values, freq=freq, unit=unit)
    out: dict[str, Any] = {"gmwm": ranking.best, "av": av, "em": None, "em_error": "", "ranking": ranking}
    structure = Model.parse(em_model) if em_model else av.model.unknown()
    try:
        out["em"] = em_fit(structure, values, freq=freq, init=av, unit=unit, max_iter=em_max_iter)
    except ImunoiseError as exc:
        out["em_error"] = str(exc)
    return out


def parameter_table(fits: dict[str, Any], unit: str) -> list[str]:
    """Markdown table: each method's model, GOF on the shared WV/Ω, time, and continuous parameters."""
    names = [k for k in ("gmwm", "av", "em") if fits.get(k) is not None]
    rows = [
        "| quantity | " + " | ".join(n.upper() for n in names) + " |",
        "|---|" + "---|" * len(names),
        "| model | " + " | ".join(str(fits[n].model) for n in names) + " |",
        "| GOF (Eq. 8, same WV and Ω) | " + " | ".join(f"{fits[n].objective:.4g}" for n in names) + " |",
        "| time [s] (GMWM: all candidates) | "
        + " | ".join(f"{fits[n].extra.get('selection_s', fits[n].elapsed_s):.3g}" for n in names)
        + " |",
    ]
    keys: list[str] = []
    for n in names:
        for k in fits[n].continuous():
            if k not in keys:
                keys.append(k)
    for k in keys:
        cells = []
        for n in names:
            c = fits[n].continuous()
            cells.append(f"{c[k]:.4g}" if k in c and math.isfinite(c[k]) else "–")
        u = fits[names[0]].continuous_units().get(k) or next(
            (fits[n].continuous_units()[k] for n in names if k in fits[n].continuous_units()), ""
        )
        rows.append(f"| {k} [{u}] | " + " | ".join(cells) + " |")

    def row(label: str, cell: dict[str, str]) -> str:
        return f"| {label} | " + " | ".join(cell.get(n, "–") for n in names) + " |"

    if "av" in names:
        a = fits["av"].extra["allan"]
        rows.append(
            row(
                f"AV reading N [{unit}/√Hz], K [{unit}/s/√Hz], B [{unit}], T_BI [s]",
                {"av": f"{a['N']:.4g}, {a['K']:.4g}, {a['B']:.4g}, {a['T_BI']:.4g}"},
            )
        )
    if "em" in names:
        e = fits["em"].extra
        state = "converged" if e["converged"] else "not converged"
        rows.append(row("EM iterations, log-likelihood", {"em": f"{e['iterations']} ({state}), {e['loglik']:.8g}"}))
    return rows


def run(args: argparse.Namespace) -> int:
    from imunoise.io.atomic import atomic_path, atomic_write_text, staged_run
    from imunoise.noise.allan import curve_from_fit, plot_allan, read_allan
    from imunoise.noise.plots import METHOD_COLORS, plot_wv_fits

    series = load_series(args)
    final = out_dir(args, "compare")
    fits = compare_fits(series.values, args.freq, series.unit, args.criterion, args.em_model, args.em_max_iter)
    title = f"{Path(args.data).name} [{series.name}]"
    rows = parameter_table(fits, series.unit)
    print(f"GMWM vs AV vs EM on {title} at {args.freq:g} Hz (unit {series.unit})\n")
    print("\n".join(rows))
    if fits["em_error"]:
        print(f"\nEM not run: {fits['em_error']}")
    labels = [(k, fits[k]) for k in ("gmwm", "av", "em") if fits.get(k) is not None]
    wv = fits["gmwm"].wv
    # the four files appear together when the run completes (Ctrl-C leaves --out as it was)
    with staged_run(final, ("compare_wv.png", "compare_allan.png", "compare.md", "compare.json")) as out:
        with atomic_path(out / "compare_wv.png") as tmp:
            plot_wv_fits(
                wv,
                [(f"{k.upper()}: {f.model} (GOF {f.objective:.3g})", f.theoretical_wv) for k, f in labels],
                tmp,
                unit=series.unit,
                title=f"{title}: GMWM vs AV vs EM",
                colors=[METHOD_COLORS[k] for k, _ in labels],
            )
        av = curve_from_fit(fits["av"])
        with atomic_path(out / "compare_allan.png") as tmp:
            plot_allan(
                av,
                tmp,
                reading=read_allan(av),
                models=[(f"{k.upper()}: {f.model}", f.model) for k, f in labels],
                unit=series.unit,
                title=f"{title}: Allan deviation",
                colors=[METHOD_COLORS[k] for k, _ in labels],
            )
        atomic_write_text(out / "compare.md", "\n".join(rows) + "\n")
        for _, f in labels:
            f.extra.update(source_extra(args, series))
        atomic_write_text(
            out / "compare.json",
            json.dumps({k: f.to_dict() for k, f in labels} | {"em_error": fits["em_error"]}, indent=1, default=str),
        )
    print(f"\nwrote {final / 'compare_wv.png'}, {final / 'compare_allan.png'}, compare.md/json", file=sys.stderr)
    return 0
