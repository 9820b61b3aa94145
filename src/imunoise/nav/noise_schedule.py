"""Process noise that changes along a run: per-axis scales, a moving Gauss–Markov, bias bumps (issue 21 §2).

The filter of the law-aware oracle is told, piece by piece, what a simulated motion law injects
(:mod:`imunoise.sim.law_schedule`). Three controls, each held until the next call (:class:`NoiseControl`):

* :meth:`NoiseControl.set_noise_scale` ``(white, bias)``: the white PSD of axis a times ``white[a]``
  (Q_white = C diag(psd·m_w²) Cᵀ Δt) and the driving noise of every RW/AR1 state of axis a times ``bias[a]``.
  The part of an axis' white PSD that stands for short AR1 processes folded into white noise (``bias_psd``,
  :func:`imunoise.online.to_filter.ekf_axis_model`) is bias driving noise and scales by ``bias[a]``.
  Exact on the k-step tables Q_m^(k) = Σ Φ^i Q Φ^iᵀ because Φ_m is block-diagonal per axis: the block of axis
  a scales by ``bias[a]`` (entries (i, j) by √(c_i c_j), zero across axes). Scale-factor states and the moving
  Gauss–Markov are not scaled.
* :meth:`NoiseControl.set_moving` ``(flag)``: the moving Gauss–Markov state of an axis (an AR1 state, H = 1,
  P0 = σ²) evolves (φ = e^{−Δt/τ}, q = σ²(1 − φ²)) while moving and is frozen (Φ = 1, q = 0) at stops.
* :func:`add_bias_variance` ``(P, bias_index, var)``: P[b_a, b_a] += var[a] at a departure (a bias step
  N(0, σ²) the simulator draws there); cross-covariances untouched.

A random walk the model lacks (the warm-up's closest random walk, :func:`imunoise.sim.law_schedule.
warmup_random_walk`) is added unscaled to the bias state: Q^(k)[b, b] += q·k·Δt (exact: the bias column of
Φ^i is e_b, a DR ramp feeds the bias, not the reverse).

:func:`run_pieces` runs the filter engine (:func:`~imunoise.nav.filter_loop.run_steps`) piece by piece between
the points where the noise changes, flushing the covariance at every piece's end so that the accumulated
increments are propagated with the noise of their own piece. A piece restarts the kernel's counters (the
consecutive-rejection count of the χ² gate, the ZUPT/NHC sample phase); the oracle uses neither ZUPT nor NHC.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imunoise.nav.error_states import KIND_SCALE, ModelLayout
from imunoise.nav.filter_loop import FilterArrays, ImuInput, ModelArrays, Outputs, flush, run_steps
from imunoise.nav.state import N_NAV
from imunoise.nav.streams import StreamSet

__all__ = ["NoiseControl", "add_bias_variance", "run_pieces"]


class NoiseControl:
    """The kernel's :class:`ModelArrays` under the current noise scales and moving flag (module docstring).

    ``base``: the arrays of the filter's layout (moving Gauss–Markov evolving, scales 1); ``gm_index``: per axis
    the layout index of its moving Gauss–Markov state or −1; ``extra_rw_q``: per axis an unscaled random-walk
    PSD added to the bias state [unit²/s]; ``bias_psd``: per axis the part of ``base.wpsd`` that is folded bias
    noise (scaled by the bias scale, not the white one); ``dt``: the nominal step [s].
    """

    def __init__(self, layout: ModelLayout, base: ModelArrays, dt: float, gm_index: Sequence[int] | None = None,
                 extra_rw_q: Sequence[float] | None = None, bias_psd: Sequence[float] | None = None) -> None:
        self.bias_psd = np.zeros(6) if bias_psd is None else np.asarray(bias_psd, dtype=float)
        self.layout, self.base, self.dt = layout, base, float(dt)
        nm = layout.nm
        self.gm_index = np.full(6, -1, dtype=np.int64) if gm_index is None else np.asarray(gm_index, dtype=np.int64)
        gm = self.gm_index[self.gm_index >= 0]
        self.bias_index = np.array([layout.index(a)[0] for a in range(6)], dtype=np.int64)
        # per state: the axis whose bias scale it takes, or −1 (scale factors, moving GM)
        self.scaled_axis = layout.axis_of.copy()
        self.scaled_axis[layout.kind == KIND_SCALE] = -1
        self.scaled_axis[gm] = -1
        kmax = base.phi_pow.shape[0] - 1
        steps = np.arange(kmax + 1, dtype=float)
        self.extra_q = np.zeros_like(base.q_pow)
        if extra_rw_q is not None:
            for a, q in enumerate(np.asarray(extra_rw_q, dtype=float)):
                b = self.bias_index[a]
                self.extra_q[:, b, b] = q * steps * self.dt
        # frozen tables: the moving GM states keep their value and get no noise
        self.phi_frozen = base.phi_pow.copy()
        self.q_frozen = base.q_pow.copy()
        for g in gm:
            self.phi_frozen[:, g, g] = 1.0
            self.q_frozen[:, g, g] = 0.0
        self._white = np.ones(6)
        self._bias = np.ones(6)
        self._moving = True
        self._mask = np.zeros((nm, nm), dtype=bool)
        self._cache: ModelArrays | None = None

    def set_noise_scale(self, white: Sequence[float], bias: Sequence[float]) -> None:
        """Scale the white PSD of axis a by ``white[a]`` and its RW/AR1 driving noise by ``bias[a]``."""
        self._white = np.asarray(white, dtype=float).copy()
        self._bias = np.asarray(bias, dtype=float).copy()
        self._cache = None

    def set_moving(self, flag: bool) -> None:
        """The moving Gauss–Markov states evolve (True) or are frozen (False)."""
        self._moving = bool(flag)
        self._cache = None

    def arrays(self) -> ModelArrays:
        """The kernel's model arrays under the current controls."""
        if self._cache is None:
            b = self.base
            c = np.ones(self.layout.nm)
            on = self.scaled_axis >= 0
            c[on] = self._bias[self.scaled_axis[on]]
            r = np.sqrt(c)
            phi, q = (b.phi_pow, b.q_pow) if self._moving else (self.phi_frozen, self.q_frozen)
            q = q * np.outer(r, r)[None, :, :] + self.extra_q
            wpsd = (b.wpsd - self.bias_psd) * self._white + self.bias_psd * self._bias
            self._cache = ModelArrays(phi, np.ascontiguousarray(q), b.hvec, b.axis_of, wpsd, b.wpsd_fb, b.sf_idx)
        return self._cache


def add_bias_variance(P: np.ndarray, bias_index: np.ndarray, var: Sequence[float]) -> None:
    """P[b_a, b_a] += var[a] for the bias state b_a of each axis (model-state index), in place."""
    for a, v in enumerate(np.asarray(var, dtype=float)):
        P[N_NAV + bias_index[a], N_NAV + bias_index[a]] += v


def _slice_out(out: Outputs, a: int, b: int, n: int) -> Outputs:
    return Outputs(*(x[a : b + 1] if x.shape[0] == n else x for x in out))


def run_pieces(ekf, imu: ImuInput, f: FilterArrays, streams: StreamSet, out: Outputs, bounds: Sequence[int],
               before_piece) -> None:
    """Run samples bounds[0] → bounds[-1] of ``imu`` as pieces [bounds[i], bounds[i+1]] through the filter engine
    with the settings of the filter ``ekf`` (:class:`~imunoise.nav.ekf.LooselyCoupledEKF`) on the state ``f``.

    ``before_piece(i0)``, the noise-schedule hook, is called before the piece starting at sample i0 and returns
    its :class:`ModelArrays` (it may change ``f.P``, e.g. :func:`add_bias_variance`); the covariance is flushed
    with those arrays at the piece's end. The epochs of ``streams`` with t[i0] < t ≤ t[i1] are applied in the
    piece (their status and NIS land in ``streams``)."""
    n = imu.t.shape[0]
    _, s = ekf.kernel_parts()
    nh = ekf.nhc_settings()
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b <= a:
            continue
        m = before_piece(a)
        piece = ImuInput(*(x[a : b + 1] for x in imu))
        run_steps(piece, f, m, s, nh, streams.slice(imu.t[a], imu.t[b]).kernel(), np.array([1, 0, 0], dtype=np.int64),
                  _slice_out(out, a, b, n), 0, b - a + 1)
        flush(f, m, s)
