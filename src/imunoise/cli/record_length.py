"""How long to record, in `fit` and `calibrate`: per axis the 95 % interval of N and K and the horizon at the
record's length, the length a ``--target`` precision (or a ``--target-horizon``) needs, one line each on stdout,
the same in the model file / calibration.json and a plot of half-width against record length in report.html
(:mod:`imunoise.noise.fitting.record_length`; docs/guide/theory.rst, 'Record length')."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from imunoise.errors import ImunoiseError, ModelError

__all__ = ["add_target", "check_target", "duration_text", "axis_record_length", "fit_record_lengths",
           "calibrate_record_lengths", "record_length_figure"]

DEFAULT_TARGET_PCT = 10.0
_CURVE_FACTORS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1, 2, 4, 8, 16, 32, 64)


def add_target(p: argparse.ArgumentParser) -> None:
    """``--target`` and ``--target-horizon``."""
    p.add_argument("--target", type=float, default=DEFAULT_TARGET_PCT, metavar="PCT",
                   help="how long to record: the record length at which N's and K's 95 %% intervals are within "
                   f"±PCT %% (default {DEFAULT_TARGET_PCT:g})")
    p.add_argument("--target-horizon", type=float, metavar="S",
                   help="how long to record: the record (calibrate: the longest stop) whose horizon reaches S "
                   "seconds of averaging time (e.g. your longest GNSS outage)")


def check_target(args: argparse.Namespace) -> None:
    """One-line errors (exit 2) before any work for a ``--target`` or ``--target-horizon`` that is not positive."""
    t = getattr(args, "target", DEFAULT_TARGET_PCT)
    if not (math.isfinite(t) and t > 0):
        raise ModelError(f"--target must be a positive percentage (e.g. --target 10 for ±10 %), got {t}")
    h = getattr(args, "target_horizon", None)
    if h is not None and not (math.isfinite(h) and h > 0):
        raise ModelError(f"--target-horizon must be a positive time in seconds, got {h}")


def duration_text(s: float) -> str:
    """A duration with its unit: "45 s", "12 min", "2.8 h", "3.1 d"; "never" for inf, "—" for NaN."""
    if math.isinf(s):
        return "never (beyond 10⁴× the record)"
    if not math.isfinite(s):
        return "—"
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 3 * 86400:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} d"


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def axis_record_length(fit: Any, target_pct: float, target_horizon_s: float | None = None, *,
                       pooled: bool = False, record_s: float | None = None) -> dict[str, Any]:
    """The JSON block of one axis: the prediction at the record's length, the lengths the targets need and the
    curve of half-widths against length (factors 1/16 … 64 of the record)."""
    from imunoise.export.record_length import LengthPredictor, length_for_horizon

    pr = LengthPredictor(fit, pooled=pooled, record_s=record_s)
    rec = pr.record_s
    here = pr.predict(rec)
    need = {k: pr.length_for(k, target_pct) for k in ("N", "K")}
    curve: dict[str, list] = {"length_s": [], "N_pct": [], "K_pct": [], "horizon_s": []}
    for c in _CURVE_FACTORS:
        try:
            p = pr.predict(rec * c)
        except ImunoiseError:  # too short to hold a wavelet level
            continue
        for key, v in (("length_s", p.length_s), ("N_pct", p.pct("N")), ("K_pct", p.pct("K")),
                       ("horizon_s", p.horizon_s)):
            curve[key].append(_finite(v))
    out = {
        "record_s": rec, "pooled_stops": pooled, "level": 0.95,
        "quantities": "the exported pair of the model (before the cap at the data's Allan bound)",
        "at_record": {"N": _finite(here.N), "N_ci": [_finite(v) for v in here.N_ci], "N_pct": _finite(here.pct("N")),
                      "K": _finite(here.K), "K_ci": [_finite(v) for v in here.K_ci], "K_pct": _finite(here.pct("K")),
                      "horizon_s": _finite(here.horizon_s)},
        "target_pct": target_pct,
        "length_for_target_s": {k: (None if math.isnan(v) else ("inf" if math.isinf(v) else v))
                                for k, v in need.items()},
        "curve": curve,
    }
    if target_horizon_s is not None:
        out["target_horizon_s"] = float(target_horizon_s)
        out["length_for_horizon_s"] = length_for_horizon(fit, target_horizon_s)
    return out


def _need(d: dict[str, Any], k: str) -> float:
    v = d["length_for_target_s"][k]
    return math.nan if v is None else (math.inf if v == "inf" else float(v))


def line(axis: str, d: dict[str, Any]) -> str:
    """The summary line of one axis: "gyro_x: record 2.8 h: N ±1.2 %, K ±18 %, horizon 655 s; for ±10 %: …"."""
    a = d["at_record"]
    pct = {k: f"±{a[k + '_pct']:.2g} %" if a[k + "_pct"] is not None else "a bound (not identified)"
           for k in ("N", "K")}
    what = "static (pooled stops)" if d["pooled_stops"] else "record"
    more = " of stops like these" if d["pooled_stops"] else ""
    need = [f"{k} {duration_text(_need(d, k))}" for k in ("N", "K") if a[k + "_pct"] is not None]
    s = (f"{axis}: {what} {duration_text(d['record_s'])}: N {pct['N']}, K {pct['K']}, horizon "
         f"{duration_text(a['horizon_s'] or math.nan)}; for ±{d['target_pct']:g} %: "
         + (", ".join(need) + more if need else "no interval to narrow"))
    if "target_horizon_s" in d:
        who = "a stop of" if d["pooled_stops"] else "a record of"
        s += f"; horizon {duration_text(d['target_horizon_s'])} needs {who} {duration_text(d['length_for_horizon_s'])}"
    return s


def fit_record_lengths(fits: dict[str, Any], args: argparse.Namespace) -> None:
    """`fit`: per axis the block into ``fit.extra["record_length"]`` (the model file) and its line (stdout)."""
    for axis, fit in fits.items():
        try:
            d = axis_record_length(fit, args.target, args.target_horizon)
        except ImunoiseError as exc:
            print(f"{axis}: how long to record: not available ({exc})", file=sys.stderr)
            continue
        fit.extra["record_length"] = d
        print(line(axis, d))


def calibrate_record_lengths(res: Any, args: argparse.Namespace) -> dict[str, Any]:
    """`calibrate`: per axis the block for pooled stops of ``res.static_s`` seconds, into
    ``res.model.source["record_length"]`` (imu_model.json) and returned (calibration.json); lines on stdout."""
    out = {}
    for axis, fit in res.fits.items():
        try:
            out[axis] = axis_record_length(fit, args.target, args.target_horizon, pooled=True,
                                           record_s=float(res.static_s))
        except ImunoiseError as exc:
            print(f"{axis}: how long to record: not available ({exc})", file=sys.stderr)
            continue
        print(line(axis, out[axis]))
    res.model.source["record_length"] = out
    return out


def record_length_figure(rep: Any, blocks: dict[str, dict[str, Any]], out: Path) -> None:
    """report.html: the half-width of N's and K's 95 % interval against record length, one panel per sensor."""
    if not blocks:
        return
    rep.heading("How long to record")
    rep.log([line(axis, d) for axis, d in blocks.items()])
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imunoise.io.atomic import atomic_savefig

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained", sharey=True)
    for i, (axis, d) in enumerate(blocks.items()):
        ax = axes[0 if axis.startswith("gyro") else 1]
        c = d["curve"]
        h = [x / 3600 for x in c["length_s"]]
        for k, style in (("N", "--"), ("K", "-")):
            y = [v if v is not None else math.nan for v in c[f"{k}_pct"]]
            if all(math.isnan(v) for v in y):  # K a bound: nothing to draw
                continue
            ax.loglog(h, y, style, color=f"C{i % 10}", label=f"{axis} {k}")
    for ax, name in zip(axes, ("gyro", "accel")):
        t = next(iter(blocks.values()))["target_pct"]
        ax.axhline(t, color="0.3", lw=0.8, ls=":")
        ax.axvline(next(iter(blocks.values()))["record_s"] / 3600, color="0.5", lw=0.8)
        ax.set_xlabel("static record length [h]")
        ax.set_title(f"{name}: ±{t:g} % dotted, this record's length solid grey")
        ax.legend(fontsize=7, ncol=2)
    axes[0].set_ylabel("95 % interval half-width [%]")
    path = out / "record_length.png"
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)
    rep.figure(path, "How long to record: N (dashed) and K (solid) interval half-width against the static time, "
               "predicted from the fitted model (docs/guide/theory.rst, 'Record length')")
