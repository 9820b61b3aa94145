"""The augmented IMU error states of the EKF: layout, initial covariance and the model swap
(docs/guide/theory.rst, 'Navigation filter').

The filter state is δx = [δr, δv, φ, x_m] with the nine navigation error states followed by the ``nm``
model states x_m of the six sensor axes (gyro x,y,z, accel x,y,z), each axis the states of its error
model's ``state_space(dt, freq)`` (bias, one per AR1, DR), and, with ``EkfConfig.scale_factors``, six
scale-factor states s_g,x..s_a,z after all of them (kind 3, h = 0: they scale the increment instead of
adding to it; KF-GINS' SG/SA states). :class:`ModelLayout` describes x_m;
:func:`initial_covariance` is P_0 of a fresh filter; :func:`swap_map` maps (x̂_m, P) from one layout to
another when the error models are replaced while the filter runs (docs/guide/theory.rst, 'Navigation filter' hot-swap).
Everything here is a
pure function of its arguments: :class:`~imunoise.nav.ekf.LooselyCoupledEKF` owns the state and applies
the results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.nav.defaults import EkfConfig
from imunoise.nav.state import ATT, N_NAV, POS, VEL
from imunoise.noise.process_base import ROLE_BIAS, ROLE_RAMP, ROLE_STATIONARY

__all__ = [
    "AXES", "ModelLayout", "SwapResult", "carried_states", "initial_covariance", "scale_spec", "swap_map",
]

POW_MAX = 64
KIND_SCALE = 3  # the filter's own state kind, after the processes' roles (imunoise.noise.process_base.ROLE_*)


def scale_spec(config: EkfConfig) -> tuple[float, float, float] | None:
    """(gyro σ, accel σ, τ [s]) of the scale-factor states of ``config``, or None when they are off.

    Parameters
    ----------
    config : EkfConfig
        ``scale_factors``, ``gyro_scale_std``, ``accel_scale_std`` (dimensionless) and ``scale_tau_s``
        (s; ``math.inf`` for a random constant).

    Returns
    -------
    tuple or None
        The three values, checked.
    """
    if not config.scale_factors:
        return None
    sg, sa, tau = float(config.gyro_scale_std), float(config.accel_scale_std), float(config.scale_tau_s)
    if not (sg > 0 and sa > 0 and math.isfinite(sg) and math.isfinite(sa)):
        raise ModelError(
            f"scale-factor σ must be finite and > 0, got gyro {sg:g}, accel {sa:g} (e.g. 1e-3 = 1000 ppm)"
        )
    if not tau > 0:
        raise ModelError(f"scale_tau_s must be > 0 s (math.inf for a random constant), got {tau:g}")
    return sg, sa, tau


@dataclass
class ModelLayout:
    """The augmented error states of the six axes at a nominal step ``dt`` (all arrays numba-ready)."""

    labels: list[str]
    axis_of: np.ndarray  # (nm,) int: 0..5
    kind: np.ndarray  # (nm,) int: ROLE_BIAS, ROLE_STATIONARY (AR1), ROLE_RAMP (DR), KIND_SCALE (scale factor)
    hvec: np.ndarray  # (nm,)
    P0: np.ndarray  # (nm, nm) AR1 stationary variances, bias/DR zero
    phi_pow: np.ndarray  # (POW_MAX+1, nm, nm): Φ_m^k
    q_pow: np.ndarray  # (POW_MAX+1, nm, nm): Q_m accumulated over k steps
    wpsd: np.ndarray  # (6,) white PSD of each axis, unit²·s
    models: list
    scale_index: np.ndarray = field(default_factory=lambda: np.full(6, -1, dtype=np.int64))  # (6,) or −1

    @property
    def nm(self) -> int:
        return len(self.labels)

    def index(self, axis: int) -> np.ndarray:
        return np.flatnonzero(self.axis_of == axis)

    def bias_rows(self) -> np.ndarray:
        """Row of each axis' bias state (its first model state) in the full covariance, gyro x,y,z, accel x,y,z."""
        return np.array([N_NAV + int(self.index(a)[0]) for a in range(6)], dtype=np.int64)

    @classmethod
    def build(
        cls, models: list, dt: float, scale: tuple[float, float, float] | None = None
    ) -> ModelLayout:
        """Layout of the six axes' models (each carrying its rate) at step ``dt``; ``scale`` = :func:`scale_spec`
        appends the six scale-factor states (Gauss–Markov: φ = exp(−dt/τ), q = σ²(1 − φ²), P0 = σ²; τ = ∞: φ = 1,
        q = 0)."""
        labels, axis_of, kind, h = [], [], [], []
        blocks_phi, blocks_q, blocks_p0, wpsd = [], [], [], np.zeros(6)
        for a, m in enumerate(models):
            ss = m.state_space(dt, m.sample_rate(None, "the filter"))
            for lab, role in zip(ss.labels, ss.roles):  # roles: imunoise.noise.processes.ROLE_* = kinds 0–2 here
                labels.append(f"{AXES[a]}.{lab}")
                kind.append(role)
            axis_of += [a] * ss.n
            h += list(np.asarray(ss.H, dtype=float))
            blocks_phi.append(np.asarray(ss.Phi, dtype=float))
            blocks_q.append(np.asarray(ss.Q, dtype=float))
            blocks_p0.append(np.asarray(ss.P0, dtype=float))
            wpsd[a] = float(ss.white_psd)
        scale_index = np.full(6, -1, dtype=np.int64)
        if scale is not None:
            sg, sa, tau = scale
            phi = math.exp(-dt / tau)  # 1.0 for τ = ∞
            for a in range(6):
                sig = sg if a < 3 else sa
                scale_index[a] = len(labels)
                labels.append(f"{AXES[a]}.scale")
                kind.append(KIND_SCALE)
                axis_of.append(a)
                h.append(0.0)
                blocks_phi.append(np.array([[phi]]))
                blocks_q.append(np.array([[sig * sig * (1.0 - phi * phi)]]))
                blocks_p0.append(np.array([[sig * sig]]))
        nm = len(labels)
        phi1, q1, p0 = np.zeros((nm, nm)), np.zeros((nm, nm)), np.zeros((nm, nm))
        i = 0
        for bp, bq, b0 in zip(blocks_phi, blocks_q, blocks_p0):
            k = bp.shape[0]
            phi1[i : i + k, i : i + k], q1[i : i + k, i : i + k], p0[i : i + k, i : i + k] = bp, bq, b0
            i += k
        if not (np.all(np.isfinite(phi1)) and np.all(np.isfinite(q1)) and np.all(np.isfinite(wpsd))):
            raise ModelError("error model state space has non-finite entries; check the model parameters")
        phi_pow = np.empty((POW_MAX + 1, nm, nm))
        q_pow = np.empty((POW_MAX + 1, nm, nm))
        phi_pow[0], q_pow[0] = np.eye(nm), 0.0
        for k in range(1, POW_MAX + 1):
            phi_pow[k] = phi1 @ phi_pow[k - 1]
            q_pow[k] = phi1 @ q_pow[k - 1] @ phi1.T + q1
        return cls(
            labels,
            np.array(axis_of, dtype=np.int64),
            np.array(kind, dtype=np.int64),
            np.array(h),
            p0,
            phi_pow,
            q_pow,
            wpsd,
            list(models),
            scale_index,
        )


def initial_covariance(config: EkfConfig, layout: ModelLayout) -> np.ndarray:
    """P_0 ((9 + nm)²) of a filter with ``layout``: the configured navigation σ, the configured turn-on σ
    for bias states and σ for DR states, the stationary variance for AR1 and scale-factor states
    (docs/guide/theory.rst, 'Navigation filter').

    Parameters
    ----------
    config : EkfConfig
        ``sigma_pos0``/``sigma_vel0``/``sigma_att0`` (m, m/s, rad), ``sigma_{gyro,accel}_bias0`` and
        ``sigma_{gyro,accel}_drift0`` (rad/s, m/s² and per sample).
    layout : ModelLayout
        The model states.

    Returns
    -------
    numpy.ndarray
        The diagonal-by-block initial covariance (AR1 blocks from ``layout.P0``).
    """
    n = N_NAV + layout.nm
    P = np.zeros((n, n))
    P[POS, POS] = np.diag(np.square(config.sigma_pos0))
    P[VEL, VEL] = np.diag(np.square(config.sigma_vel0))
    P[ATT, ATT] = np.diag(np.square(config.sigma_att0))
    P[N_NAV:, N_NAV:] = layout.P0
    for s in range(layout.nm):
        gyro = layout.axis_of[s] < 3
        if layout.kind[s] == ROLE_BIAS:
            P[N_NAV + s, N_NAV + s] = (config.sigma_gyro_bias0 if gyro else config.sigma_accel_bias0) ** 2
        elif layout.kind[s] == ROLE_RAMP:
            P[N_NAV + s, N_NAV + s] = (config.sigma_gyro_drift0 if gyro else config.sigma_accel_drift0) ** 2
    return P


def carried_states(old: ModelLayout, new: ModelLayout) -> dict[int, int]:
    """The model states of ``new`` that continue a state of ``old``: {new index: old index}.

    Per axis: when the non-bias states of both layouts have the same kinds in the same order (a refit of
    the same structure), each continues its counterpart by position (the parameters change, the states keep
    their meaning); otherwise an AR1 of ``new`` continues the first unused AR1 of ``old`` with the same
    one-step φ (to 1e-12), e.g. the slow Gauss–Markov bias of the plain default kept by the floor of every
    online model. Bias states are never listed (the new bias takes the sum of the unlisted old states), nor
    scale-factor states (:func:`swap_map` always carries those).
    """
    phi_old = np.diag(old.phi_pow[1])
    phi_new = np.diag(new.phi_pow[1])
    pairs: dict[int, int] = {}
    for a in range(6):
        so = [int(x) for x in old.index(a) if old.kind[x] not in (ROLE_BIAS, KIND_SCALE)]
        sn = [int(x) for x in new.index(a) if new.kind[x] not in (ROLE_BIAS, KIND_SCALE)]
        if [old.kind[x] for x in so] == [new.kind[x] for x in sn]:
            pairs.update(zip(sn, so))
            continue
        used: set[int] = set()
        for x in sn:
            if new.kind[x] != ROLE_STATIONARY:
                continue
            for y in so:
                if y not in used and old.kind[y] == ROLE_STATIONARY and abs(phi_new[x] - phi_old[y]) <= 1e-12:
                    pairs[x] = y
                    used.add(y)
                    break
    return pairs


class SwapResult(NamedTuple):
    """Result of :func:`swap_map`: model-state estimates ``x`` (nm_new,), covariance ``P`` ((9 + nm_new)²),
    the number of new states that continue an old one (``kept``) and that start fresh (``reset``)."""

    x: np.ndarray
    P: np.ndarray
    kept: int
    reset: int


def swap_map(
    old: ModelLayout,
    new: ModelLayout,
    x: np.ndarray,
    P: np.ndarray,
    new_initial_P: np.ndarray,
    *,
    preserve: bool = True,
) -> SwapResult:
    """Map the filter's model-state estimates and covariance from layout ``old`` to ``new``
    (docs/guide/theory.rst, 'Navigation filter' hot-swap).

    An exact linear map T of the old error state (navigation states identity): a new state listed by
    :func:`carried_states` (only with ``preserve``) continues its old state 1:1 (estimate, variance and all
    cross-covariances); the new bias state of each axis takes the sum h·x̂ of the other old states of the
    axis (variance h P hᵀ, cross-covariances P[:, old] hᵀ), so the axis' total error estimate is unchanged;
    every other new state (AR1, DR) starts at 0, uncorrelated, with its variance from ``new_initial_P``
    (the stationary variance / the configured σ). ``preserve=False`` sums every old state into the bias: the
    docs/guide/theory.rst, 'Navigation filter' swap; online, where a refit follows every stop, it would reset the
    Gauss–Markov states to their
    stationary variance at every stop, i.e. forget the bias knowledge right before the drive continues.
    Scale-factor states are no part of the noise model: they continue 1:1 whenever both layouts have them
    (with or without ``preserve``; counted in ``kept``); a new one without an old counterpart starts fresh.

    Parameters
    ----------
    old, new : ModelLayout
        Layouts before and after the swap.
    x : numpy.ndarray
        Model-state estimates (old.nm,); the navigation error states are zero (closed-loop filter).
    P : numpy.ndarray
        Covariance ((9 + old.nm)²) with the covariance propagated to the swap epoch.
    new_initial_P : numpy.ndarray
        :func:`initial_covariance` of ``new``: the variances of the fresh states.
    preserve : bool
        Carry over the states :func:`carried_states` pairs (default) or reset all non-bias states.

    Returns
    -------
    SwapResult
        (x, P, kept, reset); P symmetrised.
    """
    pairs = carried_states(old, new) if preserve else {}
    for a in range(6):
        if new.scale_index[a] >= 0 and old.scale_index[a] >= 0:
            pairs[int(new.scale_index[a])] = int(old.scale_index[a])
    T = np.zeros((N_NAV + new.nm, N_NAV + old.nm))
    T[0:N_NAV, 0:N_NAV] = np.eye(N_NAV)
    paired_old = set(pairs.values())
    fresh: list[int] = []
    for a in range(6):
        b_new = int(new.index(a)[0])
        for y in old.index(a):
            if int(y) not in paired_old and old.kind[y] != KIND_SCALE:
                T[N_NAV + b_new, N_NAV + int(y)] = old.hvec[y]
        fresh += [int(s) for s in new.index(a) if new.kind[s] != ROLE_BIAS and int(s) not in pairs]
    for s_new, s_old in pairs.items():
        T[N_NAV + s_new, N_NAV + s_old] = 1.0
    x_old = np.concatenate([np.zeros(N_NAV), x])
    P_new = T @ P @ T.T
    for s in fresh:
        P_new[N_NAV + s, :] = 0.0
        P_new[:, N_NAV + s] = 0.0
        P_new[N_NAV + s, N_NAV + s] = new_initial_P[N_NAV + s, N_NAV + s]
    return SwapResult((T @ x_old)[N_NAV:], 0.5 * (P_new + P_new.T), len(pairs), len(fresh))
