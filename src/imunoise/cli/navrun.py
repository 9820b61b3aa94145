"""What ``imunoise nav`` and ``imunoise online`` share (docs/guide/theory.rst, 'Navigation filter' and 'Interfaces'):
the start of a run (inputs resolved, read
and checked before the work) and its outputs (KF-GINS trajectory file, metrics of a run, outage summary).

Not a command: it has no ``register`` function, so the sub-command discovery of :mod:`imunoise.cli` skips it.
Light at import (no numpy), like :mod:`imunoise.cli.options`.
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imunoise.cli.options import (
    MAX_IMU_GAP_S,
    prepare_out_dir,
    read_json_option,
    read_nav_files,
    resolve_nav_inputs,
)
from imunoise.errors import ModelError

__all__ = [
    "NavInputs",
    "read_nav_inputs",
    "nav_start",
    "gyro_unit_notes",
    "write_trajectory",
    "run_metrics",
    "outage_summary",
    "add_mount_option",
    "mounting_notes",
    "mounting_metrics",
]


@dataclass
class NavInputs:
    """The inputs of a navigation run, read; paths as given (for the messages), data in SI."""

    dataset: Any  # the --data manifest (imunoise.io.dataset.Dataset) or None
    imu_path: str
    gnss_path: str
    ref_path: str | None
    outages_path: str | None
    lever: Any  # np.ndarray (3,), m
    imu: Any
    gnss: Any
    ref: Any  # Reference or None
    notes: list[str]  # the readers' warnings, for metrics.json
    windows: list[tuple[float, float]]  # GNSS outage windows (start, duration), s


def read_nav_inputs(args: argparse.Namespace, log: logging.Logger) -> NavInputs:
    """Resolve the files of :func:`~imunoise.cli.options.add_nav_input_options`, refuse an unusable ``--out``,
    a malformed ``--imu-model`` file and ``--outage-runs`` without windows before the work, then read the files
    and the outage windows."""
    from imunoise.io.kfgins import read_outages
    from imunoise.io.navchecks import check_imu_gaps

    mount = getattr(args, "mount_rpy", None)
    if mount is not None:
        from imunoise.nav.mounting import parse_mount_rpy

        mount = args.mount_rpy = parse_mount_rpy(mount)  # refused before the work
    ds, imu_p, gnss_p, ref_p, out_p, lever, offset = resolve_nav_inputs(args)
    prepare_out_dir(args.out)  # an unusable --out fails before the work
    if args.imu_model:
        read_json_option(args.imu_model, "--imu-model")  # a binary / malformed model file: one error naming it
    if args.outage_runs and not out_p:
        raise ModelError("--outage-runs needs --outages F (or a dataset.json with 'outages')")
    imu, gnss, ref, notes = read_nav_files(
        imu_p,
        gnss_p,
        ref_p,
        offset,
        log,
        imu_topic=getattr(args, "topic", None),
        gnss_topic=getattr(args, "gnss_topic", None),
        imu_frame=getattr(args, "imu_frame", None),
        min_quality=getattr(args, "min_quality", 6),
    )
    check_imu_gaps(imu.t, getattr(args, "max_imu_gap", MAX_IMU_GAP_S), imu_p)
    if mount is not None:  # once, here: alignment, NHC and ZUPT all see a vehicle-frame IMU
        from imunoise.nav.mounting import mount_matrix, rotate_imu

        imu = rotate_imu(imu, mount_matrix(mount))
    windows = read_outages(out_p) if out_p else []
    return NavInputs(ds, imu_p, gnss_p, ref_p, out_p, lever, imu, gnss, ref, notes, windows)


def nav_start(args: argparse.Namespace, inp: NavInputs) -> tuple[float, str]:
    """The start of a navigation run, the same rule for ``nav`` and ``online``: ``--start``, else the
    manifest's ``start_sow``, else the first GNSS epoch inside the IMU data; with where it came from (for
    :func:`~imunoise.cli.options.check_nav_span`'s messages)."""
    if args.start is not None:
        return float(args.start), "--start"
    sow = inp.dataset.extra.get("start_sow") if inp.dataset is not None else None
    if sow is not None:
        try:
            return float(sow), f"start_sow of {inp.dataset.root / 'dataset.json'}"
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{inp.dataset.root / 'dataset.json'}: start_sow must be a number, got {sow!r}") from exc
    return max(float(inp.imu.t[0]), float(inp.gnss.t[0])), ""


def write_trajectory(path: Path, res: Any, ref: Any) -> None:
    """Write a navigation result (``t``, ``llh``, ``vel_ned``, ``euler``) as a KF-GINS ``.nav`` file; the GPS
    week is the reference's (0 without one)."""
    import numpy as np

    from imunoise.io.kfgins import Reference, write_reference

    week = int(ref.week[0]) if ref is not None and ref.week.size else 0
    write_reference(
        path, Reference(t=res.t, llh=res.llh, vel_ned=res.vel_ned, euler=res.euler, week=np.full(res.t.size, week))
    )


def run_metrics(
    res: Any, ref: Any, lever: Any, outages: Sequence[tuple[float, float]], duration_s: float
) -> tuple[dict, Any]:
    """The metrics of one run (docs/guide/theory.rst, 'Navigation filter'): with a reference, the errors of the GNSS
    antenna and the drift over ``outages`` (the windows removed in this run); without one, only the run time.

    Returns
    -------
    tuple
        (metrics dict, :class:`imunoise.nav.metrics.NavErrors` or None without a reference).
    """
    from imunoise.nav.metrics import nav_errors, summarize

    if ref is None:
        speed = {"elapsed_s": res.elapsed_s, "realtime_factor": duration_s / max(res.elapsed_s, 1e-9), "outages": []}
        return speed, None
    err = nav_errors(res.t, res.antenna_llh(lever), res.vel_ned, res.euler, ref)
    return summarize(err, outages=outages, elapsed_s=res.elapsed_s, duration_s=duration_s), err


def outage_summary(outs: list[dict]) -> dict:
    """``metrics.json`` keys of ``--outage-runs``: the drift of each separate run at the end of its window and
    their mean horizontal end drift."""
    from imunoise.nav.metrics import mean_end_drift

    return {"outages": outs, "mean_outage_end_horizontal_m": mean_end_drift(outs)}


def gyro_unit_notes(imu: Any, gnss: Any, init: Any, static_duration: float, imu_path: str) -> list[str]:
    """The warning of :func:`imunoise.io.navchecks.gyro_unit_evidence` (gyros turning ≈ 57× the GNSS track:
    deg/s read as rad/s) for ``metrics.json``, or nothing."""
    import numpy as np

    from imunoise.io.navchecks import gyro_unit_evidence
    from imunoise.nav.earth import llh_to_ned

    gyro, _ = imu.rates()
    still = imu.t <= imu.t[0] + static_duration
    ned = llh_to_ned(gnss.llh, gnss.llh[0])
    roll, pitch = float(init.euler[0]), float(init.euler[1])
    step = max(10.0, 30.0 * float(np.median(np.hypot(gnss.sigma_ned[:, 0], gnss.sigma_ned[:, 1]))))
    bias = np.mean(gyro[still], axis=0)
    note = gyro_unit_evidence(imu.t, gyro, roll, pitch, bias, gnss.t, ned, imu_path, min_step_m=step)
    return [note] if note else []


def add_mount_option(p: argparse.ArgumentParser) -> None:
    """``--mount-rpy R,P,Y``: the IMU's mounting in the vehicle (:mod:`imunoise.nav.mounting`)."""
    p.add_argument("--mount-rpy", metavar="R,P,Y",
                   help="the IMU's mounting in the vehicle FRD frame, roll,pitch,yaw [deg] as an attitude (0,0,90: "
                        "the IMU's x points right); its data are turned into the vehicle frame before anything "
                        "else. Without it the run checks the mounting and warns above 10° with the value to give")


def mounting_notes(args: argparse.Namespace, inp: NavInputs, log: logging.Logger) -> list[str]:
    """The mounting check of a run (:func:`imunoise.nav.mounting.estimate_mounting`) on the IMU as the filter takes
    it (after ``--mount-rpy``): the estimate kept in ``args.mounting`` for ``metrics.json`` and the one-line
    warning above the threshold, or nothing."""
    import numpy as np

    from imunoise.nav.earth import llh_to_ned
    from imunoise.nav.mounting import estimate_mounting, mounting_warning

    imu, gnss = inp.imu, inp.gnss
    still = imu.t <= imu.t[0] + args.static_duration  # the levelling window of coarse_align
    sigma_h = float(np.median(np.hypot(gnss.sigma_ned[:, 0], gnss.sigma_ned[:, 1])))
    est = estimate_mounting(imu.t, imu.dv, still, gnss.t, llh_to_ned(gnss.llh, gnss.llh[0]), sigma_h)
    given = getattr(args, "mount_rpy", None)
    args.mounting = {"mount_rpy_deg": list(given) if given else None, "check": est.as_dict()}
    log.info("mounting check: roll %.1f° pitch %.1f° at the first stop, yaw %s from %d GNSS epochs", est.roll_deg,
             est.pitch_deg, "unobserved" if est.yaw_deg is None else f"{est.yaw_deg:.1f}°", est.epochs)
    note = mounting_warning(est, inp.imu_path, given=given)
    return [note] if note else []


def mounting_metrics(args: argparse.Namespace, res: Any) -> dict:
    """``metrics.json`` ``mounting``: the option, the check and the filter's sideslip (its NHC residual's
    direction, :func:`imunoise.nav.mounting.sideslip_deg`)."""
    from imunoise.nav.mounting import sideslip_deg

    m = dict(getattr(args, "mounting", None) or {})
    m["filter_sideslip_deg"] = sideslip_deg(res.euler, res.vel_ned) if res.t.size else None
    return m

