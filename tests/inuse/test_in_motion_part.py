"""The model file's in-motion part: round trip, the absent part changes nothing, the (N, K) it implies."""

from __future__ import annotations

import json
import math

import pytest

from imunoise.errors import ModelError
from imunoise.inuse import AxisInMotion, BiasWander, Bound, InMotionPart, Interval, gm_equivalent_k
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN


def _model() -> ImuModel:
    import numpy as np

    from imunoise.noise.estimator import gmwm

    x = np.random.default_rng(3).normal(0, 1e-3, 4096)
    fit = gmwm(Model([WN(), RW()]), x, freq=100.0, unit="rad/s", seed=1)
    return ImuModel.from_fits({"gyro_x": fit})


def _part() -> InMotionPart:
    gy = AxisInMotion(Interval(2.1, (1.8, 2.5)),
                      BiasWander("gm", sigma=5.8e-4, tau_s=60.0, ci95={"sigma": (4e-4, 8e-4), "tau_s": (30.0, 120.0)}),
                      Interval(2.1, (1.8, 2.5)), Interval(3.0, (2.0, 4.0)))
    ax = AxisInMotion(Interval(1.0, (0.9, 1.1)), BiasWander("none"), Interval(1.0, (0.9, 1.1)), Interval(1.0))
    return InMotionPart({"gyro_y": gy, "accel_x": ax},
                        {"accel_x": Bound("bias", 0.01, "bias wander not separable from attitude error")},
                        {"drives": ["a", "b"], "hours_moving": 0.3, "gnss_sigma_m": 1.0, "method": "ml",
                         "freq_hz": 100.0})


def test_part_round_trip_through_json():
    p = _part()
    d = json.loads(json.dumps(p.to_dict()))
    q = InMotionPart.from_dict(d)
    assert q == p
    assert d["axes"]["gyro_y"]["bias"] == {"model": "gm", "sigma": 5.8e-4, "tau_s": 60.0,
                                           "ci95": {"sigma": [4e-4, 8e-4], "tau_s": [30.0, 120.0]}}
    assert d["bounds"]["accel_x"]["upper"] == 0.01


def test_model_file_round_trip_with_part(tmp_path):
    m = _model()
    m.in_motion = _part().to_dict()
    path = m.save(tmp_path / "model.json")
    back = ImuModel.load(path)
    assert back.in_motion_part() == _part()
    assert back.to_dict() == json.loads(path.read_text())


def test_absent_part_leaves_the_file_unchanged(tmp_path):
    m = _model()
    d = m.to_dict()
    assert "in_motion" not in d
    back = ImuModel.from_dict(json.loads(json.dumps(d)))
    assert back.in_motion is None and back.in_motion_part() is None
    assert back.to_dict() == d


def test_equivalent_pair_and_gm_k():
    ax = _part().axis("gyro_y")
    n, k = ax.equivalent_pair(1e-4, 2e-5)
    assert n == pytest.approx(2.1e-4)
    assert k == pytest.approx(math.hypot(2e-5, 5.8e-4 * math.sqrt(2.0 / 60.0)))
    assert gm_equivalent_k(0.0, 60.0) == 0.0
    assert AxisInMotion(bias=BiasWander("rw", k=3e-5)).equivalent_pair(1.0, 4e-5) == (1.0, pytest.approx(5e-5))
    # an axis the part does not name: factor 1, no wander
    assert _part().axis("gyro_z").equivalent_pair(1.0, 2.0) == (1.0, 2.0)


def test_bad_part_is_refused():
    with pytest.raises(ModelError, match="bias model"):
        BiasWander("ar2")
    with pytest.raises(ModelError, match="axes"):
        InMotionPart.from_dict({"axes": {"gyro_q": {}}})
    with pytest.raises(ModelError, match="'axes'"):
        InMotionPart.from_dict({"bounds": {}})


def test_a_walk_enters_the_filter_at_the_estimates_longest_tau():
    """A random walk k is carried as the Gauss–Markov the estimate searched at its bound (τ = 3 × the moving time,
    σ = k√(τ/2)): the filter state starts at k²τ/2, not at the near-infinite τ's degrees per second, and its
    driving density per sample stays k²/f."""
    from imunoise.nav.filter_model import in_motion_filter
    from imunoise.noise.in_motion import WALK_TAU_NO_EVIDENCE_S, walk_tau_s
    from imunoise.noise.processes import AR1

    k = 8.25e-5  # rad/s/√s
    walk = AxisInMotion(Interval(1.0, (0.9, 1.1)), BiasWander("rw", k=k, ci95={"k": (5e-5, 1.4e-4)}))
    hours = 540.0 / 3600.0
    part = InMotionPart({"gyro_z": walk}, {}, {"hours_moving": hours, "freq_hz": 100.0})
    sig, tau = part.moving_gm()
    assert tau[2] == walk_tau_s(hours) == pytest.approx(3 * 540.0, rel=1e-12)
    assert sig[2] == pytest.approx(k * math.sqrt(1620.0 / 2.0), rel=1e-12)
    assert sig[:2] == [0.0, 0.0] and sig[3:] == [0.0, 0.0, 0.0]
    static = [Model([WN(sigma2=1e-6)], 100.0) for _ in range(6)]
    imf = in_motion_filter(static, part.white_factors(), sig, tau)
    moving = imf.models[2].components[imf.gm_index[2]]
    assert isinstance(moving, AR1)
    phi, q = moving.values
    assert q / (1 - phi * phi) == pytest.approx(k * k * 1620.0 / 2.0, rel=1e-9)  # P0: 0.31 °/s, not 3.3 °/s
    assert q == pytest.approx(k * k / 100.0, rel=2e-3)  # the walk's density per sample (φ ≈ 1 − 1/(τ f))
    # without the evidence (a hand-written part) the old near-infinite τ
    bare = InMotionPart({"gyro_z": walk}, {}, {})
    assert bare.moving_gm()[1][2] == WALK_TAU_NO_EVIDENCE_S
