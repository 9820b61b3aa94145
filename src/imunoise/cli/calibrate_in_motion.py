"""``imunoise calibrate --in-motion``: the in-motion stage after the static model of the stops
(docs/guide/theory.rst, 'In-use noise'; docs/guide/in_use.rst).

Each LOG is read as ``nav`` reads it (:func:`imunoise.cli.option_checks.read_nav_files`: KF-GINS text, bags
with NavSatFix, RTKLIB ``.pos``): a dataset folder brings its GNSS, lever arm and time offset; a single log
takes ``--gnss`` (and ``--lever-arm``). The drive starts at its first GNSS epoch after the IMU's first
``--static-duration`` s (aligned there, as ``nav``), its stops are the static detector's
(:func:`imunoise.inuse.stops.moving_flag`), and the drives are pooled (:func:`imunoise.inuse.
estimate_in_motion`).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from imunoise.cli.options import add_scheduler, check_scheduler
from imunoise.errors import DataError, ModelError

__all__ = ["add_in_motion_options", "check_in_motion", "in_motion_stage", "plot_factors"]

log = logging.getLogger(__name__)


def add_in_motion_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("in-motion noise (--in-motion)")
    g.add_argument("--in-motion", action="store_true",
                   help="also estimate the noise while moving (white factor, bias wander with 95 %% intervals) "
                        "from the whole GNSS-aided drive(s); needs GNSS: --gnss for one log or dataset folders")
    g.add_argument("--lever-arm", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="GNSS antenna position in body FRD from the IMU [m] (for --in-motion; default: the "
                        "dataset's, else 0 0 0)")
    g.add_argument("--static-duration", type=float, default=30.0, metavar="S",
                   help="seconds of still data at the IMU path start for levelling and gyro bias (for --in-motion "
                        "and its λ0; default 30)")
    add_scheduler(g, default="sequential", what="--in-motion: where the drives' filter runs go, one task per drive "
                  "and likelihood evaluation; the same estimate to the last bit")


def _drive_files(args: argparse.Namespace) -> list[tuple[str, str, str, Any, float]]:
    """(name, IMU path, GNSS path, lever [m], IMU time offset [s]) per LOG."""
    import numpy as np

    from imunoise.io.dataset import read_dataset

    out = []
    for path in args.logs:
        p = Path(path)
        if p.is_dir() and (p / "dataset.json").exists():
            ds = read_dataset(p)
            if ds.gnss is None:
                raise DataError(f"{path}: --in-motion needs GNSS; the dataset has none ('gnss' in dataset.json)")
            lever = np.asarray(args.lever_arm if args.lever_arm is not None else ds.lever_arm_m, dtype=float)
            out.append((ds.name, str(ds.imu), str(ds.gnss), lever, float(ds.imu_time_offset_s)))
        else:
            lever = np.asarray(args.lever_arm if args.lever_arm is not None else (0.0, 0.0, 0.0), dtype=float)
            out.append((p.name, str(p), str(args.gnss), lever, 0.0))
    return out


def check_in_motion(args: argparse.Namespace) -> None:
    """Refuse --in-motion without GNSS, and --scheduler without --in-motion, before any work (one line naming
    the fix)."""
    check_scheduler(args)
    if not getattr(args, "in_motion", False):
        if args.scheduler != "sequential" or args.workers is not None:
            raise ModelError("--scheduler and --workers run the drives of --in-motion on Dask: add --in-motion, or "
                             "drop them")
        return
    no_gnss = [p for p in args.logs if not (Path(p).is_dir() and (Path(p) / "dataset.json").exists())]
    if no_gnss and not args.gnss:
        raise ModelError("--in-motion estimates the noise while moving from GNSS-aided drives: give --gnss FILE "
                         "(KF-GINS, RTKLIB .pos, bag) for the log, or dataset folders with GNSS")


def _drive(name: str, imu_p: str, gnss_p: str, lever: Any, offset: float, static_duration: float) -> Any:
    import numpy as np

    from imunoise.cli.option_checks import read_nav_files
    from imunoise.experiments.common import Scenario
    from imunoise.inuse.stops import moving_flag
    from imunoise.nav.align import coarse_align

    imu, gnss, _, _ = read_nav_files(imu_p, gnss_p, None, offset, log)
    t_still = float(imu.t[0]) + static_duration
    gt = np.asarray(gnss.t, dtype=float)
    after = gt[gt >= t_still]
    if after.size == 0:
        raise DataError(f"{gnss_p}: no GNSS epoch after the first {static_duration:g} s of {imu_p}; --in-motion "
                        "needs GNSS while driving")
    init = coarse_align(imu, gnss, float(after[0]), static_duration=static_duration, lever_arm=lever)
    return Scenario(name, imu, gnss, None, lever, init, [], False, static_truth=~moving_flag(imu, static_duration))


def in_motion_stage(args: argparse.Namespace, model: Any) -> Any:
    """The in-motion estimate of the LOGs on top of the calibrated static ``model``
    (:class:`~imunoise.noise.imu_model.ImuModel`); sets ``model.in_motion`` and prints the summary."""
    import sys

    from imunoise.inuse import estimate_in_motion, summary_lines
    from imunoise.inuse.fleet import fleet_mapper

    drives = [_drive(*f, args.static_duration) for f in _drive_files(args)]
    rate = float(drives[0].imu.rate_hz)
    with fleet_mapper(args.scheduler, args.workers) as mapper:
        est = estimate_in_motion(drives, model, freq=rate, seed=args.seed, names=[d.name for d in drives],
                                 mapper=mapper)
    model.in_motion = est.part.to_dict()
    ev = est.part.evidence
    where = "" if mapper is None else f" + {mapper.worker_cpu_s:.1f} s on the Dask workers ({args.scheduler})"
    print(f"\nin-motion noise ({len(drives)} drive(s), {ev['hours_moving'] * 60:.1f} min moving, GNSS σ "
          f"{ev['gnss_sigma_m']:.2f} m; {est.runs} filter runs, {est.cpu_s:.1f} s CPU{where}):", file=sys.stdout)
    for line in summary_lines(est.part):
        print("  " + line)
    return est


def plot_factors(part: Any, path: Path) -> Path:
    """The white factor of each axis with its 95 % interval (log scale; 1 = the static model)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imunoise.imu import AXES

    fig, ax = plt.subplots(figsize=(5.5, 2.6))
    for i, a in enumerate(AXES):
        wf = part.axis(a).white_factor
        if wf.value is None:
            ax.plot([i], [1.0], "x", color="0.5")
            continue
        lo, hi = wf.ci95 if wf.ci95 else (wf.value, wf.value)
        ax.errorbar([i], [wf.value], yerr=[[wf.value - lo], [hi - wf.value]], fmt="o", capsize=3,
                    color="tab:blue" if i < 3 else "tab:orange")
    ax.axhline(1.0, color="0.3", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xticks(range(6), AXES, fontsize=8)
    ax.set_ylabel("in-use / static N")
    ax.set_title("white factor while moving (95 % interval; × = not identified)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

