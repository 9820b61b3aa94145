"""The Allan-deviation conventions of ``scripts/in_use_white_diagnosis.py``: the data's non-overlapping Allan
deviation of white noise is σ/√m, and a model's Allan deviation from its Haar wavelet variance is the same σ/√m
(ν² at the scale 2τ: the convention the first version of the script got wrong by √2)."""

from __future__ import annotations

import math

import numpy as np

from conftest import load_script
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN

diag = load_script("in_use_white_diagnosis")


def test_model_allan_deviation_of_white_noise_and_random_walk_is_the_textbook_one():
    f = diag.F
    white = Model([WN(sigma2=4.0e-6)], f)  # σ² per sample
    for tau in (0.1, 1.0, 10.0):
        m = tau * f
        assert math.isclose(diag.model_adev(white, tau), math.sqrt(4.0e-6 / m), rel_tol=1e-12)
    walk = Model([RW(gamma2=1.0e-10)], f)  # γ²: the variance of one sample's increment
    for tau in (10.0, 100.0):
        m = tau * f
        exact = 1.0e-10 * (2 * m * m + 1) / (6 * m)  # Allan variance of a sampled random walk at m samples
        assert math.isclose(diag.model_adev(walk, tau) ** 2, exact, rel_tol=1e-9)


def test_data_allan_deviation_matches_the_model_on_simulated_white_noise():
    rng = np.random.default_rng(7)
    x = rng.normal(0.0, 2.0e-3, 400_000)
    est, n = diag.allan_dev(x, np.ones(x.size, dtype=bool), 100)
    assert n == 3999
    # relative sd of an Allan deviation from n differences ≈ 1/√(2n) ≈ 1.1 %: 5 sd
    assert abs(est / (2.0e-3 / 10.0) - 1.0) < 5.0 / math.sqrt(2 * n)
    # blocks never span two runs: two runs of 150 samples hold one block each, no difference at m = 100
    mask = np.zeros(x.size, dtype=bool)
    mask[:150] = mask[1000:1150] = True
    assert diag.allan_dev(x, mask, 100)[1] == 0
