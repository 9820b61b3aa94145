"""The measurement streams besides GNSS position on the command line: one option per source of
:mod:`imunoise.nav.aiding_sources` (``--gnss-vel [FILE]``, ...), shared by ``nav``, ``online`` and ``experiment``.

Each option takes a file or a bag (``OPTION-topic`` chooses the bag's topic); without FILE it takes the file the
``--data`` manifest names under the source's key. This table holds names and help only (building the parser loads
nothing numerical); :func:`read_aiding` reads through the source's reader, :func:`aiding_metrics` counts what became
of every epoch (metrics.json, one entry per source under its key).
"""

from __future__ import annotations

import argparse
import logging
from typing import Any, NamedTuple

from imunoise.errors import ModelError

__all__ = ["AidingOption", "OPTIONS", "add_aiding_options", "read_aiding", "aiding_metrics", "epoch_counts",
           "stream_keys"]


class AidingOption(NamedTuple):
    """The option of a source: ``key`` (the source's, :mod:`imunoise.nav.aiding_sources`; the manifest key and
    ``args`` destination), the flag, its help."""

    key: str
    flag: str
    help: str


OPTIONS: tuple[AidingOption, ...] = (
    AidingOption("gnss_vel", "--gnss-vel",
                 "GNSS antenna velocity fixes: a file (t vN vE vD [σN σE σD]: GPS s, NED m/s; default σ 0.05 m/s) or a "
                 "bag's TwistStamped/TwistWithCovarianceStamped topic (ENU); without FILE the manifest's 'gnss_vel' "
                 "(--data). Aids through outages; counts in metrics.json"),
    AidingOption("odometer", "--odometer",
                 "vehicle (wheel) speed: a file (t speed [σ]: IMU time base s, m/s; default σ 0.05 m/s, scale-factor "
                 "σ 1 %%) or a bag's TwistStamped/Odometry topic (linear.x); without FILE the manifest's 'odometer' "
                 "(--data). Aids through outages (imunoise.nav.measurements.odometer); counts in metrics.json"),
)


def add_aiding_options(p: argparse.ArgumentParser) -> None:
    """Add every source's option and its ``-topic`` option to ``p``."""
    for o in OPTIONS:
        p.add_argument(o.flag, nargs="?", const="", metavar="FILE", help=o.help)
        p.add_argument(f"{o.flag}-topic", metavar="TOPIC",
                       help=f"ROS bag given to {o.flag}: its topic (default: the only one of a fitting type)")


def read_aiding(args: argparse.Namespace, inp: Any, log: logging.Logger) -> list[tuple[Any, Any]]:
    """``(source, epochs)`` of every source whose option was given (:class:`~imunoise.nav.streams.Epochs`, checked
    against the IMU's time base and the GNSS track by the source's reader); rows dropped for a NaN are logged and
    noted in ``inp.notes`` (metrics.json's warnings)."""
    out = []
    for o in OPTIONS:
        opt = getattr(args, o.key, None)
        if opt is None:
            continue
        from imunoise.nav.aiding_sources import source

        path = opt
        if opt == "":
            name = inp.dataset.extra.get(o.key) if inp.dataset is not None else None
            if not name:
                raise ModelError(f"{o.flag} without a file needs --data with a dataset.json naming '{o.key}'; give "
                                 f"{o.flag} FILE")
            path = str(inp.dataset.root / name)
        src = source(o.key)
        e = src.read(path, imu_t=inp.imu.t, gnss=inp.gnss, option=o.flag, topic=getattr(args, f"{o.key}_topic", None))
        if e.dropped:
            note = f"{o.flag} {path}: {e.dropped} rows with NaN dropped"
            log.warning("%s", note)
            inp.notes.append(note)
        out.append((src, e))
    return out


def stream_keys(args: argparse.Namespace) -> tuple[str, ...]:
    """The sources an experiment applies: each option given without FILE (the simulator simulates the stream from
    each drive's truth, a dataset its manifest's file); a FILE is refused (it would not match the drives)."""
    keys = []
    for o in OPTIONS:
        opt = getattr(args, o.key, None)
        if opt:
            raise ModelError(f"{o.flag} {opt}: an experiment takes {o.flag} without FILE (the simulator simulates it, "
                             f"--data reads the manifest's '{o.key}')")
        if opt is not None:
            keys.append(o.key)
    return tuple(keys)


def epoch_counts(status, epochs, windows) -> dict:
    """What became of every epoch of a run: dropped for a NaN, outside the run, used, rejected by the χ² gate,
    forced in after consecutive rejections; the same inside the outage ``windows`` (start, duration) [s]."""
    import numpy as np

    st = np.asarray(status)

    def count(m) -> dict:
        return {"used": int(np.sum(st[m] == 1)), "rejected": int(np.sum(st[m] == 0)), "forced": int(np.sum(st[m] == 2))}

    inside = np.zeros(epochs.t.size, dtype=bool)
    for s, length in windows:
        inside |= (epochs.t >= s) & (epochs.t < s + length)
    return {"fixes": int(epochs.t.size + epochs.dropped), "dropped_nan": int(epochs.dropped),
            "outside_run": int(np.sum(st < 0)), **count(np.ones(epochs.t.size, dtype=bool)),
            "in_outages": count(inside)}


def aiding_metrics(status: dict, aiding: list[tuple[Any, Any]], windows) -> dict:
    """metrics.json entries of the sources of a run: ``{key: {"file": ..., counts}}`` from the status per kind."""
    return {src.key: {"file": e.source, **epoch_counts(status[src.kind], e, windows)} for src, e in aiding}
