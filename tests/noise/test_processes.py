"""Closed-form Haar WVs (docs/guide/theory.rst, 'Latent processes') against Monte Carlo and against exact identities."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from imunoise import AR1, DR, QN, RW, WN, Model
from imunoise.noise.processes import ar1_wv, ar1_wv_dphi
from imunoise.noise.wv import wavelet_variance

N = 2**12
REPS = 200
MIN_COEF = 50


def _mc_check(model: Model, seed: int) -> None:
    """Mean empirical WV over REPS replicates lies within 3 standard errors of the closed form."""
    rng = np.random.default_rng(seed)
    wvs = []
    for _ in range(REPS):
        wv = wavelet_variance(model.simulate(N, rng), freq=1.0)
        wvs.append(wv.variance)
    scales = wv.scales
    keep = wv.n_coefficients >= MIN_COEF
    emp = np.array(wvs)[:, keep]
    mean = emp.mean(axis=0)
    se = emp.std(axis=0, ddof=1) / np.sqrt(REPS)
    theo = model.wv(scales[keep])
    z = (mean - theo) / se
    assert np.all(np.abs(z) < 3.0), f"{model!r}: z-scores {np.round(z, 2)} at scales {scales[keep]}"
    assert keep.sum() >= 8


@pytest.mark.parametrize(
    "model",
    [
        Model([WN(sigma2=2.5)]),
        Model([QN(q2=0.7)]),
        Model([RW(gamma2=1e-3)]),
        Model([AR1(phi=0.95, sigma2=1.0)]),
        Model([AR1(phi=0.5, sigma2=1.0)]),
        Model([AR1(phi=0.995, sigma2=1e-2)]),
        AR1(phi=0.99, sigma2=1e-3) + AR1(phi=0.6, sigma2=0.5) + WN(sigma2=1.0) + QN(q2=0.2) + RW(gamma2=1e-5),
    ],
    ids=["WN", "QN", "RW", "AR1-0.95", "AR1-0.5", "AR1-0.995", "sum"],
)
def test_closed_form_matches_monte_carlo(model):
    # zlib.crc32, not hash(): str hashing is randomised per process, and the test must be reproducible
    _mc_check(model, seed=zlib.crc32(repr(model).encode()))


def test_drift_wv_is_exact():
    # A linear trend has identical Haar coefficients ω·m/2 at every position, so ν̂² = ω²τ²/16 exactly.
    model = Model([DR(omega=3e-4)])
    wv = wavelet_variance(model.simulate(4096, seed=0), freq=1.0)
    np.testing.assert_allclose(wv.variance, model.wv(wv.scales), rtol=1e-8)


def test_ar1_closed_form_precision_near_unit_root():
    # As φ → 1 at fixed τ the AR1 WV tends to the RW WV of the same σ²; the textbook form loses all
    # digits here (0/0), the cancellation-free form must not.
    tau = 2.0 ** np.arange(1, 6)
    for eps in (1e-9, 1e-12):
        np.testing.assert_allclose(ar1_wv(tau, 1 - eps, 1.0), (tau**2 + 2) / (12 * tau), rtol=1e-5)


def test_ar1_matches_textbook_formula_away_from_unit_root():
    tau = 2.0 ** np.arange(1, 16)
    for phi in (0.2, 0.7, 0.9, 0.99):
        m = tau / 2
        naive = (m - 3 * phi - m * phi**2 + 4 * phi ** (m + 1) - phi ** (2 * m + 1)) / (
            2 * m * m * (1 - phi) ** 2 * (1 - phi**2)
        )
        np.testing.assert_allclose(ar1_wv(tau, phi, 1.0), naive, rtol=1e-9)


@pytest.mark.parametrize("phi", [0.3, 0.9, 0.999, 0.99999])
def test_ar1_derivative_matches_finite_difference(phi):
    tau = 2.0 ** np.arange(1, 18)
    h = 1e-3 * (1 - phi)  # central difference: truncation ~1e-7 relative, rounding negligible
    fd = (ar1_wv(tau, phi + h, 2.0) - ar1_wv(tau, phi - h, 2.0)) / (2 * h)
    np.testing.assert_allclose(ar1_wv_dphi(tau, phi, 2.0), fd, rtol=1e-5)


def test_jacobian_of_model_matches_finite_difference():
    model = (
        AR1(phi=0.99, sigma2=1e-3)
        + AR1(phi=0.6, sigma2=0.5)
        + WN(sigma2=1.0)
        + QN(q2=0.2)
        + RW(gamma2=1e-5)
        + DR(omega=1e-4)
    )
    tau = 2.0 ** np.arange(1, 15)
    jac = model.wv_jacobian(tau)
    theta = model.vector
    names = model.param_names
    for i in range(len(theta)):
        h = 1e-4 * (1 - theta[i]) if names[i].endswith(".phi") else 1e-6 * abs(theta[i])
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        fd = (model.with_vector(up).wv(tau) - model.with_vector(dn).wv(tau)) / (2 * h)
        np.testing.assert_allclose(jac[:, i], fd, rtol=1e-5, atol=1e-9 * np.max(np.abs(fd)))


def test_simulation_moments():
    rng = np.random.default_rng(3)
    x = Model([QN(q2=0.5)]).simulate(200_000, rng)
    assert abs(x.var() / (2 * 0.5) - 1) < 0.02  # Var(u_t − u_{t−1}) = 2Q²
    a = Model([AR1(phi=0.9, sigma2=1.0)]).simulate(200_000, rng)
    assert abs(a.var() / (1 / (1 - 0.81)) - 1) < 0.05  # stationary variance σ²/(1−φ²)
    assert abs(np.corrcoef(a[1:], a[:-1])[0, 1] - 0.9) < 0.01


def test_continuous_conversions():
    f = 200.0
    m = (
        AR1(phi=np.exp(-1 / (f * 50.0)), sigma2=1e-8)
        + WN(sigma2=4e-6)
        + RW(gamma2=1e-12)
        + QN(q2=1e-8)
        + DR(omega=2e-9)
    )
    c = m.continuous(f)
    assert c["AR1_1.tau_c"] == pytest.approx(50.0)
    assert c["WN.noise_density"] == pytest.approx(np.sqrt(4e-6 / f))
    assert c["RW.random_walk"] == pytest.approx(np.sqrt(1e-12 * f))
    assert c["QN.q_ieee"] == pytest.approx(1e-4 / f)
    assert c["DR.rate_ramp"] == pytest.approx(2e-9 * f)
    phi = np.exp(-1 / (f * 50.0))
    var_gm = 1e-8 / (1 - phi**2)
    assert c["AR1_1.sigma_gm"] == pytest.approx(np.sqrt(var_gm))
    assert c["AR1_1.q_c"] == pytest.approx(2 * var_gm / 50.0)


def test_algebra_works_from_the_processes_module_alone():
    """``from imunoise.noise.processes import WN, RW; WN() + RW()`` in a fresh interpreter: the algebra is no side
    effect of some other import."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    src = str(Path(__file__).resolve().parents[2] / "src")
    for where in ("imunoise.noise.processes", "imunoise.processes"):  # the new path and the old one
        code = f"from {where} import WN, RW; m = WN() + RW(); print(type(m).__name__, m)"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                             env={**os.environ, "PYTHONPATH": src})
        assert out.stdout.strip() == "Model WN + RW", where
