"""MA1 (first-order moving average, simts' MA1), added as one class in the registry: its closed-form WV against
a Monte-Carlo WV, its parameters recovered by the GMWM, its filter block against the WV's white limit."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.noise.estimator import gmwm
from imunoise.noise.fitting.kernels import wv_of_theta
from imunoise.noise.fitting.params import kind_codes
from imunoise.noise.model import Model
from imunoise.noise.processes import MA1, WN
from imunoise.noise.wv import wavelet_variance


def test_ma1_wv_matches_monte_carlo():
    # 40 paths of 2^15 samples: the mean of the empirical WV is within 3 % of the closed form at scales τ ≤ 2^8.
    # The Monte-Carlo standard error of that mean is 0.15 % at τ = 2 and 1.0 % at τ = 2^8 (measured), so 3 % is
    # three standard errors at the coarsest scale checked; the seeds give at most 1.2 %.
    m = MA1(theta=0.6, sigma2=2.0)
    acc = []
    for seed in range(40):
        wv = wavelet_variance(Model([m]).simulate(2**15, seed=seed), freq=1.0)
        acc.append(wv.variance[:8])
    mc = np.mean(acc, axis=0)
    np.testing.assert_allclose(mc, m.wv(wv.scales[:8]), rtol=0.03)


@pytest.mark.parametrize("theta", [-0.5, 0.0, 0.7])
def test_ma1_numba_form_equals_numpy(theta):
    m = Model([MA1(theta=theta, sigma2=1.5)])
    tau = 2.0 ** np.arange(1, 20)
    np.testing.assert_allclose(wv_of_theta(m.vector, kind_codes(m), tau), m.wv(tau), rtol=1e-13)


def test_gmwm_recovers_ma1():
    # 4·10^5 samples: θ̂ = 0.5006 and σ̂² within 0.1 % of the truth on this seed; the tolerances allow other
    # platforms' last-bit differences in the optimiser, not a wrong closed form (θ off by 0.05 fails)
    x = Model([MA1(theta=0.5, sigma2=1e-4)]).simulate(400_000, seed=5)
    fit = gmwm("MA1", x, freq=100.0)
    th, s2 = fit.model.vector
    assert list(fit.param_units()) == ["MA1.theta", "MA1.sigma2"] and fit.param_units()["MA1.theta"] == "1"
    assert set(fit.continuous_units()) == set(fit.continuous()) == {"MA1.theta", "MA1.noise_density"}
    assert th == pytest.approx(0.5, abs=0.01)
    assert s2 == pytest.approx(1e-4, rel=0.02)
    # beside a random walk, with a negative θ
    y = Model([MA1(theta=-0.4, sigma2=1e-4)]).simulate(400_000, seed=6)
    y = y + np.cumsum(np.random.default_rng(9).normal(0.0, 1e-5, y.size))
    model = gmwm("MA1+RW", y, freq=100.0).model
    assert model.params["MA1.theta"] == pytest.approx(-0.4, abs=0.01)
    assert model.params["MA1.sigma2"] == pytest.approx(1e-4, rel=0.02)
    assert model.params["RW.gamma2"] == pytest.approx(1e-10, rel=0.3)


def test_ma1_filter_block_is_white_with_its_long_scale_density():
    """The block is white with σ²(1+θ)² per sample: its WV differs from the MA1's by exactly 6θσ²/τ² (the one-lag
    autocovariance the white block leaves out), which vanishes at long scales."""
    th, s2 = 0.4, 3.0
    m = MA1(theta=th, sigma2=s2) + WN(sigma2=1.0)
    ss = m.state_space(0.01, 100.0)
    assert ss.labels == ("bias",)
    assert ss.white_var == pytest.approx(s2 * (1 + th) ** 2 + 1.0, rel=1e-15)
    tau = 2.0 ** np.arange(1, 25)
    block_wv = ss.white_var / tau  # WV of the block's white sequence
    np.testing.assert_allclose(m.wv(tau) - block_wv, -6.0 * th * s2 / tau**2, rtol=1e-9, atol=1e-15)


def test_ma1_in_the_registry_selection_and_filter_mapping():
    import imunoise
    from imunoise.noise.equivalent_noise import equivalent_noise
    from imunoise.noise.selection import candidates

    assert imunoise.MA1 is MA1  # the package facade serves every registered process

    assert str(Model.parse("ma1 + WN")) == "WN + MA1"
    assert sorted(c.n_params for c in candidates("WN+MA1")) == [1, 2, 3]
    eq = equivalent_noise(Model([MA1(theta=-0.3, sigma2=2e-4), WN(sigma2=1e-4)]), 100.0)
    assert eq.sigma2 == pytest.approx(2e-4 * 0.7**2 + 1e-4, rel=1e-15) and eq.gamma2 == 0.0
    fast = MA1(theta=0.2, sigma2=1e-4).at_rate(200.0, 100.0)
    assert fast.continuous(100.0)["MA1.noise_density"] == pytest.approx(
        MA1(theta=0.2, sigma2=1e-4).continuous(200.0)["MA1.noise_density"], rel=1e-14)
