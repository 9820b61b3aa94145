"""The selection's fast paths compute exactly what the process classes and the model algebra compute
(docs/guide/theory.rst, 'GMWM estimator'–5)."""

from __future__ import annotations

import math

import numpy as np

from imunoise.noise.fitting.candidate_fit import Solved, _embed_variants
from imunoise.noise.fitting.candidates import Candidate, candidate_of
from imunoise.noise.fitting.params import bounds, kind_codes, theta_to_u, thetas_to_u
from imunoise.noise.fitting.problem import prepare
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, PROCESS_TYPES


def _class_walk(theta, kinds, scale):
    """theta_to_u as the registry's classes define it (no cache, numpy scalars, np.clip)."""
    types = tuple(PROCESS_TYPES.values())
    u = np.empty_like(theta)
    p, chain, first, lo, hi = 0, None, True, [], []
    for k in kinds:
        cls = types[k]
        chain = cls.u_from_theta(theta, p, u, scale, chain)
        a, b = cls.u_bounds(first)
        lo, hi, first = lo + a, hi + b, first and cls.singleton
        p += len(cls.param_names)
    return np.clip(u, lo, hi)


def _ar1_u_with_np_clip(theta, p, u, scale, chain):
    """AR1's θ → u as it was written with ``np.clip`` (the reference the scalar clamp must reproduce)."""
    phi = float(np.clip(theta[p], 1e-300, 1.0 - 1e-15))
    v = math.log(-math.log(phi))
    if chain is None:
        u[p] = v
    else:
        u[p] = math.log(max(v - chain, 1e-9))
        v = chain + math.exp(u[p])
    u[p + 1] = math.log(max(theta[p + 1] / scale, 1e-300))
    return v


def test_ar1_conversion_is_the_np_clip_form_to_the_bit():
    rng = np.random.default_rng(4)
    phis = np.concatenate([rng.uniform(0, 1, 300), [0.0, 1e-320, 1.0, 1.0 - 1e-16, 0.5, np.nan, -1.0]])
    for phi in phis:
        for s2 in (1e-300, 0.0, 3.7e-9, 12.0):
            for chain in (None, -3.0, 0.7, 40.0):
                theta = np.array([phi, s2])
                a, b = np.empty(2), np.empty(2)
                va = _ar1_u_with_np_clip(theta, 0, a, 0.31, chain)
                vb = AR1.u_from_theta(theta.tolist(), 0, b, 0.31, chain)
                assert a.tobytes() == b.tobytes() and np.array_equal([va], [vb], equal_nan=True)


def test_theta_to_u_and_bounds_match_the_registry_walk():
    rng = np.random.default_rng(5)
    for text in ("AR1", "3*AR1+WN+QN+RW+DR", "2*AR1+MA1+RW", "WN+DR"):
        structure = Model.parse(text)
        kinds = kind_codes(structure)
        rows = []
        for _ in range(50):
            theta = np.abs(rng.standard_normal(structure.n_params)) * 10.0 ** rng.uniform(-12, 2)
            p = 0
            for c in structure.components:
                if c.kind == "AR1":
                    theta[p] = rng.uniform(0.0, 1.0)
                p += len(c.param_names)
            assert theta_to_u(theta, kinds, 0.02).tobytes() == _class_walk(theta, kinds, 0.02).tobytes()
            rows.append(theta)
        expected = np.array([_class_walk(t, kinds, 0.02) for t in rows])
        assert thetas_to_u(rows, kinds, 0.02).tobytes() == expected.tobytes()
        assert thetas_to_u([t.tolist() for t in rows], kinds, 0.02).tobytes() == expected.tobytes()
        lo, hi = bounds(kinds)
        lo[:] = 0.0  # the caller owns what bounds() returns
        assert not np.array_equal(bounds(kinds)[0], lo)


def test_embedding_vectors_are_the_models_vectors():
    rng = np.random.default_rng(6)
    x = rng.standard_normal(20_000) + np.cumsum(rng.standard_normal(20_000)) * 1e-3
    problem = prepare(x, freq=100.0)
    parents = [
        Model.parse("2*AR1+QN").with_params({"AR1_1.phi": 0.999, "AR1_1.sigma2": 1e-6, "AR1_2.phi": 0.9,
                                             "AR1_2.sigma2": 1e-3, "QN.q2": 1e-4}),
        Model.parse("WN+RW").with_params({"WN.sigma2": 1.0, "RW.gamma2": 1e-6}),
    ]
    for parent in parents:
        sol = Solved(parent, parent.vector, 1.0, True, 0, 0, 0.0)
        base = candidate_of(parent)
        for kind in ("AR1", "WN", "QN", "RW", "DR"):
            if kind != "AR1" and kind in base.others:
                continue
            child = (Candidate(base.n_ar1 + 1, base.others) if kind == "AR1" else
                     candidate_of(Model(list(parent.components) + [PROCESS_TYPES[kind].negligible()])))
            got = _embed_variants(problem, sol, kind, child)
            assert got
            for v in got:
                m = child.model.with_vector(v)
                assert m.vector.tobytes() == v.tobytes()  # already in the order Model sorts it into


def test_compiled_rows_are_the_process_walk_to_the_bit():
    # every registered kind, values from 1e-320 to 1e30, both signs, zeros, NaN and infinities
    from imunoise.noise.fitting.kernels import u_rows
    from imunoise.noise.fitting.params import _plan, _u_rows_walk

    rng = np.random.default_rng(7)
    edge = [0.0, -0.0, 1e-320, -1e-320, 1.0, 1.0 - 1e-16, -1.0, np.nan, np.inf, -np.inf, 0.5, 1e30]
    for text in ("3*AR1+WN+QN+RW+DR", "2*AR1+MA1+RW", "MA1+WN", "DR"):
        kinds = kind_codes(Model.parse(text))
        steps, lo, _ = _plan(kinds)
        P = len(lo)
        TH = rng.standard_normal((400, P)) * 10.0 ** rng.uniform(-320, 30, (400, P))
        TH[:, :] = np.where(rng.uniform(size=(400, P)) < 0.3, rng.uniform(-0.2, 1.2, (400, P)), TH)
        TH[: len(edge) * P].flat[:] = np.resize(edge, len(edge) * P * P)
        for scale in (0.02, 1.0, 3e7):
            U, ok = u_rows(TH, kinds, scale)
            assert ok
            ref = _u_rows_walk(TH, steps, P, scale)
            assert U.tobytes() == ref.tobytes(), (text, scale)


def test_process_from_values_is_the_keyword_constructor():
    # the same process for good values, the same error (type and message) for bad ones, every registered kind
    import pytest

    from imunoise.errors import ModelError

    for cls in PROCESS_TYPES.values():
        k = len(cls.param_names)
        for vals in ([0.5] * k, [0.25, 3e-7][:k] if k == 2 else [3e-7], [-1.0] * k, [math.nan] * k, [2.0] * k,
                     [0.5] * (k - 1), [0.5] * (k + 1), [math.inf] * k):
            try:
                ref = cls(**dict(zip(cls.param_names, vals)))
            except ModelError as exc:
                with pytest.raises(ModelError) as got:
                    cls.from_values(vals)
                assert str(got.value) == str(exc)
                continue
            new = cls.from_values(vals)
            assert type(new) is cls and new == ref and new.known == ref.known
            if ref.known:
                assert np.array(new.values).tobytes() == np.array(ref.values).tobytes()
