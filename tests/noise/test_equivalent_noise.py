"""The one model → (N, K) mapping (docs/guide/theory.rst, 'Latent processes' and 'Interfaces'): closed forms, log-AV
least squares, online agreement, real data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.noise.equivalent_noise import (
    ar1_white_variance,
    default_horizon_s,
    dr_equivalent_rw,
    equivalent_noise,
    match_grid,
    pair_wv,
)
from imunoise.noise.processes import AR1, DR, QN, RW, WN
from imunoise.online import ekf_axis_model

F = 100.0


def _ar1(tc_s: float, sigma_gm: float, f: float = F) -> AR1:
    phi = math.exp(-1.0 / (tc_s * f))
    return AR1(phi=phi, sigma2=sigma_gm**2 * (1.0 - phi * phi))


def test_exact_processes_keep_their_closed_forms():
    """WN, QN (2Q² white) and RW alone: the pair is the model's own, its AV equals the target everywhere."""
    eq = equivalent_noise(WN(sigma2=3e-5) + QN(q2=1e-6) + RW(gamma2=4e-12), F, horizon_s=500.0)
    assert eq.sigma2 == 3e-5 + 2e-6 and eq.gamma2 == 4e-12
    assert eq.N == pytest.approx(math.sqrt((3e-5 + 2e-6) / F), rel=1e-15)
    assert eq.K == pytest.approx(math.sqrt(4e-12 * F), rel=1e-15)
    assert eq.worst_ratio == 1.0 and eq.tau_range_s == (1 / F, 500.0)
    assert [(r.process, r.slot) for r in eq.routes] == [("WN", "N"), ("QN", "N"), ("RW", "K")]


def test_fast_gauss_markov_goes_to_n_with_its_sampled_density():
    """AR1(T_c = 5 ms) + RW at 100 Hz: N² = σ²/(1−φ)²·Δt exactly (the AR1's zero-frequency density), K the RW's.
    The continuous limit σ_GM·√(2T_c) is √((1+φ)/(1−φ)·Δt/(2T_c)) = 1.146 times smaller at T_c = Δt/2."""
    sgm, tc, g2 = 6e-3, 0.005, 2e-12
    ar1 = _ar1(tc, sgm)
    phi, s2 = ar1.values
    eq = equivalent_noise(ar1 + RW(gamma2=g2), F, horizon_s=2000.0)
    assert eq.N == pytest.approx(math.sqrt(ar1_white_variance(phi, s2) / F), rel=1e-12)
    factor = math.sqrt((1 + phi) / (1 - phi) * (1 / F) / (2 * tc))
    assert eq.N / (sgm * math.sqrt(2 * tc)) == pytest.approx(factor, rel=1e-12) and 1.14 < factor < 1.15
    assert eq.K == pytest.approx(math.sqrt(g2 * F), rel=0.2)
    assert [r.slot for r in eq.routes] == ["N", "K"]
    # far from the sampling limit (T_c = 50 Δt) the sampled density is the continuous one within 0.1 %
    phi50 = math.exp(-1 / 50)
    assert math.sqrt((1 + phi50) / (1 - phi50) / 100) == pytest.approx(1.0, abs=1e-3)


def test_slow_gauss_markov_goes_to_k():
    """T_c ≫ horizon: over the whole range the AR1 is a random walk of its innovation, K² = 2σ²_GM/T_c."""
    sgm, tc = 1e-3, 1e6
    eq = equivalent_noise(_ar1(tc, sgm) + WN(sigma2=1e-6), F, horizon_s=1000.0)
    assert eq.K == pytest.approx(math.sqrt(2 * sgm**2 / tc), rel=0.01)
    assert eq.N == pytest.approx(math.sqrt(1e-6 / F), rel=0.01)
    assert eq.worst_ratio < 1.01 and [r.slot for r in eq.routes] == ["K", "N"]


def test_matched_pair_is_the_constrained_log_av_least_squares_optimum():
    """A bias-instability bump inside the range: (σ², γ²) minimise Σ(ln AV_pair − ln AV_model)² within
    [exact part, cap] — no feasible perturbation lowers it —, the RW line stays under the model's AV
    everywhere and the white line where the model falls like white noise; the worst ratio is the largest
    factor on the grid."""
    from imunoise.noise.equivalent_noise import white_region

    model = _ar1(50.0, 2e-4) + WN(sigma2=5e-7) + RW(gamma2=1e-15)
    eq = equivalent_noise(model, F, horizon_s=3000.0)
    tau = 2 * match_grid(F, 3000.0)
    y = model.wv(tau)

    def cost(s2, g2):
        return float(np.sum((np.log(pair_wv(tau, s2, g2)) - np.log(y)) ** 2))

    c0 = cost(eq.sigma2, eq.gamma2)
    for d in (0.99, 1.01):
        if eq.sigma2_exact <= eq.sigma2 * d <= eq.sigma2_cap:
            assert cost(eq.sigma2 * d, eq.gamma2) >= c0
        if eq.gamma2_exact <= eq.gamma2 * d <= eq.gamma2_cap:
            assert cost(eq.sigma2, eq.gamma2 * d) >= c0
    assert np.all(pair_wv(tau, 0.0, eq.gamma2) <= y * (1 + 1e-12))
    white = white_region(y, tau)
    assert white.any() and np.all(pair_wv(tau, eq.sigma2, 0.0)[white] <= y[white] * (1 + 1e-12))
    r = pair_wv(tau, eq.sigma2, eq.gamma2) / y
    assert eq.worst_ratio == pytest.approx(max(r.max(), 1 / r.min()), rel=1e-12) and eq.worst_ratio > 2
    assert eq.sigma2 >= 5e-7 and eq.gamma2 >= 1e-15  # never below the exact parts
    assert [r.slot for r in eq.routes] == ["N+K", "N", "K"]


def test_gauss_markov_just_slower_than_the_update_keeps_its_white_part():
    """T_c = 1.4 Δt (ADIS16405 unit 4 accel z): smooth at Δt, white beyond — no jump at the fold threshold."""
    sgm = 0.033
    below = equivalent_noise(_ar1(0.0099, sgm) + RW(gamma2=1e-12), F, horizon_s=2000.0)
    above = equivalent_noise(_ar1(0.0143, sgm) + RW(gamma2=1e-12), F, horizon_s=2000.0)
    assert [r.slot for r in below.routes][0] == "N" and [r.slot for r in above.routes][0] == "N+K"
    phi = math.exp(-1 / (0.0143 * F))
    asym = sgm * math.sqrt((1 + phi) / (1 - phi) / F)  # its white density on scales >> T_c
    assert 0.85 < above.N / asym <= 1.0 and above.N / below.N > 0.9


def test_drift_is_the_random_walk_with_its_av_at_the_horizon_and_horizon_is_needed():
    omega, h = 2e-6, 40.96
    eq = equivalent_noise(WN(sigma2=1e-6) + DR(omega=omega), F, horizon_s=h)
    assert eq.gamma2 == pytest.approx(dr_equivalent_rw(omega, 2 * h * F), rel=1e-15)
    tau = np.array([2 * h * F])
    assert RW(gamma2=eq.gamma2).wv(tau)[0] == pytest.approx(DR(omega=omega).wv(tau)[0], rel=1e-12)
    with pytest.raises(ModelError, match="horizon"):
        equivalent_noise(_ar1(10.0, 1e-4) + WN(sigma2=1e-6), F)
    with pytest.raises(ModelError, match="shorter than one update"):
        equivalent_noise(_ar1(10.0, 1e-4) + WN(sigma2=1e-6), F, horizon_s=0.001)


def test_online_filter_mapping_agrees_with_the_export():
    """Where both apply (no Gauss–Markov state kept) the filter's WN/RW are exactly the exported pair."""
    model = _ar1(0.004, 5e-3) + _ar1(1e7, 1e-3) + WN(sigma2=1e-6) + QN(q2=1e-7) + RW(gamma2=1e-13) + DR(omega=1e-7)
    horizon = 2.0**14  # Haar scale, samples
    eq = equivalent_noise(model, F, horizon_s=horizon / (2 * F))
    filt = ekf_axis_model(model, F, None, fold_tau_s=1.0 / F, horizon=horizon)
    assert str(filt) == "WN + RW"
    assert filt.params["WN.sigma2"] == eq.sigma2 and filt.params["RW.gamma2"] == eq.gamma2
    # the default fold (1 s) folds the 4 ms AR1 with the same closed form as the export
    fast = _ar1(0.004, 5e-3) + WN(sigma2=1e-6) + RW(gamma2=1e-13)
    e2 = equivalent_noise(fast, F, horizon_s=100.0)
    assert ekf_axis_model(fast, F, None, horizon=2e4).params["WN.sigma2"] == e2.sigma2


def test_k_is_capped_at_the_data_allan_bound_but_the_online_mapping_is_not():
    """Rule 4 with known truth: WN + RW data (N = 1e-3, K = 1e-4 continuous). A fit whose RW is forced 4x too
    large (K 2x) is capped to the data's bound min AD·√(3/τ) over the ≥ 3-dof points, which lies near the
    truth; the right fit is left alone (K within 20 % of the truth). The written K is always min(K_model,
    K_data); the online filter mapping (no data curve) keeps the model's own RW."""
    from dataclasses import replace

    from imunoise.export import axis_lines, axis_noise
    from imunoise.noise.allan import allan_variance, rw_bound
    from imunoise.noise.imu_model import fit_axis

    n_true, k_true = 1e-3, 1e-4
    rng = np.random.default_rng(0)
    n = 2**18
    x = n_true * math.sqrt(F) * rng.standard_normal(n) + np.cumsum(k_true / math.sqrt(F) * rng.standard_normal(n))
    fit, _ = fit_axis(x, freq=F, model="WN+RW")
    k_data, at = rw_bound(allan_variance(x, freq=F, grid="dense"))
    assert 0.7 * k_true < k_data < 1.3 * k_true and at * F * 8 <= n + 1  # a ≥ 3-dof point: m ≤ (n + 1)/8

    right = axis_noise(fit, "gyro_x")
    assert not right.equivalent.capped and abs(right.K / k_true - 1) < 0.2
    assert right.K == right.equivalent.K_model < k_data and right.equivalent.K_data == k_data

    g2 = fit.model.params["RW.gamma2"]
    wrong_fit = replace(fit, model=fit.model.with_params({**fit.model.params, "RW.gamma2": 4.0 * g2}))
    wrong = axis_noise(wrong_fit, "gyro_x")
    e = wrong.equivalent
    assert e.capped and e.K_model == pytest.approx(2.0 * right.K, rel=1e-12)
    assert wrong.K == pytest.approx(k_data, rel=1e-12) and wrong.K <= k_data * (1 + 1e-12)
    assert wrong.N == right.N  # N is read where the AV falls like white noise; the cap leaves it alone
    assert any("K capped at the data's Allan bound" in ln for ln in axis_lines(wrong))
    # without the data's curve (the online filter's call) the model's own RW is kept
    assert equivalent_noise(wrong_fit.model, F, horizon_s=default_horizon_s(wrong_fit)).K == e.K_model


@pytest.mark.slow
def test_adis16405_unit1_six_axes(shared_data):
    """Real data: ``fit --auto`` on ADIS16405 unit 1 (six axes): no zero density; every N within ±30 % of the
    Allan N of the same axis; every K at or below the Allan bound min_τ AD(τ)·√(3/τ) over the points the
    Allan reading trusts (≥ 3 dof), capped there where the fitted model's K is above it."""
    from imunoise.export import axis_noise
    from imunoise.noise.allan import allan_variance, read_allan, rw_bound
    from imunoise.noise.imu_model import fit_axis

    z = np.load(shared_data("imudata_adis16405", "adis16405_unit1.npz"))
    data, cols = z["data"], [str(c) for c in z["columns"]]
    for i, axis in enumerate(cols):
        gyro = axis.startswith("gyro")
        x = data[:, i] * (math.pi / 180 if gyro else 9.80665)
        fit, _ = fit_axis(x, freq=100.0, auto=True, unit="rad/s" if gyro else "m/s²")
        a = axis_noise(fit, axis)
        av = allan_variance(x, freq=100.0, grid="dense")
        n_allan = read_allan(av).N
        bound = rw_bound(av)[0]
        assert math.isfinite(a.N) and math.isfinite(a.K) and a.N > 0 and a.K > 0, axis
        assert 0.7 < a.N / n_allan < 1.3, (axis, a.N, n_allan)
        assert a.K <= bound * (1 + 1e-12), (axis, a.K, bound)
        assert a.K == pytest.approx(min(a.equivalent.K_model, bound), rel=1e-12), axis
        assert a.tau_range_s == (0.01, default_horizon_s(fit))
