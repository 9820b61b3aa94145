"""Figures people would rather look at than read: WV fits with per-process curves (paper Figs. 5/9).

Conventions shared by every figure of the package (WV, Allan, experiments):

* one colour per modelling method (:data:`METHOD_COLORS`: GMWM blue, AV orange, EM purple), and process
  and IEEE-line colours that differ from all of them;
* the legend sits outside the axes, so it never hides data;
* a curve that lies wholly outside the axes gets no legend entry; a note in the corner names it instead;
* a fitted WV that leaves the empirical WV's confidence band over consecutive scales
  (:func:`imunoise.noise.estimator.band_departures`) is flagged: a shaded span (single fit) or open markers on the
  curve (several fits), and the legend says where.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

if TYPE_CHECKING:
    from imunoise.noise.estimator import GMWMFit
    from imunoise.noise.wv import WaveletVariance

__all__ = ["plot_wv", "plot_wv_fit", "plot_wv_fits", "METHOD_COLORS", "method_color", "hide_offscale", "finish_figure"]

METHOD_COLORS = {"gmwm": "tab:blue", "av": "tab:orange", "em": "tab:purple"}
# per-process curves: none of the method colours (WN grey: it is the flat floor everyone knows)
_PROC_COLORS = {"WN": "0.45", "QN": "tab:pink", "RW": "tab:red", "DR": "tab:brown"}
_OTHER_COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:cyan", "tab:olive", "tab:gray", "tab:pink")
_BAND_COLOR = "#e8a0a0"
_WRAP = 38  # legend text width (characters)


def method_color(label: str, i: int = 0) -> str:
    """Colour of a curve labelled 'GMWM…', 'AV…', 'EM…' (the method's), else the i-th of a palette."""
    words = label.replace(":", " ").split()
    head = words[0].lower() if words else ""
    return METHOD_COLORS.get(head, _OTHER_COLORS[i % len(_OTHER_COLORS)])


def _wrap(text: str) -> str:
    # no line break inside "τ = 0.02–0.04 s" (textwrap only breaks at ASCII whitespace)
    text = re.sub(r"(\d) s\b", "\\1\u00a0s", text.replace("τ = ", "τ\u00a0=\u00a0"))
    return "\n".join(textwrap.wrap(text, _WRAP, subsequent_indent="  ", break_on_hyphens=False))


def hide_offscale(ax) -> list[str]:
    """Drop the legend entry of every labelled line with no point inside the axes' current limits.

    Returns the dropped labels with where they are ("WN (below)"); call after the limits are final.
    """
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    hidden = []
    for line in ax.get_lines():
        label = line.get_label()
        if label.startswith("_"):
            continue
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        ok = np.isfinite(x) & np.isfinite(y)
        inside = ok & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
        if inside.any():
            continue
        line.set_label("_" + label)
        where = "below" if ok.any() and np.all(y[ok] < y0) else "above" if ok.any() and np.all(y[ok] > y1) else "off"
        hidden.append(f"{label.split(':')[0]}\u00a0({where})")
    return hidden


def finish_figure(fig, ax, path: str | Path, *, dpi: int = 120, note: str = "") -> Path:
    """Legend outside on the right; below it, in the margin, a note naming the curves not in view; save."""
    hidden = hide_offscale(ax)
    lines = [note] if note else []
    if hidden:
        lines += ["not in view:", *textwrap.wrap(", ".join(hidden), 30)]
    if lines:
        ax.text(1.02, 0.0, "\n".join(lines), transform=ax.transAxes, ha="left", va="bottom", fontsize=7,
                color="0.35")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


def _wv_axes(ax, wv: WaveletVariance, unit: str, label: str = "empirical WV") -> np.ndarray:
    x = wv.scales / wv.freq
    ax.fill_between(x, wv.ci_low, wv.ci_high, color="0.8", alpha=0.8, label=f"{100 * (1 - wv.alpha):.0f}% CI")
    ax.loglog(x, wv.variance, "o-", color="k", ms=3.5, lw=1, label=label)
    ax.set_xlabel("scale τ [s]")
    from imunoise.noise.estimator import unit_text

    ax.set_ylabel(f"wavelet variance ν² [{unit_text('u²', unit)}]")
    ax.grid(True, which="both", alpha=0.3)
    return x


def _wv_limits(ax, wv: WaveletVariance, curves: Sequence[np.ndarray] = (), below: float = 30.0) -> None:
    """y range of the data and the fitted totals, with room below (factor ``below``) for process curves."""
    vals = [wv.ci_low, wv.ci_high, wv.variance, *curves]
    v = np.concatenate([np.asarray(c, dtype=float).ravel() for c in vals])
    v = v[np.isfinite(v) & (v > 0)]
    if v.size:
        ax.set_ylim(v.min() / below, v.max() * 3.0)
    x = wv.scales / wv.freq
    ax.set_xlim(x[0] / 1.5, x[-1] * 1.5)


def plot_wv(wv: WaveletVariance, path: str | Path, *, unit: str = "u", title: str = "") -> Path:
    """Empirical Haar WV with its confidence band (x in seconds)."""
    fig, ax = plt.subplots(figsize=(9.2, 5.2), layout="constrained")
    _wv_axes(ax, wv, unit)
    _wv_limits(ax, wv, below=3.0)
    ax.set_title(title or "Haar wavelet variance")
    return finish_figure(fig, ax, path)


def plot_wv_fit(fit: GMWMFit, path: str | Path, *, title: str = "",
                marks: Sequence[tuple[float, str]] = ()) -> Path:
    """Empirical WV with CI band, fitted WV, and one dashed curve per process (x in seconds).

    Scales where the fit leaves the band (:func:`imunoise.noise.estimator.band_departures`) are shaded and named in
    the legend; processes wholly outside the axes are named in a corner note instead of the legend.
    ``marks``: (scale τ [s], label) pairs drawn as vertical dotted lines, e.g. the data's horizon.
    """
    from imunoise.noise.estimator import band_departures, departures_text

    fig, ax = plt.subplots(figsize=(9.6, 5.2), layout="constrained")
    x = _wv_axes(ax, fit.wv, fit.unit)
    total = fit.theoretical_wv
    for k, (a, b) in enumerate(bad := band_departures(fit.wv, total)):
        pct = f"{100 * (1 - fit.wv.alpha):.0f}%"
        # half an octave either side, so a run of one or two levels is visible as a band
        ax.axvspan(a / np.sqrt(2.0), b * np.sqrt(2.0), color=_BAND_COLOR, alpha=0.35, lw=0,
                   label=_wrap(f"fit outside the {pct} band: τ = {departures_text(bad)}") if k == 0 else None)
    ax.loglog(x, total, "-", color=METHOD_COLORS.get(fit.method, "tab:blue"), lw=2.2,
              label=_wrap(f"{fit.method.upper()}: {fit.model}"))
    n_ar = max(fit.model.n_ar1, 1)
    ar_colors = plt.cm.Greens(np.linspace(0.45, 0.9, n_ar)) if n_ar > 1 else ["tab:green"]
    i_ar = 0
    for name, curve in fit.model.component_wv(fit.wv.scales).items():
        if name.startswith("AR1"):
            color = ar_colors[i_ar]
            i_ar += 1
        else:
            color = _PROC_COLORS.get(name, "0.4")
        ax.loglog(x, curve, "--", color=color, lw=1.2, label=name)
    for tau_s, label in marks:
        ax.axvline(tau_s, color="tab:purple", ls=":", lw=1.4, label=_wrap(label))
    _wv_limits(ax, fit.wv, [total])
    ax.set_title(title or f"{fit.method.upper()} fit at {fit.freq:g} Hz, GOF = {fit.objective:.4g}")
    return finish_figure(fig, ax, path)


def plot_wv_fits(
    wv: WaveletVariance,
    fits: Sequence[tuple[str, np.ndarray]],
    path: str | Path,
    *,
    unit: str = "u",
    title: str = "",
    colors: Sequence[str] | None = None,
) -> Path:
    """Empirical WV with several implied model WVs (label, curve) on top: selection and comparisons.

    ``colors`` default: the method's colour for labels starting with GMWM/AV/EM, else a palette. Levels
    where a curve leaves the band over consecutive scales get open markers, and its legend entry says where.
    """
    from imunoise.noise.estimator import band_departures, departures_text

    fig, ax = plt.subplots(figsize=(9.6, 5.2), layout="constrained")
    x = _wv_axes(ax, wv, unit)
    tau = wv.scales / wv.freq
    for i, (label, curve) in enumerate(fits):
        color = colors[i] if colors is not None else method_color(label, i)
        bad = band_departures(wv, curve)
        text = label + (f" — outside the band at τ = {departures_text(bad)}" if bad else "")
        mask = np.zeros(tau.size, dtype=bool)
        for a, b in bad:
            mask |= (tau >= a) & (tau <= b)
        ax.loglog(x, curve, "-", color=color, lw=1.8, marker="o", ms=6, mfc="none",
                  markevery=list(np.flatnonzero(mask)), label=_wrap(text))
    _wv_limits(ax, wv, below=3.0)
    ax.set_title(title or "Wavelet variance and model fits")
    flagged = any(band_departures(wv, c) for _, c in fits)
    return finish_figure(fig, ax, path, note=f"○ fit outside the {100 * (1 - wv.alpha):.0f}% band" if flagged else "")
