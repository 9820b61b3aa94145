"""Navigation errors against a reference and the ``metrics.json`` summary (docs/guide/theory.rst, 'Navigation filter',
paper Tables 1, 5).

Errors are taken at the reference epochs. The estimate at a reference epoch t_r is the first filter
epoch t_k ≥ t_r moved back along its velocity, r(t_r) = r(t_k) − v_k (t_k − t_r): after a GNSS update
at t_k this is the updated state (linear interpolation would mix in the pre-update epoch t_{k−1}).
NED errors are C_e^n(ref) (x_est − x_ref) in ECEF (exact), ECEF errors x_est − x_ref; horizontal
= √(N² + E²), vertical = ``|D|``. Outage drift = the error at the last reference epoch inside the window
(start ≤ t < start + duration).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.earth import llh_to_ecef, radii

__all__ = ["NavErrors", "nav_errors", "summarize", "outage_drift", "mean_end_drift", "section_rms", "rms"]


@dataclass(frozen=True)
class NavErrors:
    """Errors (estimate − reference) at the reference epochs ``t``: ``ned``, ``ecef``, ``vel`` (NED, m/s),
    ``att`` (roll, pitch, yaw, rad; NaN where the reference has no attitude)."""

    t: np.ndarray
    ned: np.ndarray
    ecef: np.ndarray
    vel: np.ndarray
    att: np.ndarray

    @property
    def horizontal(self) -> np.ndarray:
        return np.hypot(self.ned[:, 0], self.ned[:, 1])

    @property
    def vertical(self) -> np.ndarray:
        return np.abs(self.ned[:, 2])


def rms(x: np.ndarray, axis: int = 0) -> np.ndarray | float:
    """Root mean square ignoring NaN."""
    return np.sqrt(np.nanmean(np.square(x), axis=axis))


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def nav_errors(
    t: np.ndarray,
    llh: np.ndarray,
    vel_ned: np.ndarray,
    euler: np.ndarray | None,
    ref,
) -> NavErrors:
    """Errors of an estimated trajectory (t, llh, vel_ned, euler) at the epochs of ``ref`` it covers.

    ``ref`` has fields t, llh, vel_ned, euler (a :class:`imunoise.io.kfgins.Reference`).
    """
    t = np.asarray(t, dtype=float)
    llh = np.asarray(llh, dtype=float)
    vel = np.asarray(vel_ned, dtype=float)
    m = (ref.t >= t[0]) & (ref.t <= t[-1])
    if not np.any(m):
        raise DataError(
            f"reference ({ref.t[0]:.3f}..{ref.t[-1]:.3f}) does not overlap the estimate ({t[0]:.3f}..{t[-1]:.3f})"
        )
    tr = ref.t[m]
    k = np.minimum(np.searchsorted(t, tr, side="left"), t.size - 1)
    dt = t[k] - tr
    est = llh[k].copy()
    rm, rn = radii(est[:, 0])
    est[:, 0] -= vel[k, 0] * dt / (rm + est[:, 2])
    est[:, 1] -= vel[k, 1] * dt / ((rn + est[:, 2]) * np.cos(est[:, 0]))
    est[:, 2] += vel[k, 2] * dt
    d_ecef = llh_to_ecef(est) - llh_to_ecef(ref.llh[m])
    lat, lon = ref.llh[m, 0], ref.llh[m, 1]
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    ned = np.column_stack(
        [
            -sl * co * d_ecef[:, 0] - sl * so * d_ecef[:, 1] + cl * d_ecef[:, 2],
            -so * d_ecef[:, 0] + co * d_ecef[:, 1],
            -cl * co * d_ecef[:, 0] - cl * so * d_ecef[:, 1] - sl * d_ecef[:, 2],
        ]
    )
    dvel = vel[k] - ref.vel_ned[m]
    if euler is None:
        att = np.full((tr.size, 3), np.nan)
    else:
        att = _wrap(np.asarray(euler, dtype=float)[k] - ref.euler[m])
    return NavErrors(tr, ned, d_ecef, dvel, att)


def mean_end_drift(outages: Sequence[dict]) -> float | None:
    """Mean horizontal drift [m] at the end of the outages of :func:`outage_drift` that have one; None if none
    has (no reference epoch inside any window)."""
    ends = [o["end_horizontal_m"] for o in outages if o["end_horizontal_m"] is not None]
    return float(np.mean(ends)) if ends else None


def outage_drift(err: NavErrors, windows: Sequence[tuple[float, float]]) -> list[dict]:
    """Per window: error at its last reference epoch (end) and the maximum inside
    (docs/guide/theory.rst, 'Navigation filter' keys)."""
    out = []
    hz, vt = err.horizontal, err.vertical
    for start, dur in windows:
        m = np.flatnonzero((err.t >= start) & (err.t < start + dur))
        if m.size == 0:
            out.append(
                {
                    "start": float(start),
                    "duration": float(dur),
                    "end_horizontal_m": None,
                    "end_vertical_m": None,
                    "max_horizontal_m": None,
                    "end_t": None,
                }
            )
            continue
        k = m[-1]
        out.append(
            {
                "start": float(start),
                "duration": float(dur),
                "end_horizontal_m": float(hz[k]),
                "end_vertical_m": float(vt[k]),
                "max_horizontal_m": float(np.max(hz[m])),
                "end_t": float(err.t[k]),
            }
        )
    return out


def section_rms(err: NavErrors, sections: Sequence[tuple[float, float]]) -> list[dict]:
    """Horizontal/vertical/ECEF RMS between given times (t0 ≤ t < t1) (paper Table 6 style)."""
    out = []
    for t0, t1 in sections:
        m = (err.t >= t0) & (err.t < t1)
        if not np.any(m):
            out.append({"t0": float(t0), "t1": float(t1), "n": 0})
            continue
        out.append(
            {
                "t0": float(t0),
                "t1": float(t1),
                "n": int(m.sum()),
                "horizontal_rms_m": float(rms(err.horizontal[m])),
                "vertical_rms_m": float(rms(err.vertical[m])),
                "ecef_rms_m": [float(x) for x in rms(err.ecef[m])],
            }
        )
    return out


def summarize(
    err: NavErrors,
    *,
    outages: Sequence[tuple[float, float]] = (),
    sections: Sequence[tuple[float, float]] = (),
    elapsed_s: float | None = None,
    duration_s: float | None = None,
) -> dict:
    """The ``metrics.json`` dictionary (docs/guide/theory.rst, 'Navigation filter' keys plus a few extras); lengths m,
    velocities m/s."""
    hz = err.horizontal
    out: dict = {
        "n_epochs": int(err.t.size),
        "horizontal_rms_m": float(rms(hz)),
        "horizontal_p95_m": float(np.percentile(hz, 95)),
        "horizontal_max_m": float(np.max(hz)),
        "vertical_rms_m": float(rms(err.vertical)),
        "vertical_max_m": float(np.max(err.vertical)),
        "ned_rms_m": [float(x) for x in rms(err.ned)],
        "ecef_rms_m": [float(x) for x in rms(err.ecef)],
        "velocity_rms_mps": [float(x) for x in rms(err.vel)],
    }
    if np.any(np.isfinite(err.att)):
        out["attitude_rms_deg"] = [float(np.degrees(x)) if np.isfinite(x) else None for x in rms(err.att)]
    out["outages"] = outage_drift(err, outages)
    out["mean_outage_end_horizontal_m"] = mean_end_drift(out["outages"])
    if outages:
        inside = np.zeros(err.t.size, dtype=bool)
        for start, dur in outages:
            inside |= (err.t >= start) & (err.t < start + dur)
        if np.any(~inside):
            out["horizontal_rms_outside_outages_m"] = float(rms(hz[~inside]))
    if sections:
        out["sections"] = section_rms(err, sections)
    out["elapsed_s"] = None if elapsed_s is None else float(elapsed_s)
    out["realtime_factor"] = float(duration_s / elapsed_s) if (elapsed_s and duration_s) else None
    return out
