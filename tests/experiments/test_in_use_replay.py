"""scripts/in_use_replay.py: the pooled carry-over tables of the real-noise replay (units as clusters) and the
share of unit-axes whose estimated in-use factor interval contains 1, on results of known content."""

from __future__ import annotations

import math

import pytest

from conftest import load_script
from imunoise.imu import AXES

mod = load_script("in_use_replay")


def _axes(white, k):
    """An in_motion part: the gyros get interval ``white[0]`` / K ``k[0]``, the accelerometers ``white[1]`` /
    ``k[1]`` (one interval per sensor group, as the estimate gives them)."""
    out = {}
    for i, ax in enumerate(AXES):
        w, kk = white[i // 3], k[i // 3]
        out[ax] = {"white_factor": w, "factor_K": kk}
    return {"in_motion": {"axes": out}}


def _res(drives, factor, learned):
    """A unit's results: per drive 3 windows, gmwm drifts 10, 20, 40 m, in_use × ``factor``, static_var × 1.25."""
    g = [[[10.0, 20.0, 40.0]] for _ in range(drives)]
    pw = {"gmwm": g, "in_use": [[[v * factor for v in r[0]]] for r in g],
          "static_var": [[[v * 1.25 for v in r[0]]] for r in g]}
    return {"per_window": {"noise:1.5,3,1": {"drift": pw}}, "seeds": list(range(drives)), "vehicle_drives": 2,
            "in_use_models": learned}


IN = {"value": 1.1, "ci95": [0.8, 1.5]}
OUT = {"value": 2.0, "ci95": [1.5, 2.7]}
ONE = {"value": 1.0, "ci95": [1.0, 1.0]}
BOUND = {"value": None, "ci95": None}


def test_pooled_ratios_are_the_paired_geometric_means_over_units():
    res = [_res(2, 0.9, {}), _res(3, 0.9, {})]
    e = {(x["method"], x["baseline"]): x for x in mod.pooled_ratios(res, ["u1", "u2"], 200)}
    assert e[("in_use", "gmwm")]["ratio"] == pytest.approx(0.9, rel=1e-12)
    assert e[("in_use", "gmwm")]["ci"] == pytest.approx([0.9, 0.9], rel=1e-12)  # the same ratio everywhere: se 0
    assert e[("in_use", "static_var")]["ratio"] == pytest.approx(0.9 / 1.25, rel=1e-12)
    assert e[("in_use", "gmwm")]["n_clusters"] == 2 and e[("in_use", "gmwm")]["n_drives"] == 5
    assert e[("in_use", "gmwm")]["cluster"] == "unit"


def test_the_interval_share_counts_bounds_and_no_wander_apart():
    u1 = {"1/g/1": _axes((IN, OUT), (ONE, IN)), "2/g/1": _axes((IN, IN), (OUT, ONE))}
    u2 = {"1/g/1": _axes((BOUND, IN), (BOUND, ONE))}  # a K factor without a value: not given, not a bound
    cov = mod.coverage([_res(2, 1.0, u1), _res(1, 1.0, u2)], ["u1", "u2"])
    w = cov["white_factor"]
    assert w["counts"] == {"in": 12, "out": 3, "one": 0, "bound": 3, "none": 0}
    assert w["share_contains_1"] == pytest.approx(12 / 15)
    assert w["share_counting_bounds_as_containing_1"] == pytest.approx(15 / 18)
    # unit-axes: u1 gyro (in, in), u1 accel (out, in), u2 accel (in); u2 gyros have no interval
    assert w["unit_axes"] == 9 and w["share_unit_axes_all_estimates_contain_1"] == pytest.approx(6 / 9)
    k = cov["factor_K"]
    assert k["counts"] == {"in": 3, "out": 3, "one": 9, "bound": 0, "none": 3}  # u2's gyros give no K factor
    assert k["share_contains_1"] == pytest.approx(12 / 15)
    assert not any(math.isnan(x) for x in w["share_ci95_units"])


@pytest.mark.parametrize("text", ["0.02,0.02", "0.02,0.02,0.05,1", "0.02,0,0.05", "0.02,-1,0.05"])
def test_rtk_sigma_needs_three_positive_values(text, capsys):
    with pytest.raises(SystemExit) as e:
        mod.main(["--rtk-sigma", text])
    assert e.value.code == 2
    assert f"need three σ > 0 (N,E,D in m), got {text!r}" in capsys.readouterr().err


def test_sigma_triple_reads_north_east_down():
    assert mod.sigma_triple("0.02,0.03,0.05") == (0.02, 0.03, 0.05)
