"""Which detected stops the online engine models: the navigation check of a static segment (``stop_guard``).

The static detector (SPEC §7) looks at the IMU alone: a stop is a window whose horizontal specific force
scatters less than λ. With a λ_0 learned on a noisy IMU (≈ 2σ of its noise at the first stop) the
vibration of a car cruising smoothly scatters as little, and the detector calls it static (simulator,
``"noisy"`` preset: epoch precision 0.5–0.6). Such a segment holds vehicle dynamics and vibration, not the
sensor's noise; pooled into the wavelet variance it made online GMWM worse than the plain filter. The
engine therefore accepts a detected stop only where the navigation solution agrees
(:func:`stop_verdict`):

* GNSS-aided samples (a fix used within ``stop_aided_s``): the filter's horizontal speed
  ‖(v_N, v_E)‖ must stay below ``max(stop_max_speed, stop_sigma_k·σ_h)``, σ_h = √(P_vN + P_vE) (so a
  filter that says it does not know its velocity is not taken as proof of motion). Aided, the velocity
  error of the filter is a few dm/s, a cruising car moves at metres per second: the test separates them
  with a wide margin.
* Unaided samples (inside a GNSS outage the INS velocity drifts and a true stop may look like motion): the
  zero-velocity innovation test NIS = vᵀ(P_vv + σ_z²I)⁻¹v ≤ ``stop_chi2`` (3 dof) when that option is on
  (> 0); otherwise they are not tested.
* The samples that contradict a stop, and every sample within ``stop_edge_s`` of one, are dropped; the rest
  of the segment is kept as separate pieces, each at least the detector's ``min_duration_s`` long. Why cut
  rather than reject whole: with a noisy IMU's learned λ_0 the detector's run often starts at a real stop and
  goes on into the smooth cruise after it (simulator, "noisy" preset: the 60 s static start plus 15 s of
  driving in one segment), and rejecting such a segment whole threw away nearly every real stop (recall
  0.87 → 0.00 on two drives). Why the margin: a car pulling away passes 1 m/s only after ≈ 0.5 s (1.8 m/s²)
  and the filter's velocity follows the GNSS with a lag, so the samples just before the first contradicting
  one are already moving.

Samples that are not tested (before the filter starts; in an outage without the χ² option) are kept: the
guard only removes what the navigation solution contradicts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["StopVerdict", "stop_verdict"]


@dataclass(frozen=True)
class StopVerdict:
    """Outcome of :func:`stop_verdict` for one segment of ``n`` samples.

    ``keep``: the half-open sample ranges [a, b), relative to the segment start, that are modelled (``[(0, n)]``
    when nothing contradicts the stop, ``[]`` when nothing is left); ``drop``: the ranges that are not (the
    complement); ``reason``: why samples were dropped (``""`` when none); ``max_speed_mps``: the largest tested
    horizontal speed (NaN when no sample was tested by speed) and ``threshold_mps`` the bound at that sample;
    ``max_nis``: the largest zero-velocity NIS of the unaided samples (NaN when none was tested);
    ``n_tested``/``n_bad``: tested and contradicting samples.
    """

    keep: list[tuple[int, int]]
    drop: list[tuple[int, int]]
    reason: str
    max_speed_mps: float
    threshold_mps: float
    max_nis: float
    n_tested: int
    n_bad: int

    @property
    def whole(self) -> bool:
        """Nothing dropped: the segment is modelled as detected."""
        return not self.drop


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open [a, b) ranges of the True runs of a boolean mask."""
    e = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2], strict=True)]


def stop_verdict(speed: np.ndarray, sigma: np.ndarray, aided: np.ndarray, nis: np.ndarray, *, rate_hz: float,
                 max_speed: float, sigma_k: float, chi2: float, edge_s: float, min_duration_s: float) -> StopVerdict:
    """Which samples of one detected segment the navigation solution agrees are a stop (module docstring).

    Parameters
    ----------
    speed, sigma : numpy.ndarray
        Per sample of the segment: the filter's horizontal speed ‖(v_N, v_E)‖ and its 1σ √(P_vN + P_vE)
        [m/s]; NaN before the filter started (such samples are not tested).
    aided : numpy.ndarray of bool
        Per sample: a GNSS fix was used within the aided horizon.
    nis : numpy.ndarray
        Per sample: NIS of the zero-velocity pseudo-measurement (NaN when not computed).
    rate_hz : float
        IMU rate [Hz] (converts ``edge_s`` and ``min_duration_s`` to samples).
    max_speed, sigma_k : float
        Speed bound max(``max_speed``, ``sigma_k``·σ) [m/s] of the aided samples.
    chi2 : float
        NIS bound of the unaided samples; ≤ 0: they are not tested.
    edge_s : float
        Samples within this time of a contradicting one are dropped too [s].
    min_duration_s : float
        Shortest piece kept [s] (the detector's own minimum; duration = (samples − 1)/rate as
        :attr:`StaticSegment.duration`).

    Returns
    -------
    StopVerdict
    """
    speed = np.asarray(speed, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    aided = np.asarray(aided, dtype=bool)
    nis = np.asarray(nis, dtype=float)
    n = speed.size
    limit = np.maximum(max_speed, sigma_k * np.nan_to_num(sigma, nan=0.0))
    tested_v = aided & np.isfinite(speed)
    tested_n = ~aided & np.isfinite(nis) if chi2 > 0 else np.zeros(n, dtype=bool)
    bad_v = tested_v & (speed > limit)
    # both tests must contradict without GNSS: the NIS alone rejected true stops of a drifting, overconfident
    # filter inside outages (a stop_max_speed floor as on the aided samples)
    bad_n = tested_n & (nis > chi2) & (speed > max_speed)
    bad = bad_v | bad_n
    if tested_v.any():
        j = int(np.argmax(np.where(tested_v, speed, -np.inf)))
        vmax, thr = float(speed[j]), float(limit[j])
    else:
        vmax = thr = math.nan
    nmax = float(np.max(nis[tested_n])) if tested_n.any() else math.nan
    n_tested, n_bad = int(np.sum(tested_v | tested_n)), int(bad.sum())
    if not n_bad:
        return StopVerdict([(0, n)] if n else [], [], "", vmax, thr, nmax, n_tested, n_bad)
    # drop every sample within edge_s of a contradicting one (a dilation of the bad mask)
    edge = int(round(edge_s * rate_hz))
    c = np.concatenate([[0], np.cumsum(bad)])
    idx = np.arange(n)
    near_bad = c[np.minimum(idx + edge + 1, n)] - c[np.maximum(idx - edge, 0)] > 0
    min_len = min_duration_s * rate_hz + 1.0
    keep = [(a, b) for a, b in _runs(~near_bad) if b - a >= min_len - 1e-9]
    kept = np.zeros(n, dtype=bool)
    for a, b in keep:
        kept[a:b] = True
    parts = []
    if bad_v.any():
        parts.append(f"speed up to {vmax:.2f} m/s > {thr:.2f} m/s while GNSS-aided")
    if bad_n.any():
        parts.append(f"zero-velocity NIS up to {nmax:.1f} > {chi2:g} without GNSS")
    return StopVerdict(keep, _runs(~kept), "; ".join(parts), vmax, thr, nmax, n_tested, n_bad)
