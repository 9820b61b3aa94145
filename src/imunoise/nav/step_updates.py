"""The measurement updates of the step filter :class:`~imunoise.nav.step_filter.LooselyCoupledEKF`, one call per
fix (docs/guide/theory.rst, 'Navigation filter'): GNSS position and velocity, ZUPT, ZARU, and any (dz, H, R) in
filterpy's form; each is recorded as an :class:`Innovation` in ``last_update``.

The updates are the batch loop's functions (:func:`~imunoise.nav.filter_loop.stream_update`,
:func:`~imunoise.nav.filter_loop.zupt_update`, :func:`~imunoise.nav.ekf_kernels.kf_update`), so a run fed fix by fix
equals :func:`~imunoise.nav.ekf.run_ekf`. :class:`StepUpdates` is a mixin of the step filter: it works on the
filter's own state (``nav``, ``xm``, ``P``, ``acc``, ``layout``, ``t``, ``config``), its kernel arguments
(``arrays()``, ``kernel_parts()``, ``flush()``), its streams (``position_stream``, ``velocity_stream``) and its
rejection counters.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from imunoise.nav.ekf_kernels import kf_update
from imunoise.nav.filter_loop import stream_update, zupt_update
from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity
from imunoise.nav.measurements.zupt import zaru
from imunoise.nav.state import A_LAST_DT
from imunoise.nav.streams import S_REJECT

log = logging.getLogger("imunoise.nav.ekf")  # the filter's one logger name

__all__ = ["Innovation", "StepUpdates"]


class Innovation(NamedTuple):
    """One measurement update (filterpy's ``y``, ``S``, ``K``): its kind, time [s], innovation ``y`` = dz,
    its covariance ``S`` = HPHᵀ + R before the update, the gain ``K`` (zeros when not used), the NIS and
    whether the update was applied."""

    kind: str
    t: float
    y: np.ndarray
    S: np.ndarray
    K: np.ndarray
    nis: float
    used: bool


class StepUpdates:
    """The step filter's measurement updates (module docstring); every one returns whether it was applied."""

    # the attributes of the filter the updates read and write (set by LooselyCoupledEKF.__init__)
    last_update: Innovation | None
    last_innovation: tuple[float, np.ndarray, np.ndarray, bool] | None
    n_rejected: int

    def _record(self, kind: str, t: float, out: tuple) -> bool:
        nis, ok, dz, S, K = out
        self.last_update = Innovation(kind, float(t), dz, S, K, float(nis), bool(ok))
        return bool(ok)

    def update_gnss(self, t: float, llh: np.ndarray, sigma_ned: np.ndarray) -> bool:
        """GNSS antenna position fix (rad, rad, m) with 1σ NED (m). Returns whether it was used.

        Parameters
        ----------
        t : float
            Time of the fix [s], ≤ the filter time.
        llh : numpy.ndarray
            Antenna latitude, longitude [rad], height [m].
        sigma_ned : numpy.ndarray
            1σ North, East, Down [m]; non-finite values are replaced by ``config.gnss_sigma_nan``.

        Returns
        -------
        bool
            False when the χ² gate rejected it or the position is not finite.
        """
        llh = np.asarray(llh, dtype=float)
        sig = np.asarray(sigma_ned, dtype=float).copy()
        if not np.all(np.isfinite(llh)):
            log.warning("GNSS fix at t=%.3f has non-finite position: ignored", t)
            return False
        bad = ~np.isfinite(sig)
        sig[bad] = self.config.gnss_sigma_nan
        sig = np.maximum(sig, self.config.gnss_sigma_floor)
        st = self.position_stream([float(t)], llh, sig)
        st.state[S_REJECT] = self._consecutive_reject
        out = stream_update(self.arrays(), *self.kernel_parts(), st, 0, self.t)
        nis, ok, dz, S, _ = out
        self._record("gnss_position", t, out)
        self.last_innovation = (float(t), dz.copy(), S, bool(ok))
        self._consecutive_reject = int(st.state[S_REJECT])
        if not ok:
            self.n_rejected += 1
            self.log_rejected(t, nis)
        return bool(ok)

    def update_gnss_velocity(self, t: float, vel_ned: np.ndarray, sigma_ned: np.ndarray, **gate) -> bool:
        """GNSS antenna velocity fix (NED m/s, 1σ NED m/s) at time t ≤ the filter time
        (:mod:`imunoise.nav.measurements.gnss_velocity`; ``gate``: its ``gate_abs``, ``max_reject``); returns
        whether the χ² gate let it in (or forced it)."""
        fix = as_gnss_velocity([t], vel_ned, sigma_ned, **gate)
        if fix.t.size == 0:
            log.warning("GNSS velocity at t=%.3f is not finite: ignored", t)
            return False
        st = self.velocity_stream(fix)
        st.state[S_REJECT] = self._vel_reject
        ok = self._record("gnss_velocity", t, stream_update(self.arrays(), *self.kernel_parts(), st, 0, self.t))
        self._vel_reject = int(st.state[S_REJECT])
        return ok

    def update(self, dz: np.ndarray, H: np.ndarray, R: np.ndarray, *, chi2: float = 0.0, force: bool = False,
               kind: str = "custom") -> bool:
        """A measurement given as filterpy's ``KalmanFilter.update`` takes it, in innovation form: ``dz`` = ẑ − z
        (m,), ``H`` (m, n) with dz ≈ H δx over the error state (layout: :mod:`imunoise.nav.state`, model states
        after ``N_NAV``), ``R`` (m, m). P is first propagated to the filter time; the update is the filter's one
        Joseph update with closed-loop feedback, skipped when its NIS exceeds ``chi2`` (> 0) unless ``force``.
        ``last_update`` keeps y, S, K. Returns whether it was applied."""
        n = self.P.shape[0]
        dz = np.ascontiguousarray(dz, dtype=float).reshape(-1)
        H = np.ascontiguousarray(H, dtype=float).reshape(dz.size, n)
        R = np.ascontiguousarray(R, dtype=float).reshape(dz.size, dz.size)
        self.flush()
        nis, ok, S, K = kf_update(self.P, self.nav, self.xm, dz, H, R, float(chi2), bool(force), 0.0)
        return self._record(kind, self.t, (nis, ok, dz, S, K))

    def zupt_update(self, sigma_v: float, chi2: float = 0.0) -> bool:
        """Zero-velocity update: v^n = 0 with 1σ ``sigma_v`` (m/s) (:mod:`imunoise.nav.measurements.zupt`).

        Parameters
        ----------
        sigma_v : float
            1σ of the zero velocity [m/s].
        chi2 : float
            Skip the update when its NIS vᵀ(P_vv + σ²I)⁻¹v exceeds this (3 dof); 0 = always apply.

        Returns
        -------
        bool
            Whether the update was applied.
        """
        return self._record("zupt", self.t, zupt_update(self.arrays(), *self.kernel_parts(), float(sigma_v),
                                                        float(chi2)))

    def zaru_update(self, sigma_w: float) -> bool:
        """Zero angular-rate update: corrected ω_ib^b equals the Earth rate in body, 1σ ``sigma_w`` (rad/s).

        Parameters
        ----------
        sigma_w : float
            1σ of the angular rate [rad/s].

        Returns
        -------
        bool
            Whether the update was applied.
        """
        self.flush()
        dt = self.acc[A_LAST_DT] if self.acc[A_LAST_DT] > 0 else self.dt_nom
        L = self.layout
        dz, H, R = zaru(self.nav, self.P.shape[0], dt, L.hvec, L.axis_of, float(sigma_w))
        nis, ok, S, K = kf_update(self.P, self.nav, self.xm, dz, H, R, 0.0, True, 0.0)
        return self._record("zaru", self.t, (nis, ok, dz, S, K))
