"""Navigation metrics against a reference with known errors (docs/guide/theory.rst, 'Navigation filter' metrics.json
keys)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.io.kfgins import Reference
from imunoise.nav.earth import ned_to_llh
from imunoise.nav.metrics import nav_errors, outage_drift, section_rms, summarize

SPEC_KEYS = {
    "horizontal_rms_m",
    "horizontal_p95_m",
    "horizontal_max_m",
    "vertical_rms_m",
    "velocity_rms_mps",
    "ecef_rms_m",
    "outages",
    "elapsed_s",
    "realtime_factor",
}


def _ref(n=101):
    t = 100.0 + np.arange(n) * 1.0
    llh0 = np.array([math.radians(40.0), math.radians(-105.0), 1600.0])
    ned = np.column_stack([t - t[0], np.zeros(n), np.zeros(n)])  # 1 m/s north
    llh = ned_to_llh(ned, llh0)
    vel = np.tile([1.0, 0.0, 0.0], (n, 1))
    return Reference(t=t, llh=llh, vel_ned=vel, euler=np.full((n, 3), np.nan)), llh0, ned


def test_constant_offset_gives_exact_numbers():
    ref, llh0, ned = _ref()
    est = ned_to_llh(ned + [3.0, 4.0, -2.0], llh0)
    err = nav_errors(ref.t, est, ref.vel_ned + [0.1, 0, 0], None, ref)
    m = summarize(err, elapsed_s=0.5, duration_s=100.0)
    assert SPEC_KEYS <= set(m)
    assert m["horizontal_rms_m"] == pytest.approx(5.0, abs=1e-3)
    assert m["horizontal_max_m"] == pytest.approx(5.0, abs=1e-3)
    assert m["vertical_rms_m"] == pytest.approx(2.0, abs=1e-3)
    np.testing.assert_allclose(m["velocity_rms_mps"], [0.1, 0, 0], atol=1e-12)
    assert np.linalg.norm(m["ecef_rms_m"]) == pytest.approx(math.sqrt(29), abs=1e-3)
    assert m["realtime_factor"] == pytest.approx(200.0)
    assert m["outages"] == []


def test_estimate_at_higher_rate_is_referred_back_with_velocity():
    ref, llh0, ned = _ref()
    # estimate at 100 Hz shifted by +4 ms: the "next sample minus v·δt" rule is exact for constant velocity
    te = ref.t[0] + 0.004 + np.arange(0, 10000) * 0.01
    llh = ned_to_llh(np.column_stack([te - ref.t[0], np.zeros(te.size), np.zeros(te.size)]), llh0)
    err = nav_errors(te, llh, np.tile([1.0, 0, 0], (te.size, 1)), None, ref)
    assert np.abs(err.ned).max() < 1e-6


def test_outage_drift_uses_last_epoch_inside_window_and_sections():
    ref, llh0, ned = _ref()
    drift = np.zeros_like(ned)
    inside = (ref.t >= 120) & (ref.t < 150)
    drift[inside, 1] = (ref.t[inside] - 120) * 2.0  # grows to 58 m at t = 149
    err = nav_errors(ref.t, ned_to_llh(ned + drift, llh0), ref.vel_ned, None, ref)
    (o,) = outage_drift(err, [(120.0, 30.0)])
    assert o["end_horizontal_m"] == pytest.approx(58.0, abs=1e-3)
    assert o["max_horizontal_m"] == pytest.approx(58.0, abs=1e-3)
    assert o["end_t"] == 149.0
    (s,) = section_rms(err, [(150.0, 200.0)])
    assert s["horizontal_rms_m"] < 1e-6 and s["n"] == 50
    m = summarize(err, outages=[(120.0, 30.0)], sections=[(100.0, 120.0)])
    assert m["mean_outage_end_horizontal_m"] == pytest.approx(58.0, abs=1e-3)
    assert m["horizontal_rms_outside_outages_m"] < 1e-6
