"""Automated IEEE Std 952/1293 reading of the Allan deviation and the equivalent filter model
(docs/guide/theory.rst, 'Baselines').

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

from imunoise.errors import FitError
from imunoise.noise.allan.variance import AllanVariance, allan_variance
from imunoise.noise.fitting.problem import prepare
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, DR, QN, RW, WN
from imunoise.noise.wv import scale_runs
from imunoise.units import required_freq

__all__ = [
    "BI_FACTOR",
    "LINES",
    "MIN_DOF",
    "AllanLine",
    "AllanReading",
    "allan_fit",
    "read_allan",
    "reading_model",
    "reliable",
    "rw_bound",
]

BI_FACTOR = 0.6643  # AD at the flicker floor = sqrt(2 ln2 / π)·B
LINES = {"Q": -1.0, "N": -0.5, "B": 0.0, "K": 0.5, "R": 1.0}
#: Equivalent degrees of freedom an Allan point needs to be read (docs/guide/theory.rst, 'Wavelet variance', η =
# max(M/(2m), 1)); the one
#: definition of a "reliable" point, shared by the reading and the data's bound on K (:func:`rw_bound`).
MIN_DOF = 3.0


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
    freq: float | None = None,
    unit: str = "u",
    grid: str = "dense",
    weights: str = "efficient",
    robust: bool = False,
    **reading_options: Any,
) -> GMWMFit:
    """AV baseline (docs/guide/theory.rst, 'Baselines'): read the AV automatically and return the equivalent model as a
    fit.

    Parameters
    ----------
    data
        Array or list of segments.
    freq
        Sample rate in Hz, required (keyword; none is assumed; a number, else ``DataError``).
    unit
        Data unit named in the summary and the reading's units.
    grid
        AV cluster sizes: ``"dense"`` or ``"octave"`` (the WV's scales; :func:`allan_variance`).
    weights, robust
        Ω and WV estimator of the reported GMWM objective (as for :func:`imunoise.noise.estimator.gmwm`).
    **reading_options
        Passed to :func:`read_allan`.

    Returns
    -------
    GMWMFit
        ``method="av"``; ``objective`` is the GMWM objective (Eq. 8) of the AV model on the data's WV
        and Ω (the same as :func:`imunoise.noise.selection.select_model` uses), ``extra["allan"]`` holds the
        reading (N, K, B, T_BI, Q, R in continuous units and the τ regions), ``extra["allan_curve"]``
        the AV points.
    """
    t0 = time.perf_counter()
    freq = required_freq(freq, "allan_fit")
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

