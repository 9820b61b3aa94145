"""What-if runs of the step filter: a copy (or the filter itself) run on over samples already seen, through the
filter engine's step sequence (:func:`imunoise.nav.filter_loop.run_steps`), e.g. to rehearse a GNSS outage or run
shadow filters (:mod:`imunoise.online.motion_noise`)."""

from __future__ import annotations

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.filter_loop import FilterArrays, ImuInput, new_outputs, run_steps
from imunoise.nav.mechanization import nav_euler

__all__ = ["rehearse"]


def rehearse(ekf, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, gnss_t: np.ndarray, gnss_llh: np.ndarray,
             gnss_sigma: np.ndarray, *, gate: np.ndarray | None = None, with_nis: bool = False,
             with_std: bool = False, in_place: bool = False, with_nll: bool = False) -> tuple:
    """Run a copy of the filter on from its current state (the filter itself is not changed, unless
    ``in_place``): the engine of :func:`~imunoise.nav.ekf.run_ekf` over IMU samples ``t[1:]`` (``t[0]``
    must be the filter time) with the fixes ``gnss_*`` (sorted; σ as given). Used to rehearse a GNSS outage on data
    already seen and to run shadow filters (:mod:`imunoise.online.motion_noise`); the result equals
    :meth:`propagate`/:meth:`update_gnss` called sample by sample.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times [s], ``t[0]`` = the filter time, increasing.
    dtheta, dv : numpy.ndarray
        (n, 3) increments [rad, m/s]; row k covers (t[k−1], t[k]] (row 0 is not used).
    gnss_t, gnss_llh, gnss_sigma : numpy.ndarray
        Fixes to apply (times [s], (m, 3) lat/lon rad, h m, (m, 3) 1σ NED m); may be empty.
    gate : numpy.ndarray, optional
        Angular-rate gate per sample (default closed).
    with_nis, with_nll, with_std : bool
        Also return the NIS, then the innovation NLL
        (:class:`~imunoise.nav.streams.Stream` ``nll``), of every fix (NaN where not reached),
        then the 1σ of δr, δv, φ at every sample, (n, 9) (NED m, m/s, rad).
    in_place : bool
        Advance this filter itself to ``t[-1]`` (``last_innovation`` is not updated).

    Returns
    -------
    tuple of numpy.ndarray
        ``(llh, euler)`` of the IMU point at every sample, (n, 3) each, followed by ``nis`` with
        ``with_nis``, ``nll`` with ``with_nll`` and ``std`` with ``with_std``.
    """
    t = np.ascontiguousarray(t, dtype=float)
    if t.size < 2 or abs(t[0] - ekf.t) > 1e-9 or np.any(np.diff(t) <= 0):
        raise DataError(f"rehearse: t must start at the filter time {ekf.t:.3f} s and increase")
    ekf.flush()
    n = t.size
    sv = ekf.view
    out = new_outputs(n, store_cov=False, has_sf=False)
    out.pos[0], out.vel[0], out.att[0] = sv.llh, sv.vel, nav_euler(ekf.nav)
    out.std[0] = sv.std_nav
    gsig = np.maximum(np.ascontiguousarray(gnss_sigma, dtype=float).reshape(-1, 3), ekf.config.gnss_sigma_floor)
    fixes = ekf.position_stream(gnss_t, gnss_llh, gsig, with_nll=with_nll)
    imu = ImuInput(t, np.ascontiguousarray(dtheta, dtype=float), np.ascontiguousarray(dv, dtype=float),
                   np.zeros(n, dtype=np.bool_) if gate is None else np.ascontiguousarray(gate, dtype=np.bool_),
                   np.zeros(n, dtype=np.bool_))
    f = ekf.arrays() if in_place else FilterArrays(*(a.copy() for a in ekf.arrays()))
    streams = ekf.streams(fixes)
    streams.start_after(t[0])
    m, s = ekf.kernel_parts()
    run_steps(imu, f, m, s, ekf.nhc_settings(), streams.kernel(), np.array([1, 0, 0], dtype=np.int64), out, 0,
              n)
    if in_place:
        ekf.t = float(t[-1])
    extra = [a for a, w in ((fixes.nis, with_nis), (fixes.nll, with_nll), (out.std, with_std)) if w]
    return (out.pos, out.att, *extra)
