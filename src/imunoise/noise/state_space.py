"""The discrete state-space form of one sensor axis' error model (docs/guide/theory.rst, 'Navigation filter'): the
blocks (Φ, Q, H, P0) a filter
runs over a step dt, stacked from each process' own :meth:`~imunoise.noise.process_base.Process.filter_block`
(:meth:`imunoise.noise.model.Model.state_space` builds it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.process_base import ROLE_BIAS, FilterState, StateBlock

__all__ = ["StateSpace", "stack_state_space"]


@dataclass(frozen=True)
class StateSpace:
    """Discrete state-space blocks of one sensor axis' error model over a step dt
    (docs/guide/theory.rst, 'Navigation filter').

    Sensor error = ``H @ x + w`` with ``x_{k+1} = Phi @ x_k + q_k``, ``q ~ N(0, Q)`` and a white part w.
    States: ``bias`` (random constant, plus RW if present), then each process' own states in canonical order
    (one per AR1, ``DR``: the rate ramp, which drives the bias; a process with coupled states, e.g. an oscillator,
    brings its k×k block), from :meth:`Process.filter_block`; ``roles``
    names what each state is to the filter (:data:`imunoise.noise.process_base.ROLE_BIAS` etc.). ``P0`` holds the
    stationary variance of each AR1 state and 0 for bias and DR: the filter sets those from its own initial
    uncertainty. ``white_psd`` is the two-sided continuous PSD of the white part (WN + QN, and an MA1 by its
    zero-frequency density; unit²·s = N², N the noise density); ``white_var`` its per-step variance at dt
    (white_psd / dt).

    Attributes
    ----------
    labels : tuple of str
        Name of each state (``bias``, ``AR1_1``, …, ``DR``).
    Phi : numpy.ndarray
        Transition matrix over dt, shape (n, n).
    Q : numpy.ndarray
        Process-noise covariance over dt, shape (n, n).
    H : numpy.ndarray
        Map from the states to the sensor error, shape (n,).
    P0 : numpy.ndarray
        Initial covariance (stationary AR1 variances, 0 elsewhere), shape (n, n).
    white_psd : float
        Two-sided PSD of the white part [unit²·s].
    white_var : float
        Its variance per step dt [unit²].
    """

    labels: tuple[str, ...]
    Phi: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    P0: np.ndarray
    white_psd: float
    white_var: float
    roles: tuple[int, ...] = ()  # per state: imunoise.noise.processes.ROLE_BIAS / ROLE_STATIONARY / ROLE_RAMP

    @property
    def n(self) -> int:
        return len(self.labels)


def stack_state_space(model: Any, dt: float, freq: float | None = None) -> StateSpace:
    """The :class:`StateSpace` over a filter step dt of ``model`` (a :class:`imunoise.noise.model.Model`: its
    ``components``, their canonical ``component_names()`` and ``white_variance()``) with parameters per sample at
    ``freq`` (default 1/dt); :meth:`imunoise.noise.model.Model.state_space` documents the blocks."""
    if not dt > 0:
        raise ModelError(f"filter step dt must be > 0 s, got {dt}")
    f = 1.0 / dt if freq is None else float(freq)
    if not f > 0:
        raise ModelError(f"sampling frequency must be > 0 Hz, got {freq}")
    steps = dt * f
    labels = ["bias"]
    states: list[FilterState | StateBlock] = []  # a scalar state or a block of k coupled ones
    bias_q = 0.0
    for name, c in zip(model.component_names(), model.components):
        q_add, own = c.filter_block(steps, dt)
        if q_add:
            bias_q += q_add
        if isinstance(own, StateBlock):
            labels += [f"{name}.{k + 1}" for k in range(len(own.h))]
            states.append(own)
            continue
        for k, st in enumerate(own):
            labels.append(name if len(own) == 1 else f"{name}.{k + 1}")
            states.append(st)
    n = len(labels)
    Phi = np.eye(n)
    Q = np.zeros((n, n))
    P0 = np.zeros((n, n))
    H = np.zeros(n)
    H[0] = 1.0
    if bias_q:
        Q[0, 0] += bias_q
    roles = [ROLE_BIAS]
    i = 1
    for st in states:
        if isinstance(st, StateBlock):
            k = len(st.h)
            Phi[i : i + k, i : i + k] = st.phi
            Q[i : i + k, i : i + k] = st.q
            P0[i : i + k, i : i + k] = st.p0
            H[i : i + k] = st.h
            roles += [st.role] * k
            i += k
            continue
        Phi[i, i] = st.phi
        Q[i, i] = st.q
        P0[i, i] = st.p0
        H[i] = st.h
        if st.bias_link:
            Phi[0, i] = st.bias_link
        roles.append(st.role)
        i += 1
    white_psd = model.white_variance() / f
    return StateSpace(tuple(labels), Phi, Q, H, P0, white_psd, white_psd / dt, tuple(roles))
