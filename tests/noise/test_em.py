"""EM baseline (docs/guide/theory.rst, 'Baselines'): exact likelihood, exact smoother moments, monotone EM, recovery,
errors, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import ModelError
from imunoise.noise.em import em_fit, kalman_loglik
from imunoise.noise.em_kalman import kalman_estep as _estep
from imunoise.noise.em_kalman import state_form as _to_state
from imunoise.noise.model import Model
from imunoise.noise.process_registry import PROCESS_TYPES

AR1_WN = Model.parse("AR1+WN").with_params({"AR1_1.phi": 0.95, "AR1_1.sigma2": 1e-2, "WN.sigma2": 1e-1})


def _dense_cov(model: Model, n: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Covariance of y and of each state path (stationary AR1s, RW from Var b_0 = p0)."""
    i = np.arange(n)
    states = []
    Cy = np.zeros((n, n))
    var_y = 1.0
    phi, q, r, p0, _, labels = _to_state(model, var_y)
    for k in range(len(labels)):
        if phi[k] == 1.0:
            C = p0[k] + q[k] * np.minimum.outer(i, i)
        else:
            C = q[k] / (1 - phi[k] ** 2) * phi[k] ** np.abs(i[:, None] - i[None, :])
        states.append(C)
        Cy += C
    return Cy + r * np.eye(n), states


@pytest.mark.parametrize(
    "model, n",
    [
        (AR1_WN, 1200),  # long enough for the steady-state freeze of both covariance recursions
        (
            Model.parse("2*AR1+WN+RW").with_params(
                {
                    "AR1_1.phi": 0.99,
                    "AR1_1.sigma2": 1e-3,
                    "AR1_2.phi": 0.5,
                    "AR1_2.sigma2": 1e-2,
                    "WN.sigma2": 1e-1,
                    "RW.gamma2": 1e-4,
                }
            ),
            400,
        ),
    ],
)
def test_loglik_and_smoother_moments_are_exact(model, n):
    y = model.simulate(n, seed=3)
    y = y - y.mean()
    phi, q, r, p0, omega, labels = _to_state(model, 1.0)
    tt = np.zeros(n)
    ll, S00, S11, S10, e2, _ = _estep(y, tt, 0.0, phi, q, r, p0)
    Cy, Cs = _dense_cov(model, n)
    sign, logdet = np.linalg.slogdet(Cy)
    Ci = np.linalg.inv(Cy)
    assert ll == pytest.approx(-0.5 * (n * np.log(2 * np.pi) + logdet + y @ Ci @ y), rel=1e-9)
    for k, C in enumerate(Cs):
        # E[x | y] and Cov[x | y] by Gaussian conditioning (x_k and y share C_k)
        m = C @ Ci @ y
        V = C - C @ Ci @ C
        assert S11[k] == pytest.approx(np.sum(np.diag(V)[1:] + m[1:] ** 2), rel=1e-6)
        assert S00[k] == pytest.approx(np.sum(np.diag(V)[:-1] + m[:-1] ** 2), rel=1e-6)
        lag = np.diagonal(V, offset=-1) + m[1:] * m[:-1]
        assert S10[k] == pytest.approx(lag.sum(), rel=1e-6)
    # E[(y − Σx)²] summed: the smoothed noise
    Vtot = Cy - r * np.eye(n)
    mt = Vtot @ Ci @ y
    Vt = Vtot - Vtot @ Ci @ Vtot
    assert e2 == pytest.approx(np.sum((y - mt) ** 2 + np.diag(Vt)), rel=1e-6)


def test_em_increases_likelihood_and_recovers_phi():
    true = Model.parse("AR1+WN").with_params({"AR1_1.phi": 0.99, "AR1_1.sigma2": 1e-4, "WN.sigma2": 1e-3})
    y = true.simulate(2**14, seed=8)
    start = Model.parse("AR1+WN").with_params({"AR1_1.phi": 0.9, "AR1_1.sigma2": 1e-3, "WN.sigma2": 5e-4})
    fit = em_fit(None, y, freq=100.0, init=start, max_iter=400)
    h = np.array(fit.extra["loglik_history"])
    assert np.all(np.diff(h) > -1e-8 * np.abs(h[1:])), "EM must not decrease the likelihood"
    assert fit.extra["decreases"] == 0 and not fit.extra["diverged"]
    assert fit.method == "em" and fit.extra["loglik"] == pytest.approx(h.max())
    assert fit.params["AR1_1.phi"] == pytest.approx(0.99, abs=0.005)
    assert fit.params["WN.sigma2"] == pytest.approx(1e-3, rel=0.1)
    assert fit.extra["loglik"] == pytest.approx(kalman_loglik(y, fit.model), rel=1e-9)


def test_em_with_drift_and_av_start():
    true = AR1_WN + Model.parse("DR").with_params({"DR.omega": 1e-4})
    y = true.simulate(8192, seed=2)
    fit = em_fit("AR1+WN+DR", y, freq=10.0, max_iter=150)  # init="av" by default
    assert fit.params["DR.omega"] == pytest.approx(1e-4, rel=0.2)
    assert fit.params["WN.sigma2"] == pytest.approx(1e-1, rel=0.2)
    assert np.isfinite(fit.objective)


def test_em_rejects_models_without_state_form():
    y = AR1_WN.simulate(512, seed=0)
    with pytest.raises(ModelError):
        em_fit("AR1+WN+QN", y, init=None, freq=1.0)
    with pytest.raises(ModelError):
        em_fit("AR1+RW", y, init=None, freq=1.0)
    with pytest.raises(ModelError):
        em_fit(None, y, init=None, freq=1.0)


def test_cli_em(tmp_path, capsys):
    data = tmp_path / "x.csv"
    np.savetxt(data, AR1_WN.simulate(4096, seed=1))
    out = tmp_path / "em"
    assert cli_main(["em", str(data), "--freq", "100", "--model", "AR1+WN", "--max-iter", "50", "--out", str(out)]) == 0
    assert "log-likelihood" in capsys.readouterr().out
    d = json.loads((out / "model.json").read_text())
    assert d["method"] == "em" and d["extra"]["iterations"] <= 50
    assert cli_main(["em", str(data), "--freq", "100", "--model", "AR1+QN+WN"]) == 2


@pytest.mark.parametrize("kind", sorted(PROCESS_TYPES))
def test_em_handles_or_refuses_every_registered_kind(kind):
    """Every kind of the registry is either in the fitted model's structure or refused in one line naming it;
    never dropped without a word (``em_fit('WN+MA1', ...)`` returned a plain WN fit)."""
    y = np.random.default_rng(3810).normal(0.0, 1e-3, 4000) + np.cumsum(np.full(4000, 1e-7))
    parts = [PROCESS_TYPES[kind]()] + ([] if kind == "WN" else [PROCESS_TYPES["WN"]()])
    structure = Model(parts)
    if PROCESS_TYPES[kind].em_form:
        fit = em_fit(structure, y, freq=100.0, init=None, max_iter=5)
        assert str(fit.model) == str(structure)
    else:
        with pytest.raises(ModelError, match=rf"^em_fit: {kind} has no place .* fit it with gmwm\(\)$"):
            em_fit(structure, y, freq=100.0, init=None)
