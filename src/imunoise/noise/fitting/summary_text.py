"""The words and units of a fit's summary (docs/guide/theory.rst, 'GMWM estimator'): units of the parameters in terms of
the data unit, the
text of a confidence interval, and the scales where a model leaves the WV's confidence band
(docs/guide/theory.rst, 'Wavelet variance')."""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import DataError
from imunoise.noise.processes import PROCESS_TYPES
from imunoise.noise.wv import WaveletVariance, scale_runs

__all__ = ["CONTINUOUS_UNITS", "PARAM_UNITS", "band_departures", "ci_text", "departures_text", "unit_text"]

# Units of each per-sample parameter and continuous quantity, in terms of the data unit "u": read from the
# registered processes (each process owns its parameters' units).
PARAM_UNITS = {
    n: u.replace("^2", "²") for cls in PROCESS_TYPES.values() for n, u in zip(cls.param_names, cls.param_units)
}
"""Unit of every parameter name of the registered processes, in terms of the data unit ``u``."""
CONTINUOUS_UNITS = {k: u for cls in PROCESS_TYPES.values() for k, u in cls.continuous_units.items()}
"""Unit of every continuous-time quantity of the registered processes (:meth:`Process.continuous` keys)."""


def unit_text(template: str, unit: str) -> str:
    """Put the data unit into a unit template: 'u²' with 'rad/s' gives '(rad/s)²', not 'rad/s²'.

    Parameters
    ----------
    template
        A unit written in terms of the data unit ``u`` (:data:`PARAM_UNITS`, :data:`CONTINUOUS_UNITS`).
    unit
        The data unit.

    Returns
    -------
    str
        The unit text (``"1"`` stays ``"1"``).
    """
    compound = any(ch in unit for ch in "/·* ")
    if compound:
        template = template.replace("u²", "(u)²").replace("u·", "(u)·")
    return template.replace("u", unit) if template != "1" else "1"


def ci_text(ci: tuple[float, float] | None, available: bool = True) -> str:
    """A confidence interval as a 29-character column of the summary table."""
    # three different statements: no CI was computed (AV/EM fits, singular Ω), the data do not
    # determine the parameter (infinite variance, see imunoise.noise.fitting.problem.param_cov), or they
    # barely do (> 6 decades wide)
    if not available:
        return f"{'no CI':^29}"
    if ci is None or not all(math.isfinite(c) for c in ci):
        return f"{'(not identified)':^29}"
    lo, hi = ci
    if lo > 0 and hi / lo > 1e6:
        return f"{'(CI wider than 10⁶×)':^29}"
    return f"[{lo:>12.5g}, {hi:>12.5g}]"


def band_departures(
    wv: WaveletVariance, theoretical: np.ndarray, *, min_levels: int = 2
) -> list[tuple[float, float]]:
    """Ranges of scales where a model's WV leaves the empirical WV's confidence band
    (docs/guide/theory.rst, 'Wavelet variance').

    Parameters
    ----------
    wv
        Empirical wavelet variance with its (1 − α) interval ``ci_low``/``ci_high``.
    theoretical
        The model's WV at ``wv.scales`` (e.g. :attr:`GMWMFit.theoretical_wv`).
    min_levels
        Shortest run of consecutive levels outside the band that is reported. Each level's interval
        misses the truth with probability α, so a single level outside is expected now and then from a
        right model (about once in 20 levels at α = 0.05); two adjacent ones rarely are.

    Returns
    -------
    list of (tau_lo_s, tau_hi_s)
        First and last scale τ_j = 2^j/f [s] of each run, finest first; empty when the fit stays inside.
    """
    nu = np.asarray(theoretical, dtype=float).reshape(-1)
    if nu.shape != wv.variance.shape:
        raise DataError(f"theoretical WV has {nu.size} levels, the empirical WV {wv.variance.size}")
    outside = ~((nu >= wv.ci_low) & (nu <= wv.ci_high))  # NaN counts as outside
    tau = wv.scales / wv.freq
    return [(float(tau[j]), float(tau[k])) for j, k in scale_runs(outside) if k - j + 1 >= min_levels]


def departures_text(ranges: list[tuple[float, float]]) -> str:
    """'0.02–0.04 s, 655 s' for :func:`band_departures` ranges (one number where a range is one level).

    Parameters
    ----------
    ranges
        Output of :func:`band_departures`.

    Returns
    -------
    str
        Comma-separated scale ranges in seconds.
    """
    return ", ".join(f"{a:.3g} s" if a == b else f"{a:.3g}–{b:.3g} s" for a, b in ranges)
