"""Figures people would rather look at than read: WV fits with per-process curves (paper Figs. 5/9)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

if TYPE_CHECKING:
    from imunoise.gmwm import GMWMFit
    from imunoise.wv import WaveletVariance

__all__ = ["plot_wv", "plot_wv_fit", "plot_wv_fits"]

_PROC_COLORS = {"WN": "tab:blue", "QN": "tab:purple", "RW": "tab:red", "DR": "tab:brown"}


def _wv_axes(ax, wv: WaveletVariance, unit: str, label: str = "empirical WV") -> np.ndarray:
    x = wv.scales / wv.freq
    ax.fill_between(x, wv.ci_low, wv.ci_high, color="0.8", alpha=0.8, label=f"{100 * (1 - wv.alpha):.0f}% CI")
    ax.loglog(x, wv.variance, "o-", color="k", ms=3.5, lw=1, label=label)
    ax.set_xlabel("scale τ [s]")
    from imunoise.gmwm import unit_text

    ax.set_ylabel(f"wavelet variance ν² [{unit_text('u²', unit)}]")
    ax.grid(True, which="both", alpha=0.3)
    return x


def plot_wv(wv: WaveletVariance, path: str | Path, *, unit: str = "u", title: str = "") -> Path:
    fig, ax = plt.subplots(figsize=(7, 5))
    _wv_axes(ax, wv, unit)
    ax.set_title(title or "Haar wavelet variance")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_wv_fit(fit: GMWMFit, path: str | Path, *, title: str = "") -> Path:
    """Empirical WV with CI band, fitted WV, and one dashed curve per process (x in seconds)."""
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    x = _wv_axes(ax, fit.wv, fit.unit)
    ax.loglog(
        x, fit.theoretical_wv, "-", color="tab:orange", lw=2.2, label=f"{fit.method.upper()}: {fit.model}"
    )
    ar_colors = plt.cm.Greens(np.linspace(0.5, 0.9, max(fit.model.n_ar1, 1)))
    i_ar = 0
    for name, curve in fit.model.component_wv(fit.wv.scales).items():
        if name.startswith("AR1"):
            color = ar_colors[i_ar]
            i_ar += 1
        else:
            color = _PROC_COLORS.get(name, "0.4")
        ax.loglog(x, curve, "--", color=color, lw=1.2, label=name)
    lo = max(np.min(fit.wv.ci_low[fit.wv.ci_low > 0]) / 30, 1e-300) if np.any(fit.wv.ci_low > 0) else None
    if lo:
        ax.set_ylim(bottom=lo)
    ax.set_title(title or f"GMWM fit at {fit.freq:g} Hz, GOF = {fit.objective:.4g}")
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_wv_fits(
    wv: WaveletVariance,
    fits: Sequence[tuple[str, np.ndarray]],
    path: str | Path,
    *,
    unit: str = "u",
    title: str = "",
) -> Path:
    """Empirical WV with several implied model WVs (label, curve) on top: selection and comparisons."""
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    x = _wv_axes(ax, wv, unit)
    colors = plt.cm.tab10(np.arange(len(fits)) % 10)
    for (label, curve), color in zip(fits, colors):
        ax.loglog(x, curve, "-", color=color, lw=1.8, label=label)
    ax.set_title(title or "Wavelet variance and model fits")
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
