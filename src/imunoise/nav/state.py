"""Named indices and views of the filter's arrays (docs/guide/theory.rst, 'Navigation filter'; KF-GINS ``StateID``): the
one place that says which
number of the error state δx, of the 17-float navigation array and of the covariance accumulator means what.

Error state δx (length 9 + number of model states; :mod:`imunoise.nav.ekf`)::

    δr (NED, m) 0:3 | δv (NED, m/s) 3:6 | φ (rad) 6:9 | model states (bias, AR1, DR, scale factors) 9:

Navigation array ``nav`` (:func:`imunoise.nav.mechanization.make_nav`)::

    lat, lon (rad), h (m) 0:3 | v NED (m/s) 3:6 | q_b^n 6:10 | previous Δθ 10:13 | previous Δv 13:16 | primed 16

Accumulator ``acc`` (between two covariance propagations; :func:`imunoise.nav.ekf_kernels.nav_step`)::

    Σ Δv_f^n 0:3 | Σ C dt 3:12 | T 12 | steps 13 | gate 14 | last dt 15 | Σ C diag(Δθ) 16:25 | Σ C diag(Δv) 25:34

Kernels index with the integer constants (numba folds them); Python code outside :mod:`imunoise.nav` reads the
filter through :class:`StateView` (``ekf.view.vel``, ``ekf.view.P_vel``) instead of slicing the arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "POS", "VEL", "ATT", "NAV", "N_NAV", "X_POS", "X_VEL", "X_ATT", "X_MODEL",
    "NAV_LEN", "I_POS", "I_VEL", "I_Q", "I_DTH", "I_DV", "I_PREV",
    "ACC_LEN", "A_DVN", "A_CDT", "A_T", "A_STEPS", "A_GATE", "A_LAST_DT", "A_CDTH", "A_CDV",
    "StateView", "InitialState",
]

# -- error state δx ------------------------------------------------------------------------------------
X_POS, X_VEL, X_ATT, X_MODEL = 0, 3, 6, 9
N_NAV = 9  # navigation error states
POS = slice(X_POS, X_POS + 3)
VEL = slice(X_VEL, X_VEL + 3)
ATT = slice(X_ATT, X_ATT + 3)
NAV = slice(0, N_NAV)

# -- navigation array ----------------------------------------------------------------------------------
NAV_LEN = 17
I_POS, I_VEL, I_Q, I_DTH, I_DV, I_PREV = 0, 3, 6, 10, 13, 16

# -- covariance accumulator ----------------------------------------------------------------------------
ACC_LEN = 34
A_DVN = 0  # Σ Δv_f^n (3)
A_CDT = 3  # Σ C_b^n dt, row-major (9)
A_T = 12  # accumulated time
A_STEPS = 13  # accumulated samples
A_GATE = 14  # the angular-rate gate was open in the interval
A_LAST_DT = 15  # dt of the last increment (survives the reset: ZARU)
A_CDTH = 16  # Σ C̄[i, a] Δθ̂_a at 16 + 3i + a (gyro scale-factor coupling)
A_CDV = 25  # Σ C̄[i, a] Δv̂_a at 25 + 3i + a (accel scale-factor coupling)


class StateView:
    """Named read/write views (not copies) of a filter's navigation array ``nav``, covariance ``P`` and model
    states ``xm``: ``llh``, ``vel``, ``quat``, ``P_pos``, ``P_vel``, ``P_att``, ``P_nav`` are numpy views, so
    reading them costs nothing and changes nothing. Units: rad, rad, m; m/s; NED."""

    __slots__ = ("nav", "P", "xm")

    def __init__(self, nav: np.ndarray, P: np.ndarray, xm: np.ndarray):
        self.nav, self.P, self.xm = nav, P, xm

    @property
    def llh(self) -> np.ndarray:
        """Latitude, longitude [rad], height [m] of the IMU point."""
        return self.nav[I_POS : I_POS + 3]

    @property
    def vel(self) -> np.ndarray:
        """Velocity NED [m/s]."""
        return self.nav[I_VEL : I_VEL + 3]

    @property
    def quat(self) -> np.ndarray:
        """Attitude quaternion q_b^n (scalar first)."""
        return self.nav[I_Q : I_Q + 4]

    @property
    def pos_vel(self) -> np.ndarray:
        """llh and velocity in one (6,) view."""
        return self.nav[I_POS : I_VEL + 3]

    @property
    def speed_h(self) -> float:
        """Horizontal speed [m/s]."""
        return math.hypot(self.nav[I_VEL], self.nav[I_VEL + 1])

    @property
    def P_pos(self) -> np.ndarray:
        """Covariance of δr (NED m²)."""
        return self.P[POS, POS]

    @property
    def P_vel(self) -> np.ndarray:
        """Covariance of δv (m²/s²)."""
        return self.P[VEL, VEL]

    @property
    def P_att(self) -> np.ndarray:
        """Covariance of φ (rad²)."""
        return self.P[ATT, ATT]

    @property
    def P_nav(self) -> np.ndarray:
        """The 9×9 navigation block of P."""
        return self.P[NAV, NAV]

    @property
    def std_nav(self) -> np.ndarray:
        """1σ of [δr (NED m), δv (m/s), φ (rad)], a new (9,) array."""
        return np.sqrt(np.abs(np.diag(self.P)[NAV]))


@dataclass(frozen=True)
class InitialState:
    """Initial navigation state and sensor biases (IMU point, not the antenna).

    Attributes
    ----------
    t : float
        Time of the state [s].
    llh : numpy.ndarray
        Latitude, longitude [rad], height [m].
    vel_ned : numpy.ndarray
        Velocity NED [m/s].
    euler : numpy.ndarray
        Roll, pitch, yaw [rad].
    gyro_bias : numpy.ndarray
        Initial gyro bias estimate [rad/s] (default zero).
    accel_bias : numpy.ndarray
        Initial accelerometer bias estimate [m/s²] (default zero).
    """

    t: float
    llh: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
