"""`imunoise demo`: the main job end to end on data the project ships or simulates, with a report."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from imunoise.cli.options import positive_float, positive_int

EXAMPLES = """examples:
  imunoise demo                       # online GMWM on the shipped real drive: out/demo/report.html
  imunoise demo --data sim/ --out out/demo_sim  # any dataset folder, e.g. one of imunoise simulate --out sim/
  imunoise demo --static --out /tmp/d # GMWM on a simulated 1 h static MEMS recording (known truth)

The default demo is the online experiment (paper §3.2) on data/drive_0708 (a real 9 min car drive with a
consumer MEMS IMU and RTK GNSS, BSD-3, shipped in the repository): static detection, online GMWM
identification and refits, model hot-swap into the EKF. Its headline is the powered comparison: plain,
static variance as white noise, AV, EM and online GMWM on 60 s outage windows opened every 20 s, with RTK
and with meter-level GNSS (noise:1.5,3,1, three noise seeds): the paired end-drift ratio of each method
against plain and against static_var with its 95 % CI. The paper-style view follows: plain, AV, EM, online
GMWM and online GMWM + ZUPT through the drive's five official 60 s outages. About two minutes on two cores.
"""

#: the demo's powered comparison (imunoise.experiments.dense on the shipped drive)
DEMO_EVIDENCE = {"methods": ("plain", "static_var", "av", "em", "gmwm"), "gnss": ("rtk", "noise:1.5,3,1"),
                 "noise_seeds": (1, 2, 3), "outages": "dense:60:20"}


def demo_truth():
    """Consumer MEMS error models per sample at 100 Hz (SI): ARW ≈ 0.3 °/√h, 100 µg/√Hz class."""
    from imunoise import AR1, RW, WN

    gyro = (
        AR1(phi=0.9999, sigma2=4.6e-13) + AR1(phi=0.995, sigma2=4.0e-10) + WN(sigma2=7.6e-7) + RW(gamma2=1e-13)
    )
    accel = AR1(phi=0.9998, sigma2=9.6e-11) + AR1(phi=0.99, sigma2=2.0e-8) + WN(sigma2=9.6e-5) + RW(gamma2=1e-12)
    return {"gyro": gyro, "accel": accel}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job on bundled/simulated data and write a report",
        description="Run imunoise end to end on data it ships or simulates and write report.html.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--static", action="store_true", help="a static recording instead of a drive (the GMWM demo)")
    p.add_argument("--data", help="dataset folder with a dataset.json manifest (docs/guide/theory.rst, 'Interfaces'; "
                                  "for the online demo, "
                   "default: the repository's data/drive_0708)")
    p.add_argument("--workers", type=positive_int, default=2,
                   help="online demo: local worker processes (parallel; default 2)")
    p.add_argument("--duration", type=positive_float, default=3600.0,
                   help="static demo: length of the simulated recording [s] (default 3600)")
    p.add_argument("--seed", type=int, default=7, help="demo data: random seed (of the simulated data; default 7)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.cli.options import prepare_out_dir
    from imunoise.io.atomic import staged_run

    final = prepare_out_dir(args.out)  # an unusable --out fails before the work
    # the report and its files appear at once when the demo completes (Ctrl-C leaves --out as it was)
    with staged_run(final, ()) as out:
        if args.static:
            return run_static_demo(out, duration_s=args.duration, seed=args.seed, shown=final)
        return run_online_demo(out, data=args.data, workers=args.workers, shown=final)


def run_online_demo(out: Path, *, data: str | None = None, workers: int = 2, evidence: dict | None = None,
                    methods: tuple[str, ...] | None = None, shown: Path | None = None) -> int:
    """The online experiment on the shipped real drive: the powered dense-window comparison
    (:data:`DEMO_EVIDENCE`, or ``evidence``) as the headline, then the paper-style five-window view with the
    demo's ``methods``; prints both and writes one report."""
    import logging

    from tqdm import tqdm

    from imunoise.cli.experiment import print_headline
    from imunoise.experiments import dense
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.online_exp import DEMO_METHODS, run_real
    from imunoise.experiments.report import DEMO_HEADS, evidence_headline_rows, headline_rows, write_online_real
    from imunoise.report import fmt

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    t_start = time.perf_counter()
    folder = data or str(repo_data_dir())
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_outages

    ev = {**DEMO_EVIDENCE, **(evidence or {})}
    methods = tuple(methods or DEMO_METHODS)
    regimes = [parse_gnss(g) for g in ev["gnss"]]
    _, spec = dense.parse_outages(ev["outages"])
    n_ev = len(ev["methods"]) * sum(len(ev["noise_seeds"]) if r.random else 1 for r in regimes)
    ds = read_dataset(folder)
    n_win = len(read_outages(ds.outages)) if ds.outages else 0
    bar = tqdm(total=n_ev + len(methods) * (n_win + 1) + 1, desc="demo: dense-window runs", unit="run")
    evres = dense.run_real(folder, spec=spec, regimes=regimes, noise_seeds=list(ev["noise_seeds"]),
                           methods=list(ev["methods"]), workers=workers, paper_windows=False,
                           progress=lambda _n: bar.update(1))
    bar.set_description("demo: five official windows")
    res, sc = run_real(folder, methods=methods, workers=workers, progress=lambda _n: bar.update(1))
    bar.set_description("writing the report")
    html = write_online_real(res, sc, out, evidence=evres)
    bar.update(1)
    bar.close()
    print(f"\nonline GMWM demo on {sc.name}")
    print(f"\nheadline: paired end-drift ratios on {evres['n_windows']} dense windows "
          f"({evres['n_independent']} independent, {ev['outages']}); < 1 = less drift than the baseline")
    _print_table(DEMO_HEADS, [[c if isinstance(c, str) else fmt(c, 3) for c in r]
                              for r in evidence_headline_rows(evres)])
    print(f"\npaper-style view: the {n_win} official outage windows (RTK; too few windows for a test)")
    print_headline(headline_rows(res), fmt)
    t = res.get("timing", {})
    if t.get("identification_s") is not None:
        print(f"structure identification {t['identification_s']:.2f} s (6 axes), refits "
              + ", ".join(f"{x * 1e3:.0f} ms" for x in t.get("refit_s", [])))
    print(f"\nreport: {((shown or out) / html.name).resolve()}  ({time.perf_counter() - t_start:.1f} s)")
    return 0


def _print_table(heads: list[str], rows: list[list[str]]) -> None:
    w = [max(len(h), *(len(str(r[i])) for r in rows)) for i, h in enumerate(heads)]
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(heads)))
    for r in rows:
        print("  ".join(str(c).ljust(w[i]) for i, c in enumerate(r)))


def run_static_demo(out: Path, *, duration_s: float = 3600.0, seed: int = 7, freq: float = 100.0,
                    shown: Path | None = None) -> int:
    """Simulate a static 6-axis recording with known models, fit each axis by GMWM, report."""
    import numpy as np
    from tqdm import tqdm

    from imunoise.imu import AXES
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.imu_model import ImuModel
    from imunoise.noise.plots import plot_wv_fit
    from imunoise.report import Report

    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    truth = demo_truth()
    n = int(duration_s * freq)
    rng = np.random.default_rng(seed)
    report = Report("imunoise demo: GMWM noise model of a static MEMS IMU")
    report.paragraph(
        f"A {duration_s / 3600:.2g} h static recording at {freq:g} Hz of a consumer MEMS IMU was simulated with "
        f"known error models (seed {seed}); each axis is then modelled with the GMWM (paper Eq. 6) using the "
        "structure 2*AR1+WN+RW. Parameters are per sample (discrete, at the data rate) with their "
        "continuous-time equivalents; units are SI (rad/s, m/s²)."
    )
    rows, axes_json = [], {}
    for axis in tqdm(AXES, desc="fitting axes", unit="axis", disable=not sys.stderr.isatty()):
        sensor = axis.split("_")[0]
        unit = "rad/s" if sensor == "gyro" else "m/s²"
        model = truth[sensor]
        x = model.simulate(n, rng)
        fit = gmwm(model.unknown(), x, freq=freq, unit=unit)
        axes_json[axis] = fit.to_dict()
        png = out / f"wv_{axis}.png"
        plot_wv_fit(fit, png, title=f"{axis}: {fit.model} (GOF {fit.objective:.3g})")
        cont_true, cont_fit = model.continuous(freq), fit.continuous()
        rows.append(
            [
                axis,
                str(fit.model),
                fit.objective,
                1e3 * fit.elapsed_s,
                cont_true["WN.noise_density"],
                cont_fit["WN.noise_density"],
                cont_true["AR1_1.tau_c"],
                cont_fit["AR1_1.tau_c"],
                cont_true["AR1_1.sigma_gm"],
                cont_fit["AR1_1.sigma_gm"],
            ]
        )
        report.heading(f"{axis}", 3)
        report.figure(png, f"{axis}: empirical WV with 95 % CI, GMWM fit and one dashed curve per process")
        report.pre(fit.summary())
    headers = [
        "axis", "model", "GOF", "fit ms", "N true [u/√Hz]", "N fit", "T_c,1 true [s]", "T_c,1 fit",
        "σ_GM,1 true [u]", "σ_GM,1 fit",
    ]
    report.blocks.insert(1, ("table", (headers, [[_f(c) for c in r] for r in rows], "truth vs GMWM, all axes")))
    ImuModel(freq, axes_json).save(out / "model.json")
    html_path, _ = report.write(out)
    elapsed = time.perf_counter() - t_start
    print(report.markdown().split("\n## ")[0].split("\n### ")[0])
    print(f"\nreport: {((shown or out) / html_path.name).resolve()}  ({elapsed:.1f} s)")
    return 0


def _f(value) -> str:
    from imunoise.report import fmt

    return fmt(value)
