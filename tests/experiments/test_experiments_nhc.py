"""The dense-window evidence runs every method with and without non-holonomic constraints (``--nhc``)."""

from __future__ import annotations

from imunoise.experiments.dense import base_method, method_setup, with_nhc
from imunoise.nav.measurements.nhc import NhcConfig


def test_with_nhc_adds_twins_and_pairs():
    methods, pairs = with_nhc(("plain", "static_var", "gmwm"))
    assert methods == ("plain", "static_var", "gmwm", "plain+nhc", "static_var+nhc", "gmwm+nhc")
    assert ("gmwm+nhc", "gmwm") in pairs and ("plain+nhc", "plain") in pairs
    assert ("gmwm+nhc", "plain+nhc") in pairs and ("gmwm+nhc", "static_var+nhc") in pairs
    assert ("plain+nhc", "static_var+nhc") not in pairs  # listed once, as static_var+nhc/plain+nhc
    assert len(pairs) == len(set(pairs)) == 3 + 2 + 1


def test_base_method_strips_filter_suffixes():
    assert base_method("gmwm+sf+nhc") == "gmwm" and base_method("av_online") == "av_online"


def test_nhc_method_is_the_method_with_the_constraints():
    from imunoise.experiments.common import simulate_scenario

    sc = simulate_scenario(0, duration_s=200, n_stops=0, n_outages=0, static_s=20)
    cfg, models, upd = method_setup("plain+sf+nhc", sc)
    plain, _, _ = method_setup("plain", sc)
    assert cfg.ekf.aid(NhcConfig) == NhcConfig() and cfg.ekf.scale_factors
    assert plain.ekf.aid(NhcConfig) is None and cfg.ekf.with_(aiding=(), scale_factors=False) == plain.ekf
