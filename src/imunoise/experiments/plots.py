"""Figures of the experiments (docs/guide/theory.rst, 'Experiments'): detection (paper Fig. 8), trajectories and errors
(Figs. 10–11), event timeline, WV fits per axis (Figs. 5/9), AV plots, Monte Carlo distributions. Matplotlib, Agg."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from imunoise.experiments.common import METHOD_LABELS  # noqa: E402
from imunoise.imu import AXES  # noqa: E402

__all__ = ["detection_figure", "trajectory_figure", "error_figure", "timeline_figure", "wv_figures",
           "av_figures", "mc_figure", "paired_figure", "ratio_ticks"]

_COLORS = {"plain": "tab:gray", "plain_zupt": "tab:brown", "av": "tab:orange", "em": "tab:purple",
           "gmwm": "tab:blue", "gmwm_wvic": "tab:cyan", "gmwm_raw": "tab:olive", "gmwm_zupt": "tab:green",
           "gmwm_top2": "tab:red", "gmwm_top3": "tab:olive", "static_var": "tab:brown",
           "static_var_hindsight": "tab:brown", "av_online": "goldenrod", "em_online": "orchid",
           "gmwm_hindsight": "navy", "oracle": "black", "gmwm_dyn": "deepskyblue", "adaptive": "darkorange"}


def _color(name: str) -> str:
    return _COLORS.get(name.removesuffix("+sf"), "tab:red")


def detection_figure(t: np.ndarray, det: Any, path: Path, *, ref=None, static_truth=None) -> Path:
    """Eq. 9 statistic (accel x, y), adaptive threshold, detected static epochs, reference speed."""
    fig, axs = plt.subplots(2, 1, figsize=(12, 6), sharex=True, gridspec_kw={"height_ratios": [2, 1]},
                            layout="constrained")
    x = t - t[0]
    ax = axs[0]
    ax.semilogy(x, det.statistic[:, 0], lw=0.6, label="T (accel x)")
    ax.semilogy(x, det.statistic[:, 1], lw=0.6, label="T (accel y)")
    ax.semilogy(x, det.threshold, lw=1.0, color="darkred", label="adaptive threshold λ")
    for k, s in enumerate(det.segments):
        ax.axvspan(s.t0 - t[0], s.t1 - t[0], color="tab:red", alpha=0.15, label="detected static" if k == 0 else None)
    ax.set_ylabel("moving std [m/s²]")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    ax.grid(alpha=0.3, which="both")
    ax.set_title("static detection (paper Eq. 9 with the adaptive threshold of "
                 "docs/guide/theory.rst, 'Static detection')")
    ax = axs[1]
    if ref is not None:
        sp = np.linalg.norm(ref.vel_ned, axis=1)
        ax.plot(ref.t - t[0], sp, color="k", lw=0.8, label="reference speed")
    if static_truth is not None:
        ax.fill_between(x, 0, np.where(static_truth, 1.0, 0.0), color="tab:green", alpha=0.2, step="mid",
                        label="reference static")
    ax.plot(x, np.where(det.static, 0.5, np.nan), color="tab:red", lw=3, label="detected static")
    ax.set_ylabel("speed [m/s]")
    ax.set_xlabel(f"time since {t[0]:.1f} s [s]")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def trajectory_figure(sc: Any, objects: dict[str, dict], path: Path, methods: Sequence[str],
                      labels: dict | None = None) -> Path:
    """Reference (antenna) with the outage windows and every method's trajectory inside the windows."""
    from imunoise.nav.earth import llh_to_ned

    origin = sc.ref.llh[0]
    rn = llh_to_ned(sc.ref.llh, origin)
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(rn[:, 1], rn[:, 0], "-", color="0.7", lw=3, label="reference")
    for k, (s, d) in enumerate(sc.windows):
        m = (sc.ref.t >= s) & (sc.ref.t < s + d)
        ax.plot(rn[m, 1], rn[m, 0], "-", color="gold", lw=5, alpha=0.6, label="outage windows" if k == 0 else None)
    for name in methods:
        if name not in objects or "_runs" not in objects[name]:
            continue
        first = True
        for w, r, _ in objects[name]["_runs"]:
            wins = [w] if w is not None else sc.windows
            ant = r.antenna_llh(sc.lever)
            for s, d in wins:
                m = (r.t >= s) & (r.t < s + d)
                e = llh_to_ned(ant[m], origin)
                ax.plot(e[:, 1], e[:, 0], "-", color=_color(name), lw=1.2,
                        label=(labels or METHOD_LABELS).get(name, name) if first else None)
                first = False
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("trajectories in the GNSS outages (one run per window)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def error_figure(sc: Any, objects: dict[str, dict], path: Path, methods: Sequence[str],
                 labels: dict | None = None) -> Path:
    """Horizontal error vs time: outage runs (top, log scale) and full-GNSS runs (ECEF X/Y/Z residuals)."""
    fig, axs = plt.subplots(4, 1, figsize=(11, 10), sharex=True, layout="constrained")
    t0 = sc.init.t
    for name in methods:
        if name not in objects:
            continue
        o = objects[name]
        for k, (w, _, e) in enumerate(o.get("_runs", [])):
            wins = [w] if w is not None else sc.windows
            for s, d in wins:
                m = (e.t >= s - 5) & (e.t < s + d)
                axs[0].semilogy(e.t[m] - t0, np.maximum(e.horizontal[m], 1e-3), color=_color(name), lw=1,
                                label=(labels or METHOD_LABELS).get(name, name)
                                if k == 0 and s == wins[0][0] else None)
        e = o.get("_err")
        if e is not None:
            for i, lab in enumerate("XYZ"):
                axs[1 + i].plot(e.t - t0, e.ecef[:, i], color=_color(name), lw=0.7)
                axs[1 + i].set_ylabel(f"ECEF {lab} error [m]")
    for s, d in sc.windows:  # only the outage panel: the full-GNSS runs below had GNSS throughout
        axs[0].axvspan(s - t0, s + d - t0, color="gold", alpha=0.15)
    axs[0].set_ylabel("horizontal error in outages [m]")
    # above the panel: inside, it covered the drift curves of the later windows
    if axs[0].get_legend_handles_labels()[0]:
        axs[0].legend(fontsize=7, ncol=3, loc="lower left", bbox_to_anchor=(0.0, 1.02), borderaxespad=0.0,
                      frameon=False)
    else:
        axs[0].text(0.5, 0.5, "no outage runs", transform=axs[0].transAxes, ha="center", va="center",
                    color="0.4")
    axs[1].set_title("full GNSS: position residuals (ECEF)", fontsize=9)
    axs[-1].set_xlabel(f"time since start {t0:.1f} s [s]")
    for ax in axs:
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def timeline_figure(full: Any, path: Path, t0: float) -> Path:
    """Static segments, angular-rate gate, model identification/refits (stop end → model in use)."""
    fig, ax = plt.subplots(figsize=(11, 3.0), layout="constrained")
    for k, s in enumerate(full.segments):
        ax.barh(2, s.t1 - s.t0, left=s.t0 - t0, height=0.6, color="tab:red", alpha=0.6,
                label="static segment" if k == 0 else None)
    if full.gate_open.size and full.sample_t.size == full.gate_open.size:
        tt, m = full.sample_t, full.gate_open
        ax.fill_between(tt - t0, 0.7, 1.3, where=m, color="tab:purple", alpha=0.5, step="mid", label="gate open")
    seen: set[str] = set()
    marks = []
    for u in full.updates:
        if u.t_effect is None:
            ax.plot(u.t_stop - t0, 0, "x", color="k", label=None if "failed" in seen else "no model (failed)")
            seen.add("failed")
            continue
        ax.annotate("", xy=(u.t_effect - t0, 0), xytext=(u.t_stop - t0, 0),
                    arrowprops={"arrowstyle": "->", "color": "tab:blue"})
        name = "identification" if u.kind == "identify" else "refit"
        ax.plot(u.t_effect - t0, 0, "o", color="tab:blue" if u.kind == "identify" else "tab:cyan",
                label=None if name in seen else name)
        seen.add(name)
        marks.append((u.t_effect - t0, f"{sum(u.elapsed_s):.2g} s"))
    ax.set_yticks([0, 1, 2], ["model", "gate", "static"])
    ax.set_ylim(-1.0, 2.5)
    ax.set_xlabel(f"time since {t0:.1f} s [s]")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    ax.grid(alpha=0.3, axis="x")
    ax.set_title("online timeline: stops → modelling → model in the filter (labels: compute time)")
    _stagger_labels(ax, marks, rows=(-0.38, -0.62, -0.86))  # last: measured on the final layout
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _stagger_labels(ax, marks: Sequence[tuple[float, str]], rows: Sequence[float], fontsize: int = 7) -> None:
    """Text labels under points at x, each on the first row where it does not touch its left neighbour.

    Widths are measured in display pixels on the figure's final layout (the layout engine runs first and is
    then frozen, so saving does not shrink the axes under the labels). When every row is taken, a row is
    added below at the same spacing and the y range grows to hold it: labels never print over each other.
    """
    if not marks:
        return
    fig = ax.figure
    ax.set_xlim(*ax.get_xlim())  # freeze autoscaling before measuring
    fig.canvas.draw()  # the layout engine places the axes (legend and titles included)
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine("none")  # keep that placement when saving
    renderer = fig.canvas.get_renderer()
    rows = list(rows)
    step = rows[1] - rows[0] if len(rows) > 1 else -0.24
    pad = 8.0  # px between neighbours on a row, so "0.07 s" and "0.07 s" read as two labels
    right = [-np.inf] * len(rows)  # right edge (px) of the last label on each row
    placed, height = [], 0.0
    for x, text in sorted(marks):
        t = ax.text(x, rows[0], text, fontsize=fontsize, ha="center", va="center")
        bb = t.get_window_extent(renderer)
        height = max(height, bb.height)
        row = next((i for i, r in enumerate(right) if bb.x0 - pad > r), None)
        if row is None:
            rows.append(rows[-1] + step)
            right.append(-np.inf)
            row = len(rows) - 1
        placed.append((t, row))
        right[row] = bb.x1
    lo, hi = ax.get_ylim()
    new_lo = min(lo, rows[-1] + 0.75 * step)
    if new_lo < lo:
        ax.set_ylim(new_lo, hi)
        # rows stay a text height apart in pixels: a taller figure (the layout is frozen, widths unchanged)
        need = (height + 2.0) * (hi - new_lo) / abs(step)
        have = ax.get_window_extent(renderer).height
        if have < need:
            fig.set_figheight(fig.get_figheight() * need / have)
    for t, row in placed:
        t.set_y(rows[row])


def wv_figures(fits: Sequence[Any], folder: Path, stem: str = "wv") -> list[Path]:
    """One WV figure per axis with the fitted model and a dashed curve per process."""
    from imunoise.noise.plots import plot_wv_fit

    out = []
    for a, f in enumerate(fits):
        if f is None:
            continue
        p = folder / f"{stem}_{AXES[a]}.png"
        plot_wv_fit(f, p, title=f"{AXES[a]}: {f.model}  (GOF {f.objective:.3g})")
        out.append(p)
    return out


def av_figures(av_fits: Sequence[Any], other: Sequence[Any] | None, folder: Path) -> Path:
    """Allan deviation of each axis with the AV model's and (optionally) the GMWM model's implied AD.

    One legend for the figure (the curves' meaning is the same in every panel); each panel's title names
    its two model structures, so no per-panel legend covers the data. Colours: the methods' colours of
    :data:`imunoise.noise.plots.METHOD_COLORS`.
    """
    from imunoise.noise.plots import METHOD_COLORS

    fig, axs = plt.subplots(2, 3, figsize=(14, 8.4), layout="constrained")
    for a, f in enumerate(av_fits):
        ax = axs[a // 3, a % 3]
        tau = f.wv.scales / 2.0 / f.freq
        ad = np.sqrt(2.0 * f.wv.variance)
        ax.fill_between(tau, np.sqrt(2 * f.wv.ci_low), np.sqrt(2 * f.wv.ci_high), color="0.85", label="95% CI")
        ax.loglog(tau, ad, "o-", color="k", ms=3, lw=1, label="overlapping AD (octave grid)")
        ax.loglog(tau, np.sqrt(2 * f.model.wv(f.wv.scales)), "-", color=METHOD_COLORS["av"], lw=1.8,
                  label="AV model")
        names = f"AV: {f.model}"
        if other is not None and other[a] is not None:
            g = other[a]
            ax.loglog(tau, np.sqrt(2 * g.model.wv(f.wv.scales)), "--", color=METHOD_COLORS["gmwm"], lw=1.5,
                      label="GMWM model")
            names += f"\nGMWM: {g.model}"
        ax.set_title(f"{AXES[a]}\n{names}", fontsize=8)
        ax.set_xlabel("τ [s]")
        ax.set_ylabel("AD [" + ("rad/s" if a < 3 else "m/s²") + "]")
        ax.grid(alpha=0.3, which="both")
    handles, labels = axs[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9, frameon=False)
    fig.suptitle("Allan deviation of the static data with the AV and GMWM models")
    p = folder / "allan.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    return p


def mc_figure(results: dict, path: Path, methods: Sequence[str]) -> Path:
    """Per-seed distributions of the mean outage-end drift and the horizontal RMS."""
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, key, lab in ((axs[0], "mean_outage_end_horizontal_m", "mean end-of-outage drift [m]"),
                         (axs[1], "horizontal_rms_m", "horizontal RMS, full GNSS [m]")):
        data = [[r[key] for r in results["per_seed"][m] if r.get(key) is not None] for m in methods]
        ax.boxplot(data, showmeans=True)
        ax.set_xticks(range(1, len(methods) + 1), methods, rotation=30, fontsize=8)
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle(f"Monte Carlo over {len(results['seeds'])} simulated drives")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# tick ladders for ratios on a log axis, densest first: plain numbers a reader can read off
_RATIO_LADDERS = (
    tuple(np.round(np.arange(0.80, 1.2501, 0.02), 2)),
    tuple(np.round(np.arange(0.50, 2.0001, 0.05), 2)),
    (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0),
    (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 7.0, 10.0, 20.0),
    tuple(float(m * 10.0**k) for k in range(-4, 4) for m in (1, 2, 5)),
)


def ratio_ticks(lo: float, hi: float, max_ticks: int = 9) -> list[float]:
    """Ticks for ratios in [lo, hi] on a log axis: the densest ladder of plain numbers that holds 1, a tick at or
    below ``lo`` and one at or above ``hi``, with at most ``max_ticks`` ticks (the coarsest ladder otherwise)."""
    lo, hi = min(lo, 0.99), max(hi, 1.01)
    for ladder in _RATIO_LADDERS:
        below = [v for v in ladder if v <= lo * (1 + 1e-9)]
        above = [v for v in ladder if v >= hi * (1 - 1e-9)]
        if not below or not above:
            continue
        ticks = [float(v) for v in ladder if below[-1] <= v <= above[0]]
        if len(ticks) <= max_ticks or ladder is _RATIO_LADDERS[-1]:
            return ticks
    return [10.0 ** np.floor(np.log10(lo)), 1.0, 10.0 ** np.ceil(np.log10(hi))]  # beyond 1e-4 … 1e3


def paired_figure(paired: Sequence[dict], path: Path, *, metric: str = "drift",
                  baselines: Sequence[str] = ("plain", "static_var")) -> Path:
    """Forest plot of the paired ratios (:func:`imunoise.experiments.dense.paired_list`): one panel per
    baseline, one row per (GNSS regime, method), the geometric-mean ratio with its 95 % CI on a log axis and the
    line of no effect at 1; a CI that excludes 1 is drawn solid, one that includes it hollow."""
    rows = [e for e in paired if e["metric"] == metric and e["baseline"] in baselines and e["method"] != "plain"
            and e["method"] != e["baseline"]]
    regimes = list(dict.fromkeys(e.get("gnss", "") for e in rows))
    methods = list(dict.fromkeys(e["method"] for e in rows))
    fig, axs = plt.subplots(1, len(baselines), figsize=(5.2 * len(baselines), 0.45 * len(regimes) * len(methods) + 1.6),
                            sharey=True, layout="constrained", squeeze=False)
    labels = [f"{m}  ({g})" for g in regimes for m in methods]
    y = np.arange(len(labels))[::-1]
    for ax, base in zip(axs[0], baselines, strict=True):
        by = {(e.get("gnss", ""), e["method"]): e for e in rows if e["baseline"] == base}
        for yi, (g, m) in zip(y, [(g, m) for g in regimes for m in methods], strict=True):
            e = by.get((g, m))
            if e is None:
                continue
            lo, hi = e["ci"]
            c = _color(m)
            ax.plot([lo, hi], [yi, yi], color=c, lw=2)
            ax.plot([e["ratio"]], [yi], "s" if m.endswith("+sf") else "o", ms=7, color=c,
                    mfc=c if e.get("significant") else "white")
        ax.axvline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        spans = [v for e in by.values() for v in e["ci"] if np.isfinite(v) and v > 0]
        ticks = ratio_ticks(min(spans, default=1.0), max(spans, default=1.0))
        # plain numbers (0.5, 0.7, 1, 1.5 …) from a tick below the lowest bound to one above the highest,
        # so every CI lies inside labelled ticks; matplotlib's log locator labels only powers of ten
        ax.xaxis.set_major_locator(matplotlib.ticker.FixedLocator(ticks))
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _p: f"{v:g}"))
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_xlim(ticks[0] / 1.03, ticks[-1] * 1.03)
        ax.tick_params(axis="x", labelsize=8)
        ax.set_xlabel(f"end-{metric} ratio vs {base} (geometric mean, 95 % CI)")
        ax.set_title(f"vs {base}  (< 1: less {metric})", fontsize=10)
        ax.grid(True, which="both", axis="x", alpha=0.3)
    axs[0][0].set_yticks(y, labels)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
