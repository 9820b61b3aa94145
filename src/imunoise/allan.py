"""Allan-variance baseline: automated IEEE Std 952/1293 reading of the overlapping AV (SPEC §6).

What practitioners do, made reproducible. The overlapping Allan variance at averaging time τ = mΔt is

    AVAR(m) = Σ_k (ȳ_{k+m}(m) − ȳ_k(m))² / (2(N − 2m + 1)),

computed from cumulative sums for any m (the dense log grid), and on the octave grid m = 2^{j−1} it is
exactly 2ν²_j of the Haar wavelet variance (SPEC §1), so it comes from :func:`imunoise.wv.wavelet_variance`.

Reading (Allan deviation AD = √AVAR, τ in seconds, data unit u):

=====  ======  ===========================  ======================================
term   slope   line                         read at
=====  ======  ===========================  ======================================
Q      −1      AD = √3·Q/τ                  the −1 region (only if present)
N      −½      AD = N/√τ                    the −½ line at τ = 1 s
B      0       AD_min = 0.6643·B            the lowest point of the flat region (else an
                                            interior minimum), T_BI = its τ
K      +½      AD = K·√(τ/3)                the +½ line at τ = 3 s
R      +1      AD = R·τ/√2                  the +1 region (only if present)
=====  ======  ===========================  ======================================

Regions are found automatically: the local log-log slope at each grid point is the least-squares slope
over a window of ±``window_octaves`` octaves; a region is a maximal run of reliable points (at least
``min_dof`` equivalent degrees of freedom) whose slope is within ``slope_tol`` of the line's slope and
that spans at least ``min_span_decades``. Each line's coefficient is the η-weighted least-squares fit of
log AD with the slope fixed (η = equivalent degrees of freedom, Var(log AD) ≈ 1/(2η)). For N, the region
containing τ = 1 s is preferred, else the longest. The regions are part of the result and drawn on the
plot, so a person can check them.

Equivalent filter model (paper Tables 2–3): WN + RW + one first-order Gauss–Markov for the bias
instability, plus QN and DR when their slopes exist. The GM takes the common reading σ_GM = B and
T_c = T_BI. Per-sample parameters at f = 1/Δt: σ²_WN = N²f, γ² = K²/f, Q² = (Qf)², ω = R/f,
φ = exp(−1/(T_c f)), σ²_AR1 = B²(1 − φ²).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from imunoise.errors import DataError, FitError
from imunoise.fitting.problem import prepare
from imunoise.fitting.result import GMWMFit
from imunoise.model import Model
from imunoise.processes import AR1, DR, QN, RW, WN
from imunoise.wv import WaveletVariance, scale_runs, wavelet_variance

__all__ = [
    "AllanVariance",
    "AllanLine",
    "AllanReading",
    "allan_variance",
    "read_allan",
    "reading_model",
    "allan_fit",
    "curve_from_fit",
    "data_curve",
    "curve_to_dict",
    "plot_allan",
    "BI_FACTOR",
    "MIN_DOF",
    "reliable",
    "rw_bound",
]

BI_FACTOR = 0.6643  # AD at the flicker floor = sqrt(2 ln2 / π)·B
LINES = {"Q": -1.0, "N": -0.5, "B": 0.0, "K": 0.5, "R": 1.0}
#: Equivalent degrees of freedom an Allan point needs to be read (SPEC §3, η = max(M/(2m), 1)); the one
#: definition of a "reliable" point, shared by the reading and the data's bound on K (:func:`rw_bound`).
MIN_DOF = 3.0


@dataclass(frozen=True)
class AllanVariance:
    """Overlapping Allan variance on a grid of averaging times (s), with η3 chi-square CIs."""

    tau: np.ndarray  # averaging time, s
    avar: np.ndarray
    dof: np.ndarray  # equivalent degrees of freedom η = max(n_terms / (2m), 1)
    ci_low: np.ndarray
    ci_high: np.ndarray
    freq: float
    grid: str  # "octave" or "dense"

    @property
    def adev(self) -> np.ndarray:
        return np.sqrt(self.avar)


def _chi2_ci(avar: np.ndarray, eta: np.ndarray, alpha: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    from scipy.special import gammaincinv

    lo = eta * avar / (2.0 * gammaincinv(eta / 2.0, 1.0 - alpha / 2.0))
    hi = eta * avar / (2.0 * gammaincinv(eta / 2.0, alpha / 2.0))
    return lo, hi


@njit(cache=True)
def _avar_sums(c, ms):  # pragma: no cover - compiled
    # Σ_k (c[k+2m] − 2c[k+m] + c[k])² and the number of terms, per m; c = cumulative sum with c[0] = 0
    n = c.shape[0] - 1
    tot = np.zeros(ms.shape[0])
    cnt = np.zeros(ms.shape[0])
    for i in range(ms.shape[0]):
        m = ms[i]
        if n < 2 * m:
            continue
        s = 0.0
        for k in range(n - 2 * m + 1):
            d = c[k + 2 * m] - 2.0 * c[k + m] + c[k]
            s += d * d
        tot[i] = s
        cnt[i] = n - 2 * m + 1
    return tot, cnt


def _segments(data: Any) -> list[np.ndarray]:
    segs = data if isinstance(data, (list, tuple)) else [data]
    out = []
    for s in segs:
        x = np.asarray(s, dtype=float).reshape(-1)
        if not np.all(np.isfinite(x)):
            raise DataError("the data contain NaN or Inf; remove or interpolate them before the Allan variance")
        out.append(x - x.mean() if x.size else x)
    return out


def allan_variance(
    data: Any,
    *,
    freq: float = 1.0,
    grid: str = "octave",
    points_per_decade: int = 10,
    wv: WaveletVariance | None = None,
) -> AllanVariance:
    """Overlapping AVAR of a series or list of segments (pooled, never across a junction).

    ``grid="octave"``: m = 2^{j−1} via the identity AVAR = 2ν²_j (a ready ``wv`` may be passed);
    ``grid="dense"``: m on a log grid with ``points_per_decade`` points, from cumulative sums.
    """
    if not freq > 0:
        raise DataError(f"sampling frequency must be > 0 Hz, got {freq}")
    if grid == "octave":
        if wv is None:
            wv = wavelet_variance(data, freq=freq)
        tau, avar = wv.scales / 2.0 / freq, 2.0 * wv.variance
        eta = np.maximum(wv.n_coefficients / wv.scales, 1.0)
        lo, hi = 2.0 * wv.ci_low, 2.0 * wv.ci_high
        return AllanVariance(tau, avar, eta, lo, hi, float(freq), "octave")
    if grid != "dense":
        raise DataError(f"unknown Allan grid {grid!r}; use 'octave' or 'dense'")
    segs = _segments(data)
    n_max = max(s.size for s in segs)
    if n_max < 4:
        raise DataError("need at least 4 samples for an Allan variance")
    m_all = np.unique(
        np.round(
            np.logspace(
                0,
                math.log10(n_max / 2),
                max(int(points_per_decade * math.log10(n_max / 2)), 1) + 1,
            )
        ).astype(np.int64)
    )
    tot = np.zeros(m_all.size)
    cnt = np.zeros(m_all.size)
    for seg in segs:
        t, c = _avar_sums(np.concatenate([[0.0], np.cumsum(seg)]), m_all)
        tot += t
        cnt += c
    keep = cnt > 0
    m_arr = m_all[keep].astype(float)
    avar = tot[keep] / (2.0 * m_arr * m_arr * cnt[keep])
    eta = np.maximum(cnt[keep] / (2.0 * m_arr), 1.0)
    lo, hi = _chi2_ci(avar, eta)
    return AllanVariance(m_arr / freq, avar, eta, lo, hi, float(freq), "dense")


@dataclass(frozen=True)
class AllanLine:
    """One IEEE line: its slope, the fitted coefficient, and the τ region (s) it was fitted on."""

    name: str
    slope: float
    value: float
    region: tuple[float, float]
    n_points: int


@dataclass
class AllanReading:
    """The automated IEEE reading; absent terms are NaN and missing from ``lines``."""

    N: float = math.nan  # u/√Hz
    K: float = math.nan  # u/s/√Hz
    B: float = math.nan  # u
    T_BI: float = math.nan  # s
    Q: float = math.nan  # u·s
    R: float = math.nan  # u/s
    lines: dict[str, AllanLine] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "N": self.N,
            "K": self.K,
            "B": self.B,
            "T_BI": self.T_BI,
            "Q": self.Q,
            "R": self.R,
            "regions_s": {k: list(v.region) for k, v in self.lines.items()},
            "points": {k: v.n_points for k, v in self.lines.items()},
        }


def _local_slopes(logt: np.ndarray, logad: np.ndarray, half_width: float) -> np.ndarray:
    out = np.full(logt.size, np.nan)
    for i in range(logt.size):
        sel = np.abs(logt - logt[i]) <= half_width + 1e-12
        if np.sum(sel) >= 2:
            x, y = logt[sel], logad[sel]
            xc = x - x.mean()
            out[i] = float(xc @ (y - y.mean()) / (xc @ xc))
    return out


def reliable(av: AllanVariance, min_dof: float = MIN_DOF) -> np.ndarray:
    """The points an Allan reading may use: η ≥ ``min_dof`` equivalent degrees of freedom and AVAR > 0."""
    return (av.dof >= min_dof) & (av.avar > 0)


def rw_bound(av: AllanVariance, min_dof: float = MIN_DOF) -> tuple[float, float]:
    """The data's Allan bound on a random-walk density: (K_data, τ at the minimum [s]).

    K_data = min_τ √(3·AVAR(τ)/τ) = min_τ AD(τ)·√(3/τ) over the :func:`reliable` points — the largest K
    whose +½ line AD = K·√(τ/3) stays at or below the Allan deviation wherever it can be read (an IEEE
    reading never draws a line above the curve). ``min_dof=0``: over every point, including the 1-dof
    tail. (NaN, NaN) when no point qualifies.
    """
    ok = reliable(av, min_dof)
    if not np.any(ok):
        return math.nan, math.nan
    k = np.sqrt(3.0 * av.avar[ok] / av.tau[ok])
    i = int(np.argmin(k))
    return float(k[i]), float(av.tau[ok][i])


def read_allan(
    av: AllanVariance,
    *,
    slope_tol: float = 0.15,
    window_octaves: float = 1.0,
    min_dof: float = MIN_DOF,
    min_span_decades: float = 0.3,
) -> AllanReading:
    """Automated IEEE 952/1293 reading of an Allan variance (module docstring).

    Parameters
    ----------
    av : AllanVariance
        The Allan variance (:func:`allan_variance`).
    slope_tol : float
        Largest departure of a local log-log slope from a line's slope (table above) inside its region.
    window_octaves : float
        Half-width of the window of the local slopes [octaves of τ].
    min_dof : float
        Points with fewer equivalent degrees of freedom are not used.
    min_span_decades : float
        Shortest span of a region [decades of τ].

    Returns
    -------
    AllanReading

    Raises
    ------
    FitError
        With fewer than 3 reliable points.
    """
    ok = reliable(av, min_dof)
    if np.sum(ok) < 3:
        raise FitError(f"only {int(np.sum(ok))} Allan points have ≥ {min_dof} degrees of freedom; need more data")
    tau, ad, eta = av.tau[ok], np.sqrt(av.avar[ok]), av.dof[ok]
    logt, logad = np.log10(tau), np.log10(ad)
    slopes = _local_slopes(logt, logad, window_octaves * math.log10(2.0))
    out = AllanReading()

    def fit_line(name: str, ref_tau: float | None, relax: bool = False) -> tuple[float, AllanLine] | None:
        s = LINES[name]
        runs: list[tuple[int, int]] = []
        # N and K are always read when the curve shows them at all: a second pass with twice the
        # tolerance catches a noisy line (the region is reported, so the reading can be checked)
        for tol in (slope_tol, 2.0 * slope_tol) if relax else (slope_tol,):
            mask = np.abs(slopes - s) <= tol
            runs = [(a, b) for a, b in scale_runs(mask) if logt[b] - logt[a] >= min_span_decades]
            if runs:
                break
        if not runs:
            return None
        if ref_tau is not None:
            lr = math.log10(ref_tau)
            inside = [r for r in runs if logt[r[0]] <= lr <= logt[r[1]]]
            run = inside[0] if inside else max(runs, key=lambda r: logt[r[1]] - logt[r[0]])
        else:
            run = max(runs, key=lambda r: logt[r[1]] - logt[r[0]])
        a, b = run
        w = eta[a : b + 1]
        c = float(np.sum(w * (logad[a : b + 1] - s * logt[a : b + 1])) / np.sum(w))  # log10 AD at τ = 1 s
        line = AllanLine(name, s, math.nan, (float(tau[a]), float(tau[b])), b - a + 1)
        return 10.0**c, line

    got = fit_line("N", 1.0, relax=True)
    if got:
        out.N = got[0]  # AD(1 s) on the −½ line
        out.lines["N"] = AllanLine("N", -0.5, out.N, got[1].region, got[1].n_points)
    got = fit_line("K", 3.0, relax=True)
    if got:
        out.K = got[0] * math.sqrt(3.0)  # AD(3 s) = K on the +½ line, AD(1 s)·√3
        out.lines["K"] = AllanLine("K", 0.5, out.K, got[1].region, got[1].n_points)
    got = fit_line("Q", None)
    if got:
        out.Q = got[0] / math.sqrt(3.0)  # AD = √3 Q/τ
        out.lines["Q"] = AllanLine("Q", -1.0, out.Q, got[1].region, got[1].n_points)
    got = fit_line("R", None)
    if got:
        out.R = got[0] * math.sqrt(2.0)  # AD = Rτ/√2
        out.lines["R"] = AllanLine("R", 1.0, out.R, got[1].region, got[1].n_points)
    # B: the lowest point of the flat (slope 0) region, else an interior global minimum
    flat = scale_runs(np.abs(slopes) <= slope_tol)
    i_min = int(np.argmin(ad))
    if flat:
        a, b = min(flat, key=lambda r: float(np.min(ad[r[0] : r[1] + 1])))
        i_min = a + int(np.argmin(ad[a : b + 1]))
    if flat or 0 < i_min < ad.size - 1:
        out.B = float(ad[i_min]) / BI_FACTOR
        out.T_BI = float(tau[i_min])
        out.lines["B"] = AllanLine("B", 0.0, out.B, (float(tau[i_min]), float(tau[i_min])), 1)
    return out


def reading_model(reading: AllanReading, freq: float) -> Model:
    """The equivalent per-sample filter model of a reading (module docstring)."""
    comps = []
    if math.isfinite(reading.B) and math.isfinite(reading.T_BI):
        phi = math.exp(-1.0 / (reading.T_BI * freq))
        comps.append(AR1(phi=phi, sigma2=reading.B**2 * (1.0 - phi * phi)))
    if math.isfinite(reading.N):
        comps.append(WN(sigma2=reading.N**2 * freq))
    if math.isfinite(reading.Q):
        comps.append(QN(q2=(reading.Q * freq) ** 2))
    if math.isfinite(reading.K):
        comps.append(RW(gamma2=reading.K**2 / freq))
    if math.isfinite(reading.R):
        comps.append(DR(omega=reading.R / freq))
    if not comps:
        raise FitError("the Allan variance shows none of the IEEE slopes; cannot build an AV model")
    return Model(comps)


def allan_fit(
    data: Any,
    *,
    freq: float = 1.0,
    unit: str = "u",
    grid: str = "dense",
    weights: str = "efficient",
    robust: bool = False,
    **reading_options: Any,
) -> GMWMFit:
    """AV baseline (SPEC §6): read the AV automatically and return the equivalent model as a fit.

    Parameters
    ----------
    data
        Array or list of segments.
    freq
        Sample rate in Hz (a number, else ``DataError``).
    unit
        Data unit named in the summary and the reading's units.
    grid
        AV cluster sizes: ``"dense"`` or ``"octave"`` (the WV's scales; :func:`allan_variance`).
    weights, robust
        Ω and WV estimator of the reported GMWM objective (as for :func:`imunoise.estimator.gmwm`).
    **reading_options
        Passed to :func:`read_allan`.

    Returns
    -------
    GMWMFit
        ``method="av"``; ``objective`` is the GMWM objective (Eq. 8) of the AV model on the data's WV
        and Ω (the same as :func:`imunoise.selection.select_model` uses), ``extra["allan"]`` holds the
        reading (N, K, B, T_BI, Q, R in continuous units and the τ regions), ``extra["allan_curve"]``
        the AV points.
    """
    t0 = time.perf_counter()
    problem = prepare(data, freq=freq, weights=weights, robust=robust)
    av = allan_variance(data, freq=freq, grid=grid, wv=problem.wv if grid == "octave" else None)
    reading = read_allan(av, **reading_options)
    model = reading_model(reading, freq)
    fit = GMWMFit.from_problem(
        problem,
        model,
        converged=True,
        unit=unit,
        method="av",
        extra={
            "allan": reading.to_dict(),
            "allan_units": {
                "N": f"{unit}/√Hz",
                "K": f"{unit}/s/√Hz",
                "B": unit,
                "T_BI": "s",
                "Q": f"{unit}·s",
                "R": f"{unit}/s",
            },
            "allan_curve": {"grid": av.grid, "tau_s": av.tau.tolist(), "avar": av.avar.tolist()},
        },
    )
    fit.elapsed_s = time.perf_counter() - t0
    return fit


def curve_to_dict(av: AllanVariance) -> dict[str, Any]:
    """JSON-ready points of an Allan curve (grid, τ [s], AVAR, η), read back by :func:`data_curve`."""
    return {"grid": av.grid, "tau_s": av.tau.tolist(), "avar": av.avar.tolist(), "dof": av.dof.tolist()}


def data_curve(fit: GMWMFit) -> AllanVariance | None:
    """The data's Allan curve a fit carries, densest first: ``extra["data_allan"]`` (the dense grid stored by
    :func:`imunoise.imu_model.fit_axis`), an AV fit's ``extra["allan_curve"]``, else the octave grid of the
    fit's own WV (AVAR = 2ν²_j at τ = 2^(j−1)Δt, SPEC §1; η = M_j/2^j). None when the fit has no WV."""
    c = fit.extra.get("data_allan")
    if c:
        tau, avar, eta = (np.asarray(c[k], dtype=float) for k in ("tau_s", "avar", "dof"))
        lo, hi = _chi2_ci(avar, eta)
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
    lo, hi = _chi2_ci(avar, eta)
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
    method's colour (:data:`imunoise.plots.METHOD_COLORS`, from a label starting with GMWM/AV/EM); the
    IEEE lines use colours none of the methods use.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imunoise.plots import finish_figure, method_color

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
