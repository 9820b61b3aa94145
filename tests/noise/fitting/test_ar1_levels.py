"""The solver's per-level AR1 kernel computes the same numbers as the scalar closed form, to the bit."""

from __future__ import annotations

import numpy as np

from imunoise.noise.ar1_math import ar1_g
from imunoise.noise.fitting.kernels import ar1_g_levels, wv_and_jacobian
from imunoise.noise.fitting.params import kind_codes
from imunoise.noise.model import Model


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the bit (np.array_equal would take −0.0 for 0.0)."""
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(a.view(np.int64) == b.view(np.int64)))


def test_ar1_g_levels_is_ar1_g_bit_for_bit():
    # both series regimes (|kL| < 1 and ≥ 1) and the switch between them, from φ → 1 to fast AR1s
    # the dyadic grid of the WV (terms reused from level to level) and an irregular one (nothing reused)
    for tau in (2.0 ** np.arange(1, 21), np.array([2.0, 3.0, 4.0, 6.0, 7.0, 14.0, 20.0, 40.0, 41.0, 500.0])):
        for L in -np.geomspace(1e-9, 30.0, 157):
            g, gL = np.empty(len(tau)), np.empty(len(tau))
            ar1_g_levels(tau, L, g, gL)
            ref = np.array([ar1_g(t / 2.0, L) for t in tau])
            assert same_bits(g, ref[:, 0]) and same_bits(gL, ref[:, 1]), (tau, L)


def test_chained_ar1_jacobian_matches_finite_differences():
    # the level-free factors of the chained AR1 entries are hoisted: the Jacobian must still be the derivative
    model = Model.parse("3*AR1 + WN + RW")
    kinds = kind_codes(model)
    tau = 2.0 ** np.arange(1, 13)
    u = np.array([-1.0, -2.0, 0.7, -1.5, 0.4, -3.0, -4.0, -6.0])
    nu, jac = np.empty(len(tau)), np.empty((len(tau), len(u)))
    wv_and_jacobian(u, kinds, tau, nu, jac)
    for p in range(len(u)):
        h = 1e-6
        up, um = u.copy(), u.copy()
        up[p] += h
        um[p] -= h
        nup, num = np.empty(len(tau)), np.empty(len(tau))
        wv_and_jacobian(up, kinds, tau, nup, np.empty_like(jac))
        wv_and_jacobian(um, kinds, tau, num, np.empty_like(jac))
        np.testing.assert_allclose(jac[:, p], (nup - num) / (2 * h), rtol=1e-4, atol=1e-4 * np.max(np.abs(jac[:, p])))


def test_series_tail_stops_early_without_changing_a_bit():
    from imunoise.noise.ar1_math import _tail as reference
    from imunoise.noise.fitting.ar1_levels import series_tail as _tail

    xs = np.concatenate([-np.geomspace(1e-300, 0.4999, 3000), np.geomspace(1e-300, 0.4999, 3000),
                         np.linspace(-0.6, 0.6, 1201)])
    for order in (2, 3):
        got = np.array([_tail(x, order) for x in xs])
        ref = np.array([reference(x, order) for x in xs])
        assert same_bits(got, ref), order
