"""Which detected stops the online engine models: the navigation check of a static segment (``stop_guard``).

The static detector (docs/guide/theory.rst, 'Static detection') looks at the IMU alone: a stop is a window whose
horizontal specific force
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

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.detect import StaticSegment
from imunoise.online.engine_state import EngineState

log = logging.getLogger("imunoise.online.navigator")

__all__ = ["StopGuard", "StopVerdict", "stop_verdict"]


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


class StopGuard:
    """The online engine's stop guard (``stop_guard="nav"``): the navigation rows of the current raw static run and
    the verdict on each segment the detector completes (:func:`stop_verdict`).

    Reads ``state.t_aided`` and ``state.sample_t``, writes the ``stop_rejected`` events; ``rejected_segments``:
    the parts of detected segments it dropped so far."""

    def __init__(self, config: Any, state: EngineState, rate: float):
        self.config = config
        self.state = state
        self.rate = rate
        self.rejected_segments: list[StaticSegment] = []
        # navigation solution at each sample of the current raw static run (rows: speed, σ_h, aided, NIS), in a
        # growing array (a 2 h static record would be 720k rows); run_i0 = absolute index of the run's first sample
        self.run_nav = np.empty((1024, 4))
        self.run_len = 0
        self.run_i0 = 0

    def new_run(self, i0: int) -> None:
        """A new raw static run starts at sample ``i0``."""
        self.run_len = 0
        self.run_i0 = i0

    def record(self, t: float, ekf: Any) -> None:
        """The navigation solution at this static sample, before any ZUPT (a ZUPT would make a false stop
        look still): horizontal speed, its σ from the (lazily propagated) covariance, whether a GNSS fix was
        used within ``stop_aided_s``, and with ``stop_chi2`` > 0 the zero-velocity NIS (3 dof). P is read as
        is, never flushed here, so the guard does not change the filter's numbers."""
        cfg = self.config
        sv = ekf.view
        v, P_vel = sv.vel, sv.P_vel
        nis = math.nan
        if cfg.stop_chi2 > 0:
            try:
                nis = float(v @ np.linalg.solve(P_vel + cfg.zupt_sigma_v**2 * np.eye(3), v))
            except np.linalg.LinAlgError:
                nis = math.inf
        self.row(math.hypot(v[0], v[1]), math.sqrt(max(P_vel[0, 0] + P_vel[1, 1], 0.0)),
                 float(t - self.state.t_aided <= cfg.stop_aided_s), nis)

    def row(self, speed: float, sigma: float, aided: float, nis: float) -> None:
        """One navigation row of the current run."""
        if self.run_len == self.run_nav.shape[0]:
            self.run_nav = np.concatenate([self.run_nav, np.empty_like(self.run_nav)])
        self.run_nav[self.run_len] = (speed, sigma, aided, nis)
        self.run_len += 1

    def rows(self, rows: np.ndarray) -> None:
        """:meth:`row` for each row of ``rows`` (k, 4), in order (a kernel span's static samples)."""
        need = self.run_len + rows.shape[0]
        while need > self.run_nav.shape[0]:
            self.run_nav = np.concatenate([self.run_nav, np.empty_like(self.run_nav)])
        self.run_nav[self.run_len:need] = rows
        self.run_len = need

    def guard(self, seg: StaticSegment, t_now: float, min_duration_s: float) -> list[StaticSegment]:
        """The pieces of a detected segment the navigation solution agrees are a stop (:func:`stop_verdict`;
        ``min_duration_s``: the detector's): ``[seg]`` when nothing contradicts it; otherwise a ``stop_rejected``
        event, the dropped pieces added to ``rejected_segments``, and the kept pieces (possibly none)."""
        cfg = self.config
        if cfg.stop_guard != "nav":
            return [seg]
        a, b = seg.i0 - self.run_i0, seg.i1 - self.run_i0
        if a < 0 or b > self.run_len:  # cannot happen: a segment lies inside the raw run that just ended
            log.warning("static segment %.2f–%.2f s outside the recorded run; not guarded", seg.t0, seg.t1)
            return [seg]
        rows = self.run_nav[a:b]
        v = stop_verdict(rows[:, 0], rows[:, 1], rows[:, 2] > 0, rows[:, 3], rate_hz=self.rate,
                         max_speed=cfg.stop_max_speed, sigma_k=cfg.stop_sigma_k, chi2=cfg.stop_chi2,
                         edge_s=cfg.stop_edge_s, min_duration_s=min_duration_s)
        if v.whole:
            return [seg]
        ts = self.state.sample_t

        def piece(p: int, q: int) -> StaticSegment:
            return StaticSegment(ts[seg.i0 + p], ts[seg.i0 + q - 1], seg.i0 + p, seg.i0 + q)

        kept = [piece(p, q) for p, q in v.keep]
        dropped = [piece(p, q) for p, q in v.drop]
        self.rejected_segments.extend(dropped)
        self.state.event("stop_rejected", t_now, t0=seg.t0, t1=seg.t1, duration_s=seg.duration, reason=v.reason,
                         max_speed_mps=v.max_speed_mps, threshold_mps=v.threshold_mps, max_nis=v.max_nis,
                         rejected_s=float(sum(d.i1 - d.i0 for d in dropped) / self.rate),
                         kept=[(k.t0, k.t1) for k in kept])
        return kept
