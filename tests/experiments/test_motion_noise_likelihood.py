"""scripts/motion_noise_likelihood.py: the innovation NLL is the Gaussian log-density (prediction-error
decomposition on a linear case), and the script runs one short simulated drive end to end."""

from __future__ import annotations

import json

import numpy as np
from scipy.stats import multivariate_normal

from conftest import load_script

lik = load_script("motion_noise_likelihood")


def test_gaussian_nll_is_the_negative_log_density():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 3, 3))
    S = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(3)
    nu = rng.normal(size=(5, 3))
    want = [-multivariate_normal(np.zeros(3), S[i]).logpdf(nu[i]) for i in range(5)]
    np.testing.assert_allclose(lik.gaussian_nll(nu, S), want, rtol=1e-12)


def test_summed_innovation_nll_equals_the_joint_density_of_a_linear_model():
    # random walk + white measurement noise: y ~ N(0, Σ), Σ_ij = p0 + q·min(i, j) + r·δ_ij (i, j ≥ 1)
    q, r, p0, n = 0.3, 0.5, 2.0, 12
    idx = np.arange(1, n + 1)
    cov = p0 + q * np.minimum.outer(idx, idx) + r * np.eye(n)
    y = multivariate_normal(np.zeros(n), cov).rvs(random_state=4)
    np.testing.assert_allclose(lik.scalar_kf_nll(y, q, r, p0).sum(), -multivariate_normal(np.zeros(n), cov).logpdf(y),
                               rtol=1e-10)


def test_the_script_runs_one_short_drive(tmp_path):
    assert lik.main(["--seeds", "3200", "--duration", "200", "--stops", "1", "--grid", "0,1", "--horizons", "120,200",
                     "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "likelihood.json").read_text())
    assert res["drives"][0]["n_fixes"] > 150 and res["drives"][0]["scale_source"] == "law schedule"
    for c in lik.CRITERIA:
        vals = res["results"]["200"][c]["values"][0]
        assert len(vals) == 2 and np.all(np.isfinite(vals))
    assert "| 3.33333 min | (a) one-step innovation NLL |" in (tmp_path / "likelihood.md").read_text()


def test_the_members_agree_until_the_car_first_moves():
    # the family changes the noise only while moving: the same innovations before the first motion, not after
    p = lik.prepare(3200, "drive0708", "noise:1.5,3,1", "drive0708", 200.0, 1)
    r0 = lik.run_member(p, 0.0, 20.0, 20.0, 2.0)
    r1 = lik.run_member(p, 1.0, 20.0, 20.0, 2.0, r0["starts"])
    assert len(r0["starts"]) >= 3 and [w["t0"] for w in r0["windows"]] == [w["t0"] for w in r1["windows"]]
    t = np.asarray(r0["t"])
    first = p["imu"].t[np.argmax(p["moving"])]
    before, after = t < first, t > first + 30.0
    assert before.sum() > 10 and after.sum() > 10
    np.testing.assert_array_equal(np.asarray(r0["a"])[before], np.asarray(r1["a"])[before])
    assert not np.allclose(np.asarray(r0["a"])[after], np.asarray(r1["a"])[after])
