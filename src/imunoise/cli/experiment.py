"""`imunoise experiment denial|online`: the paper's two experiments (docs/guide/theory.rst, 'Experiments') with a
report."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from imunoise.cli.aiding_options import add_aiding_options, stream_keys
from imunoise.cli.options import (
    add_deprecated_alias,
    int_at_least,
    nonnegative_float,
    positive_float,
    positive_int,
)
from imunoise.errors import ModelError

EXAMPLES = """examples:
  imunoise experiment online --data data/drive_0708 --out out/exp_online
  imunoise experiment online --sim --seeds 20 --out out/mc_online          # Monte Carlo, both cores
  imunoise experiment denial --sim --seeds 20 --out out/mc_denial
  imunoise experiment online --sim --seeds 5 --gnss-vel --out out/mc_vel   # + simulated GNSS velocity
  imunoise experiment denial --data data/drive_0708 --out out/denial_real
  imunoise experiment online --data data/drive_0708 --outages dense:60:20 --gnss-regime rtk \
      --gnss-regime noise:1.5,3,1 \
      --noise-seeds 5 --pairs gmwm/av,gmwm/em --out out/evidence      # paired ratios with CIs (evidence)

Writes DIR/report.html (one self-contained page), DIR/report.md, DIR/results.json (docs/guide/theory.rst, 'Experiments'
keys: methods → horizontal_rms_m, vertical_rms_m, ecef_rms_m, outage_end_horizontal_m, mean_outage_end_horizontal_m;
timing; seeds and per_seed for Monte Carlo), CSV tables (headline.csv, outages.csv, differences.csv or
sections.csv) and PNG figures. Lengths in m, times in s.

With --outages dense:L:S[:LEAD], --gnss-regime or --pairs (online only) the run is the dense-window evidence
(imunoise.experiments.dense): results.json has "paired" (per GNSS regime, metric drift/rms/aided_rms, each
method vs plain and vs static_var and every --pairs pair: geometric-mean ratio, 95 % CI, n_windows,
n_independent, n_drives, significant) and report.md/html lead with that table."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "experiment",
        help="the paper's experiments: GNSS denial (Table 1) and online GNSS-available (Tables 5-6)",
        description="Run the GNSS-denial or the online experiment on a dataset folder or the simulator.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("which", choices=("denial", "online"), help="which experiment")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--sim", action="store_true", help="Monte Carlo on simulated drives "
                                                        "(docs/guide/theory.rst, 'Simulator')")
    src.add_argument("--data", help="dataset folder with a dataset.json manifest (docs/guide/theory.rst, 'Interfaces'; "
                                    "with a reference; "
                     "default: data/drive_0708)")
    p.add_argument("--seeds", type=positive_int, default=20, help="simulator: number of seeds (default 20)")
    p.add_argument("--seed0", type=int, default=0, help="simulator: first seed (default 0)")
    p.add_argument("--duration", type=positive_float, default=600.0,
                   help="simulator: length of the simulated recording [s] (default 600)")
    p.add_argument("--stops", type=int_at_least(0), default=4,
                   help="simulator: traffic-light stops of the simulated drive (default 4)")
    p.add_argument("--outages", default=None,
                   help="outage windows: dense:L:S[:LEAD] (windows of L s every S s after LEAD s of aiding; "
                   "default 60:20:60), a number (simulator: 60 s outages per drive, default 4) or an outage file")
    p.add_argument("--gnss-regime", action="append", default=None, metavar="REGIME",
                   help="GNSS regime, repeatable: rtk (as recorded, default) or noise:H,V[,RATE[,TAU]] "
                   "(σ north/east and down [m], thinned to RATE Hz, white or Gauss-Markov with TAU s)")
    p.add_argument("--noise-seeds", type=positive_int, default=5, help="noise regimes: GNSS noise seeds (default 5)")
    p.add_argument("--noise-seed0", type=int, default=1, help="first GNSS noise seed (default 1)")
    p.add_argument("--pairs", help="extra paired comparisons method/baseline,... (e.g. gmwm/av,gmwm/em)")
    p.add_argument("--nhc", action="store_true",
                   help="non-holonomic constraints (dense-window evidence: every method also run with them as "
                        "NAME+nhc, paired with its twin and with plain+nhc)")
    p.add_argument("--bootstrap", type=positive_int, default=2000,
                   help="bootstrap replicates of the CIs (default 2000)")
    p.add_argument("--boot-seed", type=int, default=0, help="bootstrap seed (default 0)")
    p.add_argument("--imu-model", default=None,
                   help="simulator: IMU error models: preset (paper, mems, tactical), structure, or model JSON "
                   "(imunoise.sim.resolve_imu_models; default: paper = gyros of paper Table 4 and mems "
                   "accelerometers, 3*AR1+WN+RW per axis)")
    p.add_argument("--motion-noise", default=None, metavar="LAW|FILE.json",
                   help="simulator: motion law of the IMU errors (imunoise.sim.motion): drive0708 (default: white "
                   "noise and gyro y/z bias wander grow while moving, calibrated on the real drive), none "
                   "(moving = static, the paper's premise), another shipped law (gyro_departure_step, "
                   "gyro_moving_gm, accel_moving_gm, warmup) or a law file FILE.json")
    p.add_argument("--static-hours", type=positive_float, default=None,
                   help="denial --sim: static recording [h] (default 2; 1 with --imu-noise)")
    p.add_argument("--imu-noise", default=None, metavar="FILE.npz",
                   help="simulator: replay a real static recording (.npz with data, columns, units, freq_hz) as "
                   "the drives' IMU errors, one non-overlapping stretch per drive (K per vehicle with "
                   "--vehicle-drives K), its mean removed "
                   "(imunoise.sim.replay; other rates than the simulator's are refused)")
    p.add_argument("--methods", help="comma-separated subset of the methods")
    p.add_argument("--start", type=float, help="real data: start time [s, data time base]")
    p.add_argument("--workers", type=positive_int, default=2,
                   help="local worker processes (parallel drives; default 2; with --scheduler local the cluster's "
                   "size)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler (dense-window evidence on the simulator: the drives run on Dask): 'local' "
                   "(a LocalCluster of --workers processes) or a scheduler address tcp://HOST:PORT whose workers "
                   "have imunoise; default: --workers forked local processes; results are identical either way")
    p.add_argument("--latency", type=nonnegative_float, default=None,
                   help="online methods: fixed delay [s] from a stop's end to its model in the filter (a run "
                        "repeats to the bit; default: the measured compute time, as the paper; the hot-swap "
                        "moment then follows the machine's load)")
    p.add_argument("--seed-role", choices=("dev", "report"), default="dev",
                   help="what the seeds are for, recorded in results.json and named in the report: dev "
                   "(development, default) or report (fresh seeds, run once per method version)")
    add_aiding_options(p)  # here without FILE: the simulator simulates the stream, --data reads the manifest's
    p.add_argument("--vehicle-drives", default="1", metavar="K",
                   help="simulator, dense-window evidence: K drives per seed (a vehicle: the same IMU, motion law "
                   "and vehicle; other routes, stops and noise), every method scored on the last; default 1")
    p.add_argument("--learn-from-logs", nargs="+", default=None, metavar="DATASET",
                   help="real data, dense-window evidence: dataset folders of the same vehicle's other drives, which "
                   "the in_use method learns its model on (the drive of --data is only navigated)")
    p.add_argument("--learn-half", choices=("first", "second"), default=None,
                   help="real data, dense-window evidence: in_use learns on this half of the --data drive (cut midway "
                   "between the start and the last fix; every run starts at the drive's alignment) and only the "
                   "other half is scored: the windows whose outage lies in it and its NEES epochs")
    p.add_argument("--out", required=True, help="output folder")
    add_deprecated_alias(p, "--imu", "--imu-model")
    add_deprecated_alias(p, "--gnss", "--gnss-regime")
    p.set_defaults(func=run)


def select_methods(which: str, sim: bool, methods: str | None, evidence: bool = False) -> tuple[str, ...]:
    """The methods of one run (docs/guide/theory.rst, 'Experiments'): ``methods`` ("a,b,c") checked against the choices
    of the mode, or
    the mode's default list. The online Monte Carlo also offers ``oracle`` (the simulator's true IMU model
    in the filter), which real data cannot have; the default list of every mode passes this check.
    ``evidence``: the dense-window evidence (:data:`imunoise.experiments.dense.EVIDENCE_METHODS` by default,
    plus ``oracle`` on the simulator)."""
    from imunoise.experiments import denial, dense, online_exp

    mod = denial if which == "denial" else online_exp
    default = online_exp.MC_METHODS if (which == "online" and sim) else mod.METHODS
    if evidence:
        default = (*dense.EVIDENCE_METHODS, *(dense.SIM_EXTRA if sim else ()))
    allowed = tuple(dict.fromkeys((*mod.METHODS, *default)))
    if evidence:
        sim_only = ("oracle", "oracle_const", "oracle_const_gmwm", *dense.WARM_METHODS, *dense.STATIC_WARM_METHODS)
        extra = ("static_var_hindsight", "adaptive", "gmwm_dyn", "gmwm_lik", "in_use", "in_use_stops",
                 *(sim_only if sim else ()))
        allowed = tuple(dict.fromkeys((*allowed, *extra)))
    chosen = tuple(m.strip() for m in methods.split(",") if m.strip()) if methods else default
    if evidence:  # any evidence method with the scale-factor states: NAME+sf
        allowed = (*allowed, *(m + dense.SF_SUFFIX for m in allowed))
        allowed = (*allowed, *(m + dense.NHC_SUFFIX for m in allowed))
    bad = [m for m in chosen if m not in allowed]
    if bad or not chosen:
        raise ModelError(f"unknown method(s) {bad or [methods]}; choose from {', '.join(allowed)}")
    return chosen


def _progress(total: int, desc: str, unit: str = "job"):
    """A tqdm bar with an ETA on stderr (off when stderr is not a terminal) and its step; ``step(n)`` with an
    integer adds n units, any other argument (a seed, a method name) one."""
    from tqdm import tqdm

    from imunoise.io.interrupt import interrupt_point

    bar = tqdm(total=total, desc=desc, unit=unit, disable=not sys.stderr.isatty())

    def step(n=None) -> None:
        bar.update(n if isinstance(n, int) and not isinstance(n, bool) else 1)
        interrupt_point("experiment-progress")

    return bar, step


def run(args: argparse.Namespace) -> int:
    from imunoise.io.atomic import staged_run

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from imunoise.cli.options import prepare_out_dir

    args.motion_noise = _motion_arg(args)  # checked before the output folder is made
    args.base = _base_config(args)
    from imunoise.experiments.dense import parse_outages

    form, outages = parse_outages(args.outages)
    evidence = form == "dense" or bool(args.gnss_regime) or bool(args.pairs) or args.nhc
    _check_vehicle(args, evidence)
    if args.seed_role == "report":  # refused before anything is made: a report label must be true
        from imunoise.experiments.gnss_regimes import parse_gnss
        from imunoise.experiments.report_tables import seed_role_problem

        noisy = evidence and any(parse_gnss(g).random for g in (args.gnss_regime or ["rtk"]))
        why = seed_role_problem(
            sim=args.sim, seeds=range(args.seed0, args.seed0 + max(args.seeds, 0)) if args.sim else (),
            noise_seeds=range(args.noise_seed0, args.noise_seed0 + max(args.noise_seeds, 0)) if noisy else ())
        if why:
            raise ModelError(f"--seed-role report: {why}")
    if args.scheduler and not (evidence and args.sim):
        raise ModelError("--scheduler runs the dense-window evidence on the simulator (--sim --outages dense:L:S); "
                         "drop it, or use --workers")
    final = prepare_out_dir(args.out)
    # the report, its tables, plots and results.json appear at once when the run completes: an interrupted or
    # failed run leaves --out as it was (files of another kind already there are left alone)
    with staged_run(final, ()) as out:
        return _run_in(args, out, final, form, outages, evidence)


def _run_in(args: argparse.Namespace, out: Path, final: Path, form, outages, evidence: bool) -> int:
    """The experiment, its files written into ``out`` (the staging folder of ``final``)."""
    from imunoise.experiments import denial, online_exp
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.report import headline_rows, write_denial_real, write_online_real, write_sim
    from imunoise.report import fmt

    t0 = time.perf_counter()
    if evidence:
        if args.which != "online":
            raise ModelError("--outages dense:..., --gnss-regime, --pairs and --nhc belong to the online experiment")
        return _run_evidence(args, out, outages, t0, final)
    methods = select_methods(args.which, args.sim, args.methods)
    if args.imu_noise:
        from imunoise.experiments.common import replay_methods

        methods = replay_methods(methods, bool(args.methods))
    if form == "file" and args.sim:
        raise ModelError("--outages FILE is for real data; the simulator takes a number or dense:L:S")
    if form == "count" and not args.sim:
        raise ModelError("--outages N is for the simulator; on real data give dense:L:S or an outage file")
    if args.sim:
        if args.seeds < 1:
            raise ModelError(f"--seeds must be ≥ 1, got {args.seeds}")
        seeds = list(range(args.seed0, args.seed0 + args.seeds))
        bar, step = _progress(len(seeds), f"{args.which} Monte Carlo")
        kw = {"duration_s": args.duration, "n_stops": args.stops, "n_outages": 4 if outages is None else outages,
              "streams": stream_keys(args)}
        if args.imu_model:
            kw["imu_models"] = args.imu_model
        kw["motion_noise"] = args.motion_noise
        static_h = args.static_hours if args.static_hours is not None else (1.0 if args.imu_noise else 2.0)
        from imunoise.experiments.common import imu_noise_kwargs

        kw.update(imu_noise_kwargs(args.imu_noise, args.seed0, imu=args.imu_model,
                                   reserve_s=3600.0 * static_h if args.which == "denial" else 0.0))
        if args.which == "denial":
            res = denial.run_sim(seeds, methods=methods, workers=args.workers,
                                 static_recording_s=3600.0 * static_h, progress=step, **kw)
        else:
            res = online_exp.run_sim(seeds, methods=methods, workers=args.workers, progress=step, base=args.base,
                                     **kw)
        bar.close()
        res["seed_role"] = args.seed_role
        html = write_sim(res, out, title=f"imunoise: {args.which} experiment, Monte Carlo ({len(seeds)} seeds)")
    else:
        data = args.data or str(repo_data_dir())
        n_runs = len(methods) * 6 if args.which == "online" else len(methods)
        bar, step = _progress(n_runs, f"{args.which} experiment")
        if args.which == "denial":
            res, sc = denial.run_real(data, methods=methods, start=args.start, progress=step, streams=stream_keys(args))
            bar.close()
            res["seed_role"] = args.seed_role
            html = write_denial_real(res, sc, out)
        else:
            windows = None
            if form == "file":
                from imunoise.io.kfgins import read_outages

                windows = read_outages(outages)
            res, sc = online_exp.run_real(data, methods=methods, workers=args.workers, start=args.start, progress=step,
                                          windows=windows, base=args.base, streams=stream_keys(args))
            bar.close()
            res["seed_role"] = args.seed_role
            html = write_online_real(res, sc, out)
    print_headline(headline_rows(res), fmt)
    print(f"\nreport: {(final / html.relative_to(out)).resolve()}  ({time.perf_counter() - t0:.1f} s)")
    return 0


def _check_vehicle(args: argparse.Namespace, evidence: bool) -> None:
    """``--vehicle-drives`` read (an int >= 1, one-line error otherwise) and refused where it has no meaning."""
    from imunoise.experiments.carry_over import check_vehicle_drives

    args.vehicle_drives = check_vehicle_drives(args.vehicle_drives)
    if args.vehicle_drives > 1 and not (evidence and args.sim):
        raise ModelError("--vehicle-drives K > 1 simulates vehicles of K drives for the dense-window evidence: add "
                         "--sim and --outages dense:L:S")
    if args.learn_from_logs and (args.sim or not evidence):
        raise ModelError("--learn-from-logs gives in_use its drives on real data in the dense-window evidence "
                         "(--data ... --outages dense:L:S); on the simulator use --vehicle-drives K")
    if args.learn_half and (args.sim or not evidence):
        raise ModelError("--learn-half cross-fits on the halves of a real drive in the dense-window evidence "
                         "(--data ... --outages dense:L:S); on the simulator use --vehicle-drives K")
    learned = {"in_use", "in_use_stops", "oracle_const_gmwm"} & set((args.methods or "").split(","))
    if args.learn_half and "in_use_stops" in learned:  # refused here, before the drive's learning runs
        raise ModelError("--methods in_use_stops pools the stops in_use learned its static part on, and --learn-half "
                         "fits that part on the whole drive's stops: use in_use with --learn-half")
    if learned and args.sim and args.vehicle_drives < 2:
        raise ModelError(f"--methods {sorted(learned)[0]} learns on a vehicle's earlier drives: give --vehicle-drives "
                         "2 or more")
    if args.imu_noise and args.sim and evidence and args.seeds >= 1:  # every vehicle's stretches fit the recording
        from imunoise.sim import DriveConfig
        from imunoise.sim.replay import check_vehicles

        check_vehicles(str(Path(args.imu_noise).resolve()), args.seed0, [args.seed0 + args.seeds - 1],
                       args.vehicle_drives, args.duration, DriveConfig.imu_rate_hz)


def _base_config(args: argparse.Namespace):
    """The online engine's settings every method starts from: the defaults, with ``--latency`` if given."""
    from imunoise.online import OnlineConfig

    if args.latency is None:
        return None
    if args.which != "online":
        raise ModelError("--latency belongs to the online experiment (the denial experiment swaps no model)")
    if not (args.latency >= 0 and args.latency < float("inf")):
        raise ModelError(f"--latency must be a finite number of seconds ≥ 0, got {args.latency}")
    return OnlineConfig(latency=args.latency)


def _motion_arg(args: argparse.Namespace) -> str | None:
    """The law of ``--motion-noise`` on the simulator, a shipped law's name or a law file's path (default
    :data:`imunoise.sim.motion.DEFAULT_MOTION`, ``none`` with ``--imu-noise``); checked before any run. Real
    data have their own motion: the option is refused there."""
    if not args.sim:
        if args.motion_noise is not None or args.imu_noise is not None:
            raise ModelError("--motion-noise and --imu-noise belong to the simulator (--sim); real data have their "
                             "own motion and noise")
        return None
    from imunoise.sim.motion import DEFAULT_MOTION, motion_arg

    # a replayed recording is used as it is: no law by default
    return motion_arg(args.motion_noise or ("none" if args.imu_noise else DEFAULT_MOTION))


def print_headline(rows, fmt) -> None:
    """Print the headline table of an experiment (one line per method: horizontal / vertical RMS, mean
    end-of-outage drift and the change against the plain default) to stdout.

    Parameters
    ----------
    rows : list of list
        :func:`imunoise.experiments.report.headline_rows` of the results.
    fmt : callable
        Number formatter (:func:`imunoise.report.fmt`).
    """
    heads = ["method", "horiz. RMS [m]", "vert. RMS [m]", "mean outage drift [m]", "Δ vs plain [%]"]
    table = [[r[0].split(" (")[0], fmt(r[1]), fmt(r[2]), fmt(r[4]), fmt(r[5])] for r in rows]
    w = [max([len(h), *(len(t[i]) for t in table)]) for i, h in enumerate(heads)]  # no pairs: heads only
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(heads)))
    for t in table:
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(t)))


def _run_evidence(args: argparse.Namespace, out, spec, t0: float, final: Path) -> int:
    """The dense-window evidence (``imunoise.experiments.dense``) with its paired table."""
    from imunoise.experiments import dense
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.report import paired_rows, write_evidence
    from imunoise.report import fmt

    spec = spec if isinstance(spec, dense.DenseSpec) else dense.DenseSpec()
    methods = select_methods("online", args.sim, args.methods, evidence=True)
    if args.imu_noise:
        from imunoise.experiments.common import replay_methods

        methods = replay_methods(methods, bool(args.methods))
    regimes = [parse_gnss(g) for g in (args.gnss_regime or ["rtk"])]
    if args.noise_seeds < 1:
        raise ModelError(f"--noise-seeds must be ≥ 1, got {args.noise_seeds}")
    noise_seeds = list(range(args.noise_seed0, args.noise_seed0 + args.noise_seeds))
    pairs = dense.parse_pairs(args.pairs)
    if args.nhc:
        methods, nhc_pairs = dense.with_nhc(methods)
        pairs += [p for p in nhc_pairs if p not in pairs]
    for a, b in pairs:
        if a not in methods or b not in methods:
            raise ModelError(f"--pairs {a}/{b}: both must be among the methods ({', '.join(methods)})")
    kw = {"spec": spec, "regimes": regimes, "noise_seeds": noise_seeds, "methods": methods, "pairs": pairs,
          "workers": args.workers, "n_boot": args.bootstrap, "boot_seed": args.boot_seed,
          "base": args.base}
    if args.sim:
        if args.seeds < 1:
            raise ModelError(f"--seeds must be ≥ 1, got {args.seeds}")
        seeds = list(range(args.seed0, args.seed0 + args.seeds))
        # one unit = one method on one GNSS realisation of one drive
        bar, step = _progress(len(seeds) * dense.n_units(methods, regimes, noise_seeds), "evidence (drives × methods)",
                              unit="run")
        scen = {"duration_s": args.duration, "n_stops": args.stops, "streams": stream_keys(args)}
        if args.imu_model:
            scen["imu_models"] = args.imu_model
        scen["motion_noise"] = args.motion_noise
        from imunoise.experiments.common import imu_noise_kwargs

        scen.update(imu_noise_kwargs(args.imu_noise, args.seed0, imu=args.imu_model,
                                     vehicle_drives=args.vehicle_drives))
        res = dense.run_sim(seeds, progress=step, scheduler=args.scheduler, vehicle_drives=args.vehicle_drives,
                            **kw, **scen)
        title = f"imunoise: dense-window evidence, {len(seeds)} simulated drives"
    else:
        data = args.data or str(repo_data_dir())
        n_jobs = len(methods) * sum(len(noise_seeds) if r.random else 1 for r in regimes)
        bar, step = _progress(n_jobs, "evidence")
        res = dense.run_real(data, start=args.start, progress=step, streams=stream_keys(args),
                             learn_from=args.learn_from_logs or (), learn_half=args.learn_half, **kw)
        title = f"imunoise: dense-window evidence on {data}"
    bar.close()
    res["elapsed_s"] = time.perf_counter() - t0
    res["latency_s"] = args.latency  # None: each model took effect after its measured compute time
    res["seed_role"] = args.seed_role
    html = write_evidence(res, out, title=title)
    rows = paired_rows(res)
    heads = ["GNSS", "method", "baseline", "metric", "ratio", "95 % CI", "n_win", "n_ind", "n_drv", "verdict"]
    table = [[str(c) if isinstance(c, (str, int)) else fmt(c, 3) for c in r] for r in rows]
    w = [max([len(h), *(len(t[i]) for t in table)]) for i, h in enumerate(heads)]  # no pairs: heads only
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(heads)))
    for t in table:
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(t)))
    from imunoise.experiments.evidence_report import nees_rows

    for r in nees_rows(res):
        print(f"NEES pos+vel (6 dof) inside its 95 % band, {r[0]}, {r[1]}: {r[2]} [{r[3]}] over {r[5]} epochs of "
              f"{r[6]} drive(s); mean NEES {r[4]}")
    print(f"\nreport: {(final / html.relative_to(out)).resolve()}  ({time.perf_counter() - t0:.1f} s)")
    return 0
