"""Allan curves of a fit: the data's curve stored with it, the model's curve, their JSON form and the plot
with the reading's lines and regions (docs/guide/theory.rst, 'Baselines')."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imunoise.noise.allan.reading import BI_FACTOR, AllanReading
from imunoise.noise.allan.variance import AllanVariance, allan_variance, chi2_ci
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.model import Model

__all__ = ["curve_from_fit", "curve_to_dict", "data_curve", "plot_allan"]


def curve_to_dict(av: AllanVariance) -> dict[str, Any]:
    """JSON-ready points of an Allan curve (grid, τ [s], AVAR, η), read back by :func:`data_curve`."""
    return {"grid": av.grid, "tau_s": av.tau.tolist(), "avar": av.avar.tolist(), "dof": av.dof.tolist()}


def data_curve(fit: GMWMFit) -> AllanVariance | None:
    """The data's Allan curve a fit carries, densest first: ``extra["data_allan"]`` (the dense grid stored by
    :func:`imunoise.noise.imu_model.fit_axis`), an AV fit's ``extra["allan_curve"]``, else the octave grid of the
    fit's own WV (AVAR = 2ν²_j at τ = 2^(j−1)Δt, docs/guide/theory.rst, 'Conventions'; η = M_j/2^j). None when the fit
    has no WV."""
    c = fit.extra.get("data_allan")
    if c:
        tau, avar, eta = (np.asarray(c[k], dtype=float) for k in ("tau_s", "avar", "dof"))
        lo, hi = chi2_ci(avar, eta)
        return AllanVariance(tau, avar, eta, lo, hi, float(fit.freq), str(c.get("grid", "dense")))
    if fit.extra.get("allan_curve"):
        return curve_from_fit(fit)
    if getattr(fit, "wv", None) is None or len(fit.wv) == 0:
        return None
    return allan_variance(None, freq=fit.freq, grid="octave", wv=fit.wv)


def curve_from_fit(fit: GMWMFit) -> AllanVariance:
    """The AV points stored in an AV fit (``extra["allan_curve"]``)."""
    c = fit.extra["allan_curve"]
    tau, avar = np.asarray(c["tau_s"]), np.asarray(c["avar"])
    m = tau * fit.freq
    n = int(fit.extra.get("data_span", {}).get("n_samples", 0)) or int(fit.wv.n_coefficients[0] + 1)
    eta = np.maximum((n - 2 * m + 1) / (2 * m), 1.0)
    lo, hi = chi2_ci(avar, eta)
    return AllanVariance(tau, avar, eta, lo, hi, fit.freq, c["grid"])


def plot_allan(
    av: AllanVariance,
    path: Any,
    *,
    reading: AllanReading | None = None,
    models: list[tuple[str, Model]] | None = None,
    unit: str = "u",
    title: str = "",
    colors: list[str] | None = None,
) -> Any:
    """Log-log Allan deviation with CI band, the fitted IEEE lines over their regions (shaded), and the
    AD implied by any models (AVAR = 2ν² evaluated on the octave grid).

    Legend: each line's coefficient with its unit; B is marked at its value (square at τ = T_BI) and
    joined to the AD minimum it is read from (AD_min = 0.6643·B). Model curves take ``colors`` or the
    method's colour (:data:`imunoise.noise.plots.METHOD_COLORS`, from a label starting with GMWM/AV/EM); the
    IEEE lines use colours none of the methods use.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imunoise.noise.plots import finish_figure, method_color

    fig, ax = plt.subplots(figsize=(9.6, 5.2), layout="constrained")
    ax.fill_between(av.tau, np.sqrt(av.ci_low), np.sqrt(av.ci_high), color="0.85", label="95% CI")
    ax.loglog(
        av.tau,
        av.adev,
        "o-" if av.grid == "octave" else ".-",
        color="k",
        ms=3,
        lw=1,
        label=f"overlapping AD ({av.grid} grid)",
    )
    # not blue/orange/purple: those are GMWM/AV/EM
    colors_ieee = {"Q": "tab:pink", "N": "tab:green", "B": "tab:olive", "K": "tab:red", "R": "tab:brown"}
    units = {"Q": f"{unit}·s", "N": f"{unit}/√Hz", "K": f"{unit}/s/√Hz", "R": f"{unit}/s"}
    slope_text = {-1.0: "−1", -0.5: "−½", 0.5: "+½", 1.0: "+1"}
    tt = np.geomspace(av.tau[0], av.tau[-1], 200)
    if reading is not None:
        for name, line in reading.lines.items():
            c = colors_ieee[name]
            if name == "B":
                t_bi, floor = line.region[0], BI_FACTOR * line.value
                ax.plot([t_bi, t_bi], [floor, line.value], ":", color=c, lw=1.2)
                ax.plot([t_bi], [floor], "o", color=c, mfc="none", ms=7, label="AD minimum = 0.6643·B")
                ax.plot([t_bi], [line.value], "s", color=c, ms=7,
                        label=f"B = {line.value:.3g} {unit} at T_BI = {t_bi:.3g} s")
                continue
            if name == "N":
                y = line.value / np.sqrt(tt)
            elif name == "K":
                y = line.value * np.sqrt(tt / 3.0)
            elif name == "Q":
                y = math.sqrt(3.0) * line.value / tt
            else:
                y = line.value * tt / math.sqrt(2.0)
            ax.loglog(tt, y, "--", color=c, lw=1.2,
                      label=f"{name} = {line.value:.3g} {units[name]} ({slope_text[line.slope]} line)")
            ax.axvspan(line.region[0], line.region[1], color=c, alpha=0.08)
    y_data = np.concatenate([np.sqrt(av.ci_low), np.sqrt(av.ci_high), av.adev])
    y_data = y_data[np.isfinite(y_data) & (y_data > 0)]
    for i, (label, model) in enumerate(models or []):
        m = np.unique(np.round(np.geomspace(1, av.tau[-1] * av.freq, 60)))
        scales = 2.0 * m
        ad = np.sqrt(2.0 * model.wv(scales))
        color = colors[i] if colors is not None else method_color(label, i)
        ax.loglog(m / av.freq, ad, "-", lw=1.8, color=color, label=label)
    if y_data.size:  # the data decide the range; lines and models far outside are named in a note
        ax.set_ylim(y_data.min() / 3.0, y_data.max() * 3.0)
    ax.set_xlim(av.tau[0] / 1.5, av.tau[-1] * 1.5)
    ax.set_xlabel("averaging time τ [s]")
    ax.set_ylabel(f"Allan deviation [{unit}]")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title or "Allan deviation with automated IEEE reading")
    return finish_figure(fig, ax, path)
